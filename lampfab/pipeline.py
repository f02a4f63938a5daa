"""The stages: each reads its inputs from the build folder, calls the library, and
writes its artifact plus a JSON report (inputs with hashes, resolved settings,
versions, wall time, key figures).  ``stages/NN_name.py`` and ``lampfab <stage>`` both
call these.
"""

from __future__ import annotations

import dataclasses
import json
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
        return surface.Cylinder(self.design.lens.outer_radius_mm, self.design.lens.height_mm)

    @property
    def light(self) -> np.ndarray:
        return room.light_position(self.design)

    @property
    def walls(self) -> list[room.Wall]:
        return room.walls(self.design)

    def settings(self) -> dict:
        return {"design": profile.as_dict(self.design), "fabrication": profile.as_dict(self.fab)}

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
    print(msg, flush=True)


# -- settings -------------------------------------------------------------------------
def snapshot(build: Build, path, images: dict[str, str]) -> bool:
    """Write the resolved profiles and the input images' hashes to ``path`` only if
    they changed (Make's prerequisite for every stage, so editing a profile or an image
    redoes what depends on it, and nothing else).  Returns whether it wrote."""
    hashes = {}
    for wall, image_path in sorted(images.items()):
        if image_path:
            if not Path(image_path).is_file():
                raise LampfabError(f"{image_path}: image not found")
            hashes[wall] = {"path": image_path, "sha256": artifacts.file_sha256(image_path)}
    text = json.dumps({**build.settings(), "images": hashes}, indent=2, sort_keys=True) + "\n"
    path = Path(path)
    if path.exists() and path.read_text() == text:
        return False
    with artifacts.atomic_path(path) as tmp:
        tmp.write_text(text)
    return True


def summary(build: Build) -> None:
    """One line per stage: wall time and its key figure."""
    keys = {"init": "method", "optimize": "final_loss", "solid": "volume_mm3", "check": "passed",
            "export": "bspline_deviation_mm"}
    names = {"check": "checks"}
    total = 0.0
    for stage in STAGES:
        p = build.path(f"{names.get(stage, stage)}.json")
        if not p.exists():
            continue
        data = artifacts.read_json(p)
        total += data.get("wall_time_s", 0.0)
        figs = data["figures"]
        if stage == "verify":
            key = ", ".join(f"{n} r {f['pearson']:.2f}" for n, f in figs["walls"].items())
        elif stage == "plan":
            key = f"{1 - figs['lost_share']:.0%} of the light on the wall planes"
        else:
            k = keys.get(stage)
            key = f"{k} {_fmt(figs.get(k))}" if k else ""
        print(f"{stage:9s} {data.get('wall_time_s', 0):7.1f} s  {key}")
    print(f"{'total':9s} {total:7.1f} s  -> {build.path('report.html')}")


# -- 1. prepare ---------------------------------------------------------------------
def prepare(build: Build, target: str, per_wall: dict[str, str]) -> dict:
    """One linear-luminance target per wall, letterboxed to the wall's aspect ratio."""
    from . import image

    sources = {w.name: per_wall.get(w.name) or target for w in build.walls}
    if not all(sources.values()):
        raise LampfabError("no target image given: set TARGET=path/to/image.png")
    report = artifacts.StageReport("prepare", {f"image_{k}": v for k, v in sources.items()}, build.settings())
    loaded = {}
    for wall in build.walls:
        src = sources[wall.name]
        if src not in loaded:
            loaded[src] = image.load_target(src)
        img = image.letterbox(loaded[src], *room.image_shape(wall, TARGET_PX))
        artifacts.write_linear_png16(build.path("targets", f"{wall.name}.png"), img)
        artifacts.write_png(build.path("targets", f"{wall.name}_preview.png"), img, normalize=False)
        report.figure(**{f"{wall.name}_mean_luminance": float(img.mean()),
                         f"{wall.name}_source": str(src)})
    report.write(build.path("prepare.json"))
    return report.data


# -- 2. plan ------------------------------------------------------------------------
def plan(build: Build) -> dict:
    """The un-optimized lens in the room: where its light falls, wall by wall.

    Each wall plane is rendered three times larger than its target rectangle so the
    report shows light that would fall outside it.
    """
    from . import lens, trace

    d = build.design
    report = artifacts.StageReport("plan", {}, build.settings())
    iv, if_ = build.inner()
    nu, nv = d.optimize.grid_u, d.optimize.grid_v
    verts, faces = lens.optical_mesh(build.cylinder, np.zeros((nu, nv)), d.optimize.tessellation, iv, if_)
    scene = trace.MeshScene(verts, faces)
    walls = build.walls
    big = [room.Wall(w.name, w.origin - w.right - w.down, 3 * w.right, 3 * w.down) for w in walls]
    px = d.verify.image_px
    shapes = [room.image_shape(w, 3 * px) for w in big]
    images, info = trace.render_walls(scene, build.light, 0.0, build.fab.ior, big, shapes,
                                      d.verify.photons, d.optimize.seed, d.verify.max_bounces)
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


