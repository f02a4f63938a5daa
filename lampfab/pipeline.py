"""The stages: each reads its inputs from the build folder, calls the library, and
writes its artifact plus a JSON report (inputs with hashes, resolved settings,
versions, wall time, key figures).  ``stages/NN_name.py`` and ``lampfab <stage>`` both
call these.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import artifacts, profile, room, surface
from .errors import CheckFailed, LampfabError

STAGES = ("prepare", "plan", "init", "optimize", "solid", "check", "export", "verify")
TARGET_PX = 256  # prepared targets: 256 px wide, enough for every stage's resolution


@dataclass(frozen=True)
class Build:
    """The build folder of one design and the profiles it uses."""
    out: Path
    design: profile.Design
    fab: profile.Fabrication

    @staticmethod
    def open(out, design_name: str, fab_name: str) -> "Build":
        return Build(Path(out), profile.load_design(design_name), profile.load_fabrication(fab_name))

    def path(self, *parts) -> Path:
        return self.out.joinpath(*parts)

    @property
    def cylinder(self) -> surface.Cylinder:
        return surface.Cylinder(self.design.lens.outer_radius_mm, self.design.lens.height_mm,
                                self.fab.sector_creases)

    @property
    def limits(self):
        """What the outer surface may do (``limits.Limits``), from both profiles."""
        from .limits import Limits

        return Limits.of(self.design, self.fab)

    @property
    def light(self) -> np.ndarray:
        return room.light_position(self.design)

    @property
    def walls(self) -> list[room.Wall]:
        return room.walls(self.design)

    def settings(self) -> dict:
        return {"design": profile.as_dict(self.design), "fabrication": profile.as_dict(self.fab)}

    def begin(self, stage: str, inputs: dict) -> artifacts.StageReport:
        """Start a stage: refuse it with a message if it needs more memory than is
        free, then open its report, with the profiles and the inner layer's file among
        the hashed inputs."""
        from . import resources
        from .inner import DEFAULT_INNER

        resources.check_memory(stage, self.design)
        files = {"design_profile": self.design.path, "fabrication_profile": self.fab.path,
                 "inner_layer": self.design.lens.inner_mesh or DEFAULT_INNER}
        return artifacts.StageReport(stage, {**inputs, **files}, self.settings(), seed=self.design.optimize.seed)

    def transport_design(self, opt, inner, **progress) -> tuple[np.ndarray, dict]:
        """``transport.design`` for this build's lens, room, light and fabrication limits
        with the ``[optimize]`` settings ``opt``; ``progress``: log, on_step, on_pass."""
        from . import transport

        return transport.design(self.cylinder, self.walls, self.targets(opt.sensor_px), *inner, self.light,
                                self.fab.ior, self.limits, opt, **progress)

    def optimizer(self, opt, inner, targets):
        """The refinement ``opt.method`` names, for this build's lens, room, light and
        fabrication limits, against ``targets`` (one image per wall)."""
        from . import optimize
        from .splat import SplatOptimizer

        method = {"seed": optimize.SeedOptimizer, "splat": SplatOptimizer}[opt.method]
        return method(self.cylinder, *inner, self.light, self.fab.ior, self.walls, targets, opt, self.limits)

    def inner(self):
        from . import inner

        lens = self.design.lens
        return inner.load_inner(lens.inner_mesh or None, lens.inner_scale, self.light, lens.outer_radius_mm,
                                lens.max_offset_mm, lens.height_mm)

    def targets(self, width_px: int) -> list[np.ndarray]:
        """Each wall's prepared target resampled to ``width_px`` wide (rows, cols)."""
        from . import image

        out = []
        for wall in self.walls:
            full = artifacts.read_linear_png16(self.path("targets", f"{wall.name}.png"))
            out.append(image.letterbox(full, *room.image_shape(wall, width_px)))
        return out

    def target_paths(self) -> dict:
        return {f"target_{w.name}": self.path("targets", f"{w.name}.png") for w in self.walls}


def _log(msg: str) -> None:
    """One line on stdout, above any progress bar on the terminal rather than through it."""
    from tqdm import tqdm

    tqdm.write(msg, file=sys.stdout)
    sys.stdout.flush()


def _per_kind(step):
    """The one place that picks the lens kind: for a panel (``[lens] kind = "panel"``)
    ``panel_stages`` does ``step`` its own way, under the same name."""
    @functools.wraps(step)
    def run(build: Build, *args, **kwargs):
        if build.design.lens.kind == "panel":
            from . import panel_stages

            return getattr(panel_stages, step.__name__)(build, *args, **kwargs)
        return step(build, *args, **kwargs)
    return run


# -- settings -------------------------------------------------------------------------
def snapshot(build: Build, path, images: dict[str, str], text: str = "") -> bool:
    """Write the resolved profiles, the hashes of the input images and of the inner
    layer's file, and the target text to ``path`` only if they changed (Make's
    prerequisite for every stage, so editing a profile, an image or the text redoes
    what depends on it, and nothing else).  Before writing, every input is read as the
    stages will read it, so a bad one stops here, with one line and no files.
    Returns whether it wrote."""
    hashes = {}
    for wall, image_path in sorted(images.items()):
        if image_path:
            if not Path(image_path).is_file():
                raise LampfabError(f"{image_path}: image not found; give the path of a PNG or JPEG image")
            hashes[wall] = {"path": image_path, "sha256": artifacts.file_sha256(image_path)}
    inner_mesh = build.design.lens.inner_mesh
    if inner_mesh and Path(inner_mesh).is_file():
        hashes["inner_layer"] = {"path": inner_mesh, "sha256": artifacts.file_sha256(inner_mesh)}
    body = json.dumps({**build.settings(), "images": hashes, "text": text}, indent=2, sort_keys=True) + "\n"
    if artifacts.holds_text(path, body):
        return False
    _check_inputs(build, images, text)
    artifacts.write_text(path, body)
    return True


def _check_inputs(build: Build, images: dict[str, str], text: str) -> None:
    """Read the images and the inner layer as the stages will, and check that every
    stage fits in the memory that is free; raise LampfabError."""
    from . import image, resources, targets

    per_wall = {w.name: images[w.name] for w in build.walls if images.get(w.name)}
    _target_sources(build, images.get("all", ""), per_wall, text, images.get("panorama", ""))
    for stage in STAGES:
        resources.check_memory(stage, build.design)

    for key, image_path in images.items():
        if image_path:
            luminance = image.load_target(image_path)
            if key == "panorama":
                targets.check_panorama(luminance, image_path)
    if build.design.lens.kind == "cylinder":  # a panel has no inner layer
        build.inner()


def _target_sources(build: Build, target: str, per_wall: dict[str, str], text: str,
                    panorama: str) -> tuple[str, dict[str, str]]:
    """(what the walls without an image of their own show, {wall: its source}); raises
    LampfabError where the walls' sources are missing or contradict each other."""
    if text and panorama:
        raise LampfabError("TEXT and PANORAMA both given: choose one (per-wall TARGET_<WALL> images may be added)")
    common = f"text: {text}" if text else f"panorama {panorama}" if panorama else target
    sources = {w.name: per_wall.get(w.name) or common for w in build.walls}
    if not all(sources.values()):
        raise LampfabError("no target image given: set TARGET=path/to/image.png (or TEXT=\"...\" or PANORAMA=...)")
    return common, sources


def summary(build: Build) -> None:
    """One line per stage: wall time and its key figure."""
    names = {"check": "checks"}
    total = 0.0
    for stage in STAGES:
        p = build.path(f"{names.get(stage, stage)}.json")
        if not p.exists():
            continue
        data = artifacts.read_json(p)
        total += data.get("wall_time_s", 0.0)
        print(f"{stage:9s} {data.get('wall_time_s', 0):7.1f} s  {_key_figure(stage, data['figures'])}")
    print(f"{'total':9s} {total:7.1f} s  -> {build.path('report.html')}")


def _key_figure(stage: str, figs: dict) -> str:
    """A stage's headline, in words, for the summary."""
    if stage == "prepare":
        sources = {k[:-len("_source")]: v for k, v in figs.items() if k.endswith("_source")}
        return "; ".join(f"{v} on {', '.join(w for w in sources if sources[w] == v)}"
                         for v in dict.fromkeys(sources.values()))
    if stage == "plan":
        return f"{1 - figs['lost_share']:.0%} of the light on the wall planes"
    if stage == "init":
        tilt = figs.get("max_tilt_deg")
        return figs["method"] + (f", max tilt {tilt:.1f}°" if tilt is not None else "")
    if stage == "optimize":
        loss = figs.get("final_loss")
        return f"{figs['steps']} steps" + (f", final loss {loss:.3g}" if loss is not None else "")
    if stage == "solid":
        return f"{figs['volume_mm3'] / 1000:.0f} cm³, {figs['triangles']} triangles"
    if stage == "check":
        failed = [c["name"] for c in figs["checks"] if c["applies"] and not c["passed"]]
        return f"FAILED: {', '.join(failed)}" if failed else "all checks pass"
    if stage == "export":
        return (f"lens.stl {figs['stl_bytes'] / 1e6:.1f} MB, lens.step {figs['step_bytes'] / 1e6:.1f} MB, "
                f"B-spline within {figs['bspline_deviation_mm'] * 1000:.2g} µm")
    return ", ".join(f"{n} r {f['pearson']:.2f} SSIM {f['ssim']:.2f} (LED r {f['led_pearson']:.2f})"
                     for n, f in figs["walls"].items())