# -- 3a. init (transport) -------------------------------------------------------------
def init(build: Build) -> dict:
    """The first lens: transport-based (default) or the source's plain cylinder."""
    from . import transport

    d, opt = build.design, build.design.optimize
    report = artifacts.StageReport("init", build.target_paths(), build.settings())
    grid = (opt.grid_u, opt.grid_v)
    if opt.init == "cylinder":
        heights = np.zeros(grid)
        report.figure(method="cylinder")
    else:
        iv, if_ = build.inner()
        heights, figs = transport.design(
            build.cylinder, build.walls, build.targets(min(64, opt.grid_v)), iv, if_, build.light,
            build.fab.ior, grid, opt.tessellation, opt.transport_rounds, opt.transport_photons,
            opt.smoothness, d.lens.max_offset_mm, build.fab.max_slope_deg, opt.seed,
            corrections=opt.transport_corrections, dump_share=opt.dump_share, log=_log)
        report.figure(method="transport", **figs)
    artifacts.write_npz(build.path("init.npz"), heights=heights)
    report.write(build.path("init.json"))
    return report.data


# -- 3b. optimize (the source's method) ---------------------------------------------------
def optimize(build: Build) -> dict:
    """Refine the initial lens by gradient descent through a differentiable renderer
    (``splat``, or the source's ``seed`` ptracer); resumes from a checkpoint."""
    from tqdm import tqdm

    from . import optimize as opt_mod

    d, opt = build.design, build.design.optimize
    report = artifacts.StageReport("optimize", {"init": build.path("init.npz"), **build.target_paths()},
                                   build.settings())
    init_heights = artifacts.read_npz(build.path("init.npz"))["heights"]
    if init_heights.shape != (opt.grid_u, opt.grid_v):
        raise LampfabError(f"{build.path('init.npz')}: grid {init_heights.shape} is not the profile's "
                           f"({opt.grid_u}, {opt.grid_v}); re-run init")
    iv, if_ = build.inner()
    targets = build.targets(opt.sensor_px)
    from .splat import SplatOptimizer

    method = {"seed": opt_mod.SeedOptimizer, "splat": SplatOptimizer}[opt.method]
    seed_opt = method(build.cylinder, iv, if_, build.light, build.fab.ior, build.walls, targets, opt,
                      d.lens.max_offset_mm, build.fab.max_slope_deg)
    checkpoint = build.path("checkpoint.npz")
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
        for k, wall in enumerate(build.walls):
            img = seed_opt.render(s.heights, k, seed=opt.seed + 1)
            artifacts.write_png(build.path("previews", f"step{s.step:06d}_{wall.name}.png"), img)

    bar = tqdm(total=opt.iterations, initial=state.step, desc="optimize", unit="step", disable=opt.iterations == 0,
               dynamic_ncols=True)

    def progress(s, loss, message):
        bar.update(s.step - bar.n)
        bar.set_postfix(loss=f"{loss:.4f}", level=s.level)
        if message:
            bar.write(f"optimize: step {s.step}: {message}")

    if state.step == 0 and opt.iterations:
        preview(state)
    try:
        state = seed_opt.run(state, save, preview, progress)
    except opt_mod.Interrupted:
        bar.close()
        raise LampfabError(f"optimize interrupted at step {state.step}; checkpoint saved to {checkpoint}, "
                           f"run the same command again to resume") from None
    bar.close()
    heights = state.heights
    artifacts.write_npz(build.path("heightmap.npz"), heights=heights, radius_mm=d.lens.outer_radius_mm,
                        height_mm=d.lens.height_mm)
    log = np.asarray(state.log).reshape(-1, 5)
    with artifacts.atomic_path(build.path("loss.csv")) as tmp:
        np.savetxt(tmp, log, delimiter=",", header="step,level,view,loss,seconds", comments="",
                   fmt=["%d", "%d", "%d", "%.6g", "%.3f"])
    report.figure(steps=int(state.step), resumed=resumed,
                  final_loss=float(log[-1, 3]) if len(log) else None,
                  median_step_s=float(np.median(log[:, 4])) if len(log) else None,
                  offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()))
    report.write(build.path("optimize.json"))
    checkpoint.unlink(missing_ok=True)
    return report.data