# -- 1. prepare ---------------------------------------------------------------------
def prepare(build: Build, target: str, per_wall: dict[str, str], text: str = "", panorama: str = "") -> dict:
    """One linear-luminance target per wall, letterboxed to the wall's aspect ratio.

    Each wall takes its own image if given, else ``text``, else its slice of
    ``panorama``, else ``target``."""
    from . import image, targets

    common, sources = _target_sources(build, target, per_wall, text, panorama)
    inputs = {f"image_{k}": v for k, v in sources.items()}  # text is no file: the report leaves it out
    report = build.begin("prepare", {**inputs, "panorama": panorama})
    loaded, prepared = {}, {}
    if panorama:
        loaded[common] = image.load_target(panorama)
        targets.check_panorama(loaded[common], panorama)
    for wall in build.walls:
        src = sources[wall.name]
        shape = room.image_shape(wall, TARGET_PX)
        if src == common and text:
            img = targets.text_image(text, *shape)
        elif src == common and panorama:
            d = build.design.room
            img = targets.panorama_slice(loaded[common], wall, build.light, d.wall_distance_mm,
                                         d.target_center_z_mm, *shape)
        else:
            if src not in loaded:
                loaded[src] = image.load_target(src)
            img = image.letterbox(loaded[src], *shape)
        prepared[wall.name] = img
        report.figure(**{f"{wall.name}_mean_luminance": float(img.mean()),
                         f"{wall.name}_source": str(src)})
    # Written only once every wall's image has been read: a bad one leaves no files.
    for name, img in prepared.items():
        artifacts.write_linear_png16(build.path("targets", f"{name}.png"), img)
        artifacts.write_png(build.path("targets", f"{name}_preview.png"), img, normalize=False)
    report.write(build.path("prepare.json"))
    return report.data


# -- 2. plan ------------------------------------------------------------------------
def plan(build: Build) -> dict:
    """The un-optimized lens in the room: where its light falls, wall by wall.

    Each wall plane is rendered three times larger than its target rectangle so the
    report shows light that would fall outside it.
    """
    from . import trace

    d = build.design
    report = build.begin("plan", {})
    scene, emitter = _plain_optics(build)
    walls = build.walls
    big = [room.Wall(w.name, w.origin - w.right - w.down, 3 * w.right, 3 * w.down) for w in walls]
    px = d.verify.image_px
    shapes = [room.image_shape(w, 3 * px) for w in big]
    images, info = trace.render_walls(scene, build.light, 0.0, build.fab.ior, big, shapes,
                                      d.verify.photons, d.optimize.seed, d.verify.max_bounces, emitter)
    figures = {"lost_share": info["lost"], "walls": {}}
    for wall, img in zip(walls, images):
        artifacts.write_png(build.path("plan", f"{wall.name}.png"), img)
        rows, cols = img.shape
        inside = img[rows // 3: 2 * rows // 3, cols // 3: 2 * cols // 3].sum()
        lit = np.argwhere(img > 0.05 * img.max())
        extent = {}
        if len(lit):
            (r0, c0), (r1, c1) = lit.min(0), lit.max(0)
            extent = {"left_mm": (c0 / cols * 3 - 1) * wall.width_mm, "right_mm": ((c1 + 1) / cols * 3 - 1) * wall.width_mm,
                      "top_mm": (r0 / rows * 3 - 1) * wall.height_mm, "bottom_mm": ((r1 + 1) / rows * 3 - 1) * wall.height_mm}
        figures["walls"][wall.name] = {
            "share_in_target": float(inside), "share_on_plane": float(img.sum()),
            "lit_extent_from_target_corner": extent,
            "target_mm": [wall.width_mm, wall.height_mm]}
        _log(f"plan: {wall.name}: {inside:.1%} of the light inside the target rectangle, "
             f"{img.sum():.1%} on the wall plane")
    report.figure(**figures)
    report.write(build.path("plan.json"))
    return report.data


@_per_kind
def _plain_optics(build: Build):
    """(the un-optimized lens as a ``trace.MeshScene``, its light's emitter: None for the LED)."""
    from . import trace

    grid = (build.design.optimize.grid_u, build.design.optimize.grid_v)
    plain = _solid_maker(build)(np.zeros(grid))
    return trace.MeshScene(plain.vertices, plain.faces), None


def _solid_maker(build: Build):
    """``make(heights)``: the lens solid (``solid.Solid``, mm) the solid stage builds from
    (nu, nv) heights in mm, the inner layer loaded once for every call.

    The plan and the tolerance study trace it too, not the bore-less optical mesh: the
    bore through the base removes the glass under the cavity's floor, whose reflections
    would otherwise light a spot on a wall."""
    from . import solid as solid_mod

    iv, if_ = build.inner()

    def make(heights: np.ndarray):
        return solid_mod.build_solid(build.cylinder, heights, build.design.optimize.tessellation, iv, if_,
                                     build.fab.mount_radius_mm)
    return make


# -- 3a. init (transport) -------------------------------------------------------------
@_per_kind
def init(build: Build) -> dict:
    """The first lens: transport-based (default) or the source's plain cylinder."""
    from . import transport

    opt = build.design.optimize
    report = build.begin("init", build.target_paths())
    grid = (opt.grid_u, opt.grid_v)
    if opt.init == "cylinder":
        heights = np.zeros(grid)
        report.figure(method="cylinder")
    else:
        from tqdm import tqdm

        bar = tqdm(total=transport.fit_steps(grid, opt.transport_rounds, opt.transport_corrections), desc="init",
                   unit="step", dynamic_ncols=True)

        def step(figures):
            bar.update()
            bar.set_postfix(error=f"{figures['rms_landing_error_mm']:.1f} mm")

        heights, figs = build.transport_design(opt, build.inner(), log=bar.write, on_step=step)
        bar.update(bar.total - bar.n)  # a fit that converged early skips its last steps
        bar.close()
        report.figure(method="transport", **figs)
    artifacts.write_npz(build.path("init.npz"), heights=heights)
    report.write(build.path("init.json"))
    return report.data


# -- 3b. optimize (the profile's method: splat, or the source's seed) ----------------------
@_per_kind
def optimize(build: Build) -> dict:
    """Refine the initial lens by gradient descent through a differentiable renderer
    (``splat``, or the source's ``seed`` ptracer); resumes from a checkpoint."""
    from tqdm import tqdm

    from . import optimize as opt_mod

    d, opt = build.design, build.design.optimize
    report = build.begin("optimize", {"init": build.path("init.npz"), **build.target_paths()})
    init_heights = artifacts.read_npz(build.path("init.npz"))["heights"]
    if init_heights.shape != (opt.grid_u, opt.grid_v):
        raise LampfabError(f"{build.path('init.npz')}: grid {init_heights.shape} is not the profile's "
                           f"({opt.grid_u}, {opt.grid_v}); re-run init")
    if not np.all(np.isfinite(init_heights)):
        raise LampfabError(f"{build.path('init.npz')}: {int(np.sum(~np.isfinite(init_heights)))} heights are NaN or "
                           f"Inf; re-run init (make init), and report it if it happens again")
    optimizer = build.optimizer(opt, build.inner(), build.targets(opt.sensor_px))
    checkpoint = build.path("checkpoint.npz")
    for written in (checkpoint, build.path("heightmap.npz")):
        artifacts.remove_stale_temps(written)
    state = opt_mod.State(init_heights.copy(), 0, 0)
    resumed = False
    if checkpoint.exists():
        saved = artifacts.read_npz(checkpoint)
        if str(saved.get("settings_hash", "")) == _settings_hash(build, init_heights):
            state = opt_mod.State.from_arrays(saved)
            resumed = True
            _log(f"optimize: resuming from {checkpoint} at step {state.step}")

    def save(s):
        artifacts.write_npz(checkpoint, settings_hash=_settings_hash(build, init_heights), **s.to_arrays())

    def preview(s):
        for wall, img in zip(build.walls, optimizer.render_all(s.heights, seed=opt.seed + 1)):
            artifacts.write_png(build.path("previews", f"step{s.step:06d}_{wall.name}.png"), img)

    bar = tqdm(total=opt.iterations, initial=state.step, desc="optimize", unit="step", disable=opt.iterations == 0,
               dynamic_ncols=True)

    def progress(s, loss, message):
        bar.update(s.step - bar.n)
        bar.set_postfix(loss=f"{loss:.4f}", level=s.level)
        if message:
            bar.write(f"optimize: {message}")

    if state.step == 0 and opt.iterations:
        preview(state)
    try:
        state = optimizer.run(state, save, preview, progress)
    except opt_mod.Interrupted as exc:
        bar.close()
        raise LampfabError(f"optimize interrupted at step {exc.step}; checkpoint saved to {checkpoint}, "
                           f"run the same command again to resume") from None
    bar.close()
    heights = state.heights
    artifacts.write_npz(build.path("heightmap.npz"), heights=heights, radius_mm=d.lens.outer_radius_mm,
                        height_mm=d.lens.height_mm)
    # The optimizer's own picture of its result: verify compares the exported lens with it.
    artifacts.write_npz(build.path("optimize_render.npz"), **{
        w.name: img for w, img in zip(build.walls, optimizer.render_all(heights, seed=opt.seed + 1))})
    log = np.asarray(state.log).reshape(-1, 5)
    artifacts.write_csv(build.path("loss.csv"), log, ["step", "level", "view", "loss", "seconds"],
                        ["%d", "%d", "%d", "%.6g", "%.3f"])
    from . import pictures

    frames = pictures.optimization_gif(build.path("previews"), [w.name for w in build.walls],
                                       build.path("optimization.gif"))
    report.figure(steps=int(state.step), resumed=resumed, gif_frames=frames,
                  numerical_faults=[{"step": int(a), "learning_rate_scale": b} for a, b in state.faults],
                  backtracks=[{"step": int(a), "learning_rate_scale": b} for a, b in state.backtracks],
                  final_loss=float(log[-1, 3]) if len(log) else None,
                  median_step_s=float(np.median(log[:, 4])) if len(log) else None,
                  offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()))
    report.write(build.path("optimize.json"))
    artifacts.remove(checkpoint)
    return report.data