def _settings_hash(build: Build, init_heights: np.ndarray) -> str:
    import hashlib

    h = hashlib.sha256(json.dumps(build.settings(), sort_keys=True).encode())
    h.update(np.ascontiguousarray(init_heights).tobytes())
    for p in build.target_paths().values():
        h.update(artifacts.file_sha256(p).encode())
    return h.hexdigest()


def load_heights(build: Build) -> np.ndarray:
    return artifacts.read_npz(build.path("heightmap.npz"))["heights"]


# -- 4. solid -------------------------------------------------------------------------
def solid(build: Build) -> dict:
    """Outer shell minus inner layer and LED bore: one watertight solid in mm."""
    from . import solid as solid_mod

    report = artifacts.StageReport("solid", {"heightmap": build.path("heightmap.npz")}, build.settings())
    iv, if_ = build.inner()
    s = solid_mod.build_solid(build.cylinder, load_heights(build), build.design.optimize.tessellation,
                              iv, if_, build.fab.mount_radius_mm)
    artifacts.write_npz(build.path("solid.npz"), vertices=s.vertices, faces=s.faces)
    report.figure(volume_mm3=s.volume_mm3, triangles=int(len(s.faces)), genus=s.genus,
                  bore=dataclasses.asdict(s.bore))
    report.write(build.path("solid.json"))
    return report.data


# -- 5. check -------------------------------------------------------------------------
def check(build: Build, allow_fail: bool) -> dict:
    """Manufacturability against the fabrication profile; raises CheckFailed on a fail."""
    from . import checks

    report = artifacts.StageReport("check", {"solid": build.path("solid.npz")}, build.settings())
    iv, if_ = build.inner()
    heights = load_heights(build)
    sv = artifacts.read_npz(build.path("solid.npz"))
    results = checks.run_checks(build.cylinder, heights, iv, if_, sv["vertices"], sv["faces"], build.fab, build.light)
    checks.paint_checks(build.path("checks.png"), build.cylinder, heights, iv, if_, sv["vertices"], sv["faces"],
                        build.fab, build.light, results)
    failed = [r for r in results if r["applies"] and not r["passed"]]
    report.figure(checks=results, passed=not failed, allowed_to_fail=allow_fail)
    for r in results:
        if r["applies"]:
            _log(f"check: {r['name']}: {'pass' if r['passed'] else 'FAIL'} ({_fmt(r['value'])} {r['unit']}, "
                 f"limit {_fmt(r['limit'])})")
    if failed and not allow_fail:
        report.write(build.path("checks.failed.json"))
        worst = failed[0]
        place = worst.get("worst") or {}
        where = f" at u {place['u_deg']:.1f}°, z {place['z_mm']:.1f} mm" if "u_deg" in place else ""
        raise CheckFailed(f"check {worst['name']} failed: {_fmt(worst['value'])} {worst['unit']} against "
                          f"limit {_fmt(worst['limit'])}{where} ({len(failed)} failed; see "
                          f"{build.path('checks.failed.json')} and checks.png; ALLOW_FAIL=1 to go on)", failed)
    build.path("checks.failed.json").unlink(missing_ok=True)
    report.write(build.path("checks.json"))
    return report.data


def _fmt(value) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


# -- 6. export ------------------------------------------------------------------------
def export(build: Build) -> dict:
    """lens.stl and lens.step, both read back and checked, and design.json."""
    from . import solid as solid_mod
    from . import step, stl
    from .tolerances import VOLUME_REL

    d, fab = build.design, build.fab
    report = artifacts.StageReport("export", {"solid": build.path("solid.npz"),
                                              "heightmap": build.path("heightmap.npz")}, build.settings())
    sv = artifacts.read_npz(build.path("solid.npz"))
    stl_bytes = stl.write_stl(build.path("lens.stl"), sv["vertices"], sv["faces"])
    rv, rf = stl.read_stl(build.path("lens.stl"))
    stl_volume = solid_mod.mesh_volume(rv, rf)
    edges = solid_mod.edge_check(rf)
    if not (edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1):
        raise LampfabError(f"{build.path('lens.stl')}: read back it is not one closed, consistently wound "
                           f"solid ({edges})")
    iv, if_ = build.inner()
    step_info = step.write_step(build.path("lens.step"), build.cylinder, load_heights(build), iv, if_,
                                fab.mount_radius_mm, d.export.step_samples_u, d.export.step_samples_v,
                                expected_volume_mm3=stl_volume)
    back = step.read_step(build.path("lens.step"))
    rel = abs(back["volume_mm3"] - stl_volume) / stl_volume
    if not (back["n_solids"] == 1 and back["valid"] and back["closed"] and rel <= VOLUME_REL):
        raise LampfabError(f"{build.path('lens.step')}: read back it is not one valid closed solid matching the "
                           f"STL within {VOLUME_REL:.1%} ({back}, volume difference {rel:.3%})")
    design_json = {
        "units": "mm",
        "light": {"position": build.light.tolist(), "radius": fab.led_radius_mm},
        "material": {"name": fab.material, "ior": fab.ior},
        "lens": {"stl": "lens.stl", "step": "lens.step"},
        "walls": [w.to_json(f"targets/{w.name}.png") for w in build.walls],
    }
    artifacts.write_json(build.path("design.json"), design_json)
    report.figure(stl_bytes=stl_bytes, stl_volume_mm3=stl_volume, stl_triangles=int(len(rf)),
                  step_bytes=step_info["file_bytes"], step_volume_mm3=back["volume_mm3"],
                  step_stl_volume_rel=rel, step_faces=back["faces"],
                  bspline_deviation_mm=step_info["deviation_mm"],
                  bspline_poles=[step_info["poles_u"], step_info["poles_v"]])
    _log(f"export: lens.stl {stl_bytes / 1e6:.1f} MB, lens.step {step_info['file_bytes'] / 1e6:.1f} MB, "
         f"B-spline deviation {step_info['deviation_mm'] * 1000:.3g} µm, volumes agree to {rel:.2e}")
    report.write(build.path("export.json"))
    return report.data