def _settings_hash(build: Build, init_heights: np.ndarray) -> str:
    import hashlib

    h = hashlib.sha256(json.dumps(build.settings(), sort_keys=True).encode())
    h.update(np.ascontiguousarray(init_heights).tobytes())
    for p in build.target_paths().values():
        h.update(artifacts.file_sha256(p).encode())
    return h.hexdigest()


def load_heights(build: Build) -> np.ndarray:
    """The optimized outer layer: (nu, nv) float64 mm radial offsets (heightmap.npz)."""
    return artifacts.read_npz(build.path("heightmap.npz"))["heights"]


# -- 4. solid -------------------------------------------------------------------------
@_per_kind
def solid(build: Build) -> dict:
    """Outer shell minus inner layer and LED bore: one watertight solid in mm."""
    report = build.begin("solid", {"heightmap": build.path("heightmap.npz")})
    s = _solid_maker(build)(load_heights(build))
    artifacts.write_npz(build.path("solid.npz"), vertices=s.vertices, faces=s.faces)
    report.figure(volume_mm3=s.volume_mm3, triangles=int(len(s.faces)), genus=s.genus,
                  bore=dataclasses.asdict(s.bore))
    report.write(build.path("solid.json"))
    return report.data


# -- 5. check -------------------------------------------------------------------------
def check(build: Build, allow_fail: bool) -> dict:
    """Manufacturability against the fabrication profile; raises CheckFailed on a fail."""
    report = build.begin("check", {"solid": build.path("solid.npz")})
    sv = artifacts.read_npz(build.path("solid.npz"))
    results = _run_checks(build, sv["vertices"], sv["faces"])
    failed = [r for r in results if r.failed]
    report.figure(checks=[r.to_json() for r in results], passed=not failed, allowed_to_fail=allow_fail)
    for r in results:
        if r.applies:
            _log(f"check: {r.name}: {'pass' if r.passed else 'FAIL'} ({_fmt(r.value)} {r.unit}, "
                 f"limit {_fmt(r.limit)})")
    if failed and not allow_fail:
        # A checks.json of an earlier run with other settings must not pass for this one.
        artifacts.remove(build.path("checks.json"))
        report.write(build.path("checks.failed.json"))
        worst = failed[0]
        place = worst.worst or {}
        where = f" at u {place['u_deg']:.1f}°, z {place['z_mm']:.1f} mm" if "u_deg" in place else ""
        raise CheckFailed(f"check {worst.name} failed: {_fmt(worst.value)} {worst.unit} against "
                          f"limit {_fmt(worst.limit)}{where} ({len(failed)} failed; see "
                          f"{build.path('checks.failed.json')} and checks.png; ALLOW_FAIL=1 to go on)", failed)
    artifacts.remove(build.path("checks.failed.json"))
    report.write(build.path("checks.json"))
    return report.data


@_per_kind
def _run_checks(build: Build, vertices: np.ndarray, faces: np.ndarray) -> list:
    """Every check's result (``checks.run_checks``), and checks.png painted."""
    from . import checks

    iv, if_ = build.inner()
    heights = load_heights(build)
    results = checks.run_checks(build.cylinder, heights, iv, if_, vertices, faces, build.fab, build.light)
    checks.paint_checks(build.path("checks.png"), build.cylinder, heights, iv, if_, build.fab, results)
    return results


def _fmt(value) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


# -- 6. export ------------------------------------------------------------------------
def export(build: Build) -> dict:
    """lens.stl and lens.step, both read back and checked, and design.json."""
    from . import solid as solid_mod
    from .export import gltf, step_file, stl
    from .tolerances import VOLUME_REL

    fab = build.fab
    report = build.begin("export", {"solid": build.path("solid.npz"), "heightmap": build.path("heightmap.npz")})
    sv = artifacts.read_npz(build.path("solid.npz"))
    stl_bytes = stl.write_stl(build.path("lens.stl"), sv["vertices"], sv["faces"])
    rv, rf = stl.read_stl(build.path("lens.stl"))
    stl_volume = solid_mod.mesh_volume(rv, rf)
    glb_bytes = gltf.write_glb(build.path("lens.glb"), rv, rf, fab.ior)
    edges = solid_mod.edge_check(rf)
    if not (edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1):
        raise LampfabError(f"{build.path('lens.stl')}: read back it is not one closed, consistently wound "
                           f"solid ({edges})")
    slicer = stl.admesh_check(build.path("lens.stl"))         # None where admesh is not installed
    if slicer is not None and (slicer["repairs"] or slicer["parts"] != 1):
        raise LampfabError(f"{build.path('lens.stl')}: admesh would repair it ({slicer}); a slicer would too")
    step_info = _write_step(build, stl_volume)
    back = step_file.read_step(build.path("lens.step"))
    rel = abs(back["volume_mm3"] - stl_volume) / stl_volume
    if not (back["n_solids"] == 1 and back["valid"] and back["closed"] and rel <= VOLUME_REL):
        raise LampfabError(f"{build.path('lens.step')}: read back it is not one valid closed solid matching the "
                           f"STL within {VOLUME_REL:.1%} ({back}, volume difference {rel:.3%})")
    design_json = {
        "units": "mm",
        "light": _light_json(build),
        "material": {"name": fab.material, "ior": fab.ior},
        "lens": {"stl": "lens.stl", "step": "lens.step", "glb": "lens.glb"},
        "walls": [w.to_json(f"targets/{w.name}.png") for w in build.walls],
    }
    artifacts.write_json(build.path("design.json"), design_json)
    report.figure(stl_bytes=stl_bytes, stl_volume_mm3=stl_volume, stl_triangles=int(len(rf)), glb_bytes=glb_bytes,
                  step_bytes=step_info["file_bytes"], step_volume_mm3=back["volume_mm3"],
                  step_stl_volume_rel=rel, step_faces=back["faces"],
                  bspline_deviation_mm=step_info["deviation_mm"],
                  bspline_poles=[step_info["poles_u"], step_info["poles_v"]], admesh=slicer)
    _log(f"export: lens.stl {stl_bytes / 1e6:.1f} MB, lens.step {step_info['file_bytes'] / 1e6:.1f} MB, "
         f"B-spline deviation {step_info['deviation_mm'] * 1000:.3g} µm, volumes agree to {rel:.2e}")
    report.write(build.path("export.json"))
    return report.data


@_per_kind
def _write_step(build: Build, stl_volume_mm3: float) -> dict:
    """lens.step, checked against the STL's volume; ``step.write_step``'s figures."""
    from .export import step_file

    d = build.design
    iv, if_ = build.inner()
    return step_file.write_step(build.path("lens.step"), build.cylinder, load_heights(build), iv, if_,
                           build.fab.mount_radius_mm, d.export.step_samples_u, d.export.step_samples_v,
                           expected_volume_mm3=stl_volume_mm3)


@_per_kind
def _light_json(build: Build) -> dict:
    """design.json's ``light``: the LED's centre and radius."""
    return {"position": build.light.tolist(), "radius": build.fab.led_radius_mm}