# -- 7. verify ------------------------------------------------------------------------
def verify(build: Build) -> dict:
    """Render the exported STL (true facets) from design.json; compare; write report.html."""
    from . import report as report_mod
    from . import verify as verify_mod

    v = build.design.verify
    design_path = build.path("design.json")
    report = artifacts.StageReport("verify", {"design": design_path, "stl": build.path("lens.stl")},
                                   build.settings())
    figures = verify_mod.verify(design_path, build.path("verify"), v.image_px, v.photons,
                                build.design.optimize.seed + 7, v.max_bounces)
    for name, f in figures["walls"].items():
        _log(f"verify: {name}: Pearson r {f['pearson']:.3f}, SSIM {f['ssim']:.3f}, {f['share']:.1%} of the light "
             f"(LED {figures['led_radius_mm']} mm: r {f['led_pearson']:.3f})")
    report.figure(**figures)
    report.write(build.path("verify.json"))
    _write_report(build, figures, report_mod)
    return report.data


def _write_report(build: Build, figures: dict, report_mod) -> None:
    walls = []
    for name, f in figures["walls"].items():
        walls.append({"name": name, "target_png": build.path("targets", f"{name}_preview.png"),
                      "render_png": build.path("verify", f"{name}.png"),
                      "blur_png": build.path("verify", f"{name}_led.png"),
                      "pearson": f["pearson"], "ssim": f["ssim"], "share": f["share"],
                      "blur_pearson": f["led_pearson"], "blur_ssim": f["led_ssim"], "blur_share": f["led_share"]})
    stage_figures = {}
    for stage in ("init", "optimize", "solid", "export"):
        p = build.path(f"{stage}.json")
        if p.exists():
            data = artifacts.read_json(p)
            flat = {k: v for k, v in data["figures"].items() if not isinstance(v, (dict, list))}
            flat["wall_time_s"] = data.get("wall_time_s")
            stage_figures[stage] = flat
    checks = build.path("checks.json") if build.path("checks.json").exists() else build.path("checks.failed.json")
    sections = []
    if checks.exists():
        rows = "".join(
            f"<tr><td>{r['name']}</td><td class=\"{'ok' if r['passed'] else 'fail'}\">"
            f"{'pass' if r['passed'] else 'FAIL'}</td><td>{_fmt(r['value'])} {r['unit']}</td>"
            f"<td>{_fmt(r['limit'])}</td></tr>"
            for r in artifacts.read_json(checks)["figures"]["checks"] if r["applies"])
        sections.append((f"Fabrication checks ({build.fab.name})",
                         f"<table><tr><th>check</th><th>result</th><th>value</th><th>limit</th></tr>{rows}</table>"))
    sections.append(("Next steps", (
        f"<p>Send <code>lens.stl</code> to the printer's slicer (binary STL, millimetres, Z up, standing on its "
        f"base) or <code>lens.step</code> to the CNC shop (one solid; the outer surface is a single B-spline "
        f"face). Material: {build.fab.material} (n = {build.fab.ior}). The LED goes into the bore in the base "
        f"(radius {build.fab.mount_radius_mm} mm); place the lamp with its +y side facing the front wall, "
        f"{build.design.room.wall_distance_mm:.0f} mm from the front, left and right walls.</p>")))
    report_mod.write_report(build.path("report.html"), f"lampfab: {build.out.name}", walls, stage_figures, sections)