# -- 7. verify ------------------------------------------------------------------------
def verify(build: Build) -> dict:
    """Render the exported STL (true facets) from design.json; compare; write report.html."""
    from tqdm import tqdm

    from . import report as report_mod
    from . import verify as verify_mod
    from .tolerances import OPTIMIZER_MATCH_R

    v = build.design.verify
    design_path = build.path("design.json")
    report = build.begin("verify", {"design": design_path, "stl": build.path("lens.stl")})
    # Its parts take a minute together with nothing to print between them: a bar by part.
    parts = ["tracing the exported lens", "tolerance study", "the lamp's renders", "report.html"]
    bar = tqdm(total=len(parts), desc="verify", unit="part", dynamic_ncols=True,
               bar_format="{desc}: {n}/{total} parts{postfix} [{elapsed}]")

    def begin(part: str) -> None:  # the parts before it are done
        bar.update(parts.index(part) - bar.n)
        bar.set_postfix_str(part)

    begin("tracing the exported lens")
    figures = verify_mod.verify(design_path, build.path("verify"), v.image_px, v.photons,
                                build.design.optimize.seed + 7, v.max_bounces)
    begin("tolerance study")
    if build.path("optimize_render.npz").exists():
        agree = verify_mod.optimizer_agreement(build.path("verify"), build.path("optimize_render.npz"),
                                               list(figures["walls"]))
        for name, r in agree.items():
            figures["walls"][name]["optimizer_pearson"] = r
        figures["optimizer_match_min"] = min(agree.values())
        figures["optimizer_match_limit"] = OPTIMIZER_MATCH_R
    for name, f in figures["walls"].items():
        _log(f"verify: {name}: Pearson r {f['pearson']:.3f}, SSIM {f['ssim']:.3f}, {f['share']:.1%} of the light "
             f"({figures['real_light']}: r {f['led_pearson']:.3f}); {f['ghost_share']:.1%} of it reflected "
             f"inside the lens, SSIM {f['direct_ssim']:.3f} without it"
             + (f"; r {f['optimizer_pearson']:.3f} against the optimizer's render" if "optimizer_pearson" in f else ""))
    if figures.get("optimizer_match_min", 1.0) < OPTIMIZER_MATCH_R:
        _log(f"verify: WARNING: the exported lens's render matches the optimizer's only to r "
             f"{figures['optimizer_match_min']:.3f} (< {OPTIMIZER_MATCH_R})")
    figures.update(_finishing(build))
    begin("the lamp's renders")
    report.figure(**figures)
    pictures = _report_pictures(build)
    begin("report.html")
    report.write(build.path("verify.json"))
    _write_report(build, figures, pictures, report_mod)
    bar.update(len(parts) - bar.n)
    bar.close()
    return report.data


@_per_kind
def _finishing(build: Build) -> dict:
    """The tolerance study and the post-processing guidance (``guidance``), for verify.json."""
    from . import guidance, tolerance_study

    d, v, fab = build.design, build.design.verify, build.fab
    make = _solid_maker(build)

    def lens_mesh(heights):
        made = make(heights)
        return made.vertices, made.faces

    study = tolerance_study.study(build.cylinder, load_heights(build), lens_mesh, build.light,
                                  fab.ior, build.walls, build.targets(v.image_px), v.study_photons,
                                  d.optimize.seed + 11, v.max_bounces, fab.surface_error_mm)
    _log(f"verify: polishing allowance {'>= ' if study['allowance_at_least'] else ''}"
         f"{study['allowance_mm'] * 1000:.0f} µm; the profile's {fab.surface_error_mm * 1000:.0f} µm costs r "
         f"{study['profile_error_drop']:.3f}")
    return {"tolerance": study, "guidance": guidance.advice(fab, [w.name for w in build.walls], build.light, study)}


def _report_pictures(build: Build) -> dict:
    """The report's own pictures in ``report/``: the glass lamp in its room, the
    bumpy lens, the unrolled heightmap.  Returns their paths."""
    from . import beauty
    from .export import stl

    v = build.design.verify
    design = artifacts.read_json(build.path("design.json"))
    vertices, faces = stl.read_stl(build.path("lens.stl"))
    walls = [room.Wall.from_json(w) for w in design["walls"]]
    flux = [artifacts.read_npz(build.path("verify", f"{w.name}.npz"))["led"] for w in walls]
    paths = {"room": build.path("report", "room.png"), "lens": build.path("report", "lens.png"),
             "heightmap": build.path("report", "heightmap.png")}
    light_mm, light_radius_mm = _report_light(build, design)
    artifacts.write_png(paths["room"], beauty.room_scene(
        vertices, faces, build.fab.ior, light_mm, light_radius_mm, walls, flux, v.scene_px, v.scene_spp,
        build.design.optimize.seed), normalize=False)
    artifacts.write_png(paths["lens"], beauty.bumpy_lens(vertices, faces, v.scene_px, 4), normalize=False)
    _heightmap_picture(build, [w.name for w in walls], paths["heightmap"])
    return paths


@_per_kind
def _report_light(build: Build, design: dict) -> tuple[np.ndarray, float]:
    """The light of the report's room render: (3,) mm position and its radius in mm."""
    return np.asarray(design["light"]["position"], float), build.fab.led_radius_mm


@_per_kind
def _heightmap_picture(build: Build, wall_names: list[str], path) -> None:
    """The unrolled heightmap as a colour map, each sector labelled with its wall."""
    from . import pictures

    pictures.heightmap_map(build.cylinder, load_heights(build), wall_names, path)


def _write_report(build: Build, figures: dict, pics: dict, report_mod) -> None:
    walls = []
    for name, f in figures["walls"].items():
        walls.append({"name": name, "target_png": build.path("targets", f"{name}_preview.png"),
                      "render_png": build.path("verify", f"{name}.png"),
                      "blur_png": build.path("verify", f"{name}_led.png"),
                      "pearson": f["pearson"], "ssim": f["ssim"], "share": f["share"],
                      "ghost_share": f["ghost_share"], "direct_ssim": f["direct_ssim"],
                      "blur_pearson": f["led_pearson"], "blur_ssim": f["led_ssim"], "blur_share": f["led_share"],
                      **({"r_vs_optimizer": f["optimizer_pearson"]} if "optimizer_pearson" in f else {})})
    stage_figures = {}
    for stage in ("init", "optimize", "solid", "export"):
        p = build.path(f"{stage}.json")
        if p.exists():
            data = artifacts.read_json(p)
            flat = {k: v for k, v in data["figures"].items() if not isinstance(v, (dict, list))}
            flat["wall_time_s"] = data.get("wall_time_s")
            stage_figures[stage] = flat
    fig = report_mod.figure_html
    first, sections = _lens_sections(build, pics, fig)
    if build.path("optimization.gif").exists():
        sections.append(("Optimization", fig("The walls during optimization", build.path("optimization.gif"),
                                             "one frame per preview step (loss per step: loss.csv)")))
    checks = build.path("checks.json") if build.path("checks.json").exists() else build.path("checks.failed.json")
    if checks.exists():
        rows = "".join(
            f"<tr><td>{r['name']}</td><td class=\"{'ok' if r['passed'] else 'fail'}\">"
            f"{'pass' if r['passed'] else 'FAIL'}</td><td>{_fmt(r['value'])} {r['unit']}</td>"
            f"<td>{_fmt(r['limit'])}</td></tr>"
            for r in artifacts.read_json(checks)["figures"]["checks"] if r["applies"])
        picture = fig("Checks on the unrolled lens", build.path("checks.png"), "red: where a check fails") \
            if build.path("checks.png").exists() else ""
        sections.append((f"Fabrication checks ({build.fab.name})",
                         f"<table><tr><th>check</th><th>result</th><th>value</th><th>limit</th></tr>{rows}</table>"
                         f"{picture}"))
    if "guidance" in figures:
        from . import guidance

        sections.append(("Finishing and tolerances", guidance.html(figures["guidance"], figures["tolerance"])))
    sections.append(("Next steps", _next_steps(build) + (
        "<p>For a beauty render, import <code>lens.glb</code> into Blender (File › Import › glTF): it arrives "
        "at its real size with a glass material of the same refractive index. <code>design.json</code> gives "
        "the light and the walls in the same frame.</p>")))
    report_mod.write_report(build.path("report.html"), f"lampfab: {build.out.name}", walls, stage_figures, sections,
                            first)


@_per_kind
def _lens_sections(build: Build, pics: dict, fig) -> tuple[list, list]:
    """The report's first section (the lamp) and the outer layer's section."""
    first = [("Your lamp", '<div class="row">' + fig(
        "The lamp in its room", pics["room"], "the exported lens path-traced as glass; the walls show the "
        "projections verify traced from the same file (LED size)") + fig(
        "The lens", pics["lens"], "lens.stl as a matte object: the bumps are the outer layer that makes "
        "the picture") + "</div>")]
    return first, [("The outer layer, unrolled", fig(
        "Radial offset from the plain cylinder", pics["heightmap"], "each 90° sector lights the wall named "
        "above it; orange bulges out, blue goes in"))]


@_per_kind
def _next_steps(build: Build) -> str:
    """What to do with the files (HTML)."""
    return (f"<p>Send <code>lens.stl</code> to the printer's slicer (binary STL, millimetres, Z up, standing on "
            f"its base) or <code>lens.step</code> to the CNC shop or into FreeCAD / Fusion (one solid; the outer "
            f"surface is a single B-spline face). Material: {build.fab.material} (n = {build.fab.ior}). The LED "
            f"goes into the bore in the base (radius {build.fab.mount_radius_mm} mm); place the lamp with its +y "
            f"side facing the front wall, {build.design.room.wall_distance_mm:.0f} mm from the front, left and "
            f"right walls.</p>")
