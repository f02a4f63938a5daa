"""The build folder of one design: where every artifact lives, how each is read and
written, and the profiles the stages run with.

``Build`` is the one owner of the artifacts' paths: a stage asks it for ``heights()`` or
``save_solid(...)``, never for a file name.  It also picks the lens kind, once
(``kind``): the lamp, or the source's flat panel (``kind.LensKind``).

The folder ``out`` (every file is written atomically, ``artifacts``):

    settings.json                 the resolved profiles and input hashes Make depends on
    <stage>.json                  each stage's report (``report_file``); the fabrication
                                  check's is checks.json, or checks.failed.json
    targets/<wall>.png            prepare: the 16-bit linear target, and <wall>_preview.png
    plan/<wall>.png               plan: where the plain lens's light falls
    init.npz                      init: the first design's heights
    heightmap.npz                 optimize: the refined heights; with checkpoint.npz,
                                  optimize_render.npz, loss.csv, previews/, optimization.gif
    solid.npz                     solid: the solid's vertices and faces
    checks.png                    fabcheck
    lens.stl, lens.step,          export
    lens.glb, design.json,
    fins.stl                      (a post's fins, to print in black)
    verify/, report/, report.html verify
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import artifacts, profile, room, surface
from ..errors import LampfabError
from ..source import FLAT
from .kind import Lamp, LensKind

# The stages in the order make runs them.
STAGES = ("prepare", "plan", "init", "optimize", "solid", "fabcheck", "export", "verify")
# The fabrication check's report keeps the name it has always had, beside checks.png.
_REPORT_NAMES = {"fabcheck": "checks"}

# How prepare's report names a wall's source when it shows words: this, then the phrase.
TEXT_SOURCE = "text: "


def _artifact(*parts: str) -> property:
    """A ``Build`` property: the path of one artifact in the build folder."""
    return property(lambda build: build.out.joinpath(*parts))


@dataclass(frozen=True)
class Build:
    """The build folder ``out`` of one design and the profiles it uses: ``fab``'s bore
    is already widened for ``led``'s board (``profile.with_bore_for``)."""
    out: Path
    design: profile.Design
    fab: profile.Fabrication
    led: profile.Led

    @staticmethod
    def open(out, design_name: str, fab_name: str, led_name: str = profile.DEFAULT_LED) -> "Build":
        led = profile.load_led(led_name)
        design = profile.load_design(design_name)
        fab = profile.load_fabrication(fab_name)
        profile.check_led_for(design, led)
        profile.check_fab_for(design, fab)
        return Build(Path(out), design, profile.with_bore_for(fab, led), led)

    # -- the lens and its room, as the stages use them ------------------------------------
    @functools.cached_property
    def kind(self) -> LensKind:
        """What the stages do differently for this lens: a lamp, or a panel."""
        if self.design.lens.kind == "panel":
            from ..panel.kind import Panel

            return Panel()
        return Lamp()

    @property
    def cylinder(self) -> surface.Cylinder:
        return surface.Cylinder(self.design.lens.outer_radius_mm, self.design.lens.height_mm,
                                self.fab.sector_creases)

    @property
    def limits(self):
        """What the outer surface may do (``limits.Limits``), from both profiles."""
        from ..limits import Limits

        return Limits.of(self.design, self.fab)

    @property
    def light(self) -> np.ndarray:
        return room.light_position(self.design)

    @property
    def source(self):
        """The LED at its place (``source.Source``)."""
        from ..source import Source

        return Source.of_led(self.light, self.led, [room.SECTOR_CENTRE_DEG[w] for w in self.design.room.walls])

    @property
    def walls(self) -> list[room.Wall]:
        return room.walls(self.design)

    def settings(self) -> dict:
        return {"design": profile.as_dict(self.design), "fabrication": profile.as_dict(self.fab),
                "led": profile.as_dict(self.led)}

    def begin(self, stage: str, inputs: dict) -> artifacts.StageReport:
        """Start a stage: refuse it with a message if it needs more memory than is
        free, then open its report, with the profiles and the inner layer's file among
        the hashed inputs."""
        from .. import resources
        from ..inner import inner_file

        resources.check_memory(stage, self.design)
        files = {"design_profile": self.design.path, "fabrication_profile": self.fab.path,
                 "led_profile": self.led.path}
        # A bundled layer made with another hollow has no file: the profile describes it.
        inner_layer = inner_file(self.design.lens.inner_mesh, self.design.lens.hollow_radius_mm)
        if inner_layer:
            files["inner_layer"] = inner_layer
        return artifacts.StageReport(stage, {**inputs, **files}, self.settings(), seed=self.design.optimize.seed)

    def inner(self) -> tuple[np.ndarray, np.ndarray]:
        """The lamp's inner layer: ((n, 3) mm vertices, (m, 3) int faces), wound outward;
        read and checked once per build, the arrays shared by every caller (none writes
        to them; manifold3d refuses read-only ones)."""
        return self._inner_layer

    @functools.cached_property
    def _inner_layer(self) -> tuple[np.ndarray, np.ndarray]:
        from .. import inner

        lens = self.design.lens
        vertices, faces = inner.load_inner(lens.inner_mesh or None, lens.inner_scale, self.light,
                                           lens.outer_radius_mm, lens.max_offset_mm, lens.height_mm,
                                           lens.hollow_radius_mm)
        inner.check_led_inside(vertices, faces, self.source, f"{self.design.path} with LED={self.led.name}")
        return vertices, faces

    def transport_design(self, opt, inner, **progress) -> tuple[np.ndarray, dict]:
        """``transport.design`` for this build's lens, room, light and limits with the
        ``[optimize]`` settings ``opt``; ``progress``: log, on_step, on_pass."""
        from .. import transport

        return transport.design(self.cylinder, self.walls, self.targets(opt.sensor_px), *inner, self.source,
                                self.fab.ior, self.limits, opt, **progress)

    def optimizer(self, opt, inner, targets, limits=None, slots=None):
        """The refinement ``opt.method`` names, for this build's lens, room, light and
        ``limits`` (default: the profiles' ``limits``), against ``targets`` (one image per
        wall), the light ending in ``slots`` (``slots.Slots``)."""
        from .. import optimize
        from ..splat import SplatOptimizer

        method = {"ptracer": optimize.PtracerOptimizer, "splat": SplatOptimizer}[opt.method]
        if opt.method == "ptracer" and self.source.shape in FLAT:
            raise LampfabError(f"{self.design.path}: [optimize] method \"ptracer\" lights the lens with Mitsuba's "
                               f"point light, which shines every way; LED={self.led.name} shines from flat faces: "
                               f"use method \"splat\"")
        source = self.source if opt.design_light == "led" else self.source.point()
        return method(self.cylinder, *inner, source, self.fab.ior, self.walls, targets, opt, limits or self.limits,
                      slots)

    # -- where each artifact lives ----------------------------------------------------------
    def report_file(self, stage: str) -> Path:
        """The JSON report of ``stage`` (one of ``STAGES``)."""
        return self.out.joinpath(f"{_REPORT_NAMES.get(stage, stage)}.json")

    settings_file = _artifact("settings.json")
    failed_checks_file = _artifact("checks.failed.json")
    init_file = _artifact("init.npz")
    heightmap_file = _artifact("heightmap.npz")
    checkpoint_file = _artifact("checkpoint.npz")
    optimizer_render_file = _artifact("optimize_render.npz")
    loss_file = _artifact("loss.csv")
    previews_dir = _artifact("previews")
    gif_file = _artifact("optimization.gif")
    solid_file = _artifact("solid.npz")
    checks_picture = _artifact("checks.png")
    lens_stl = _artifact("lens.stl")
    lens_step = _artifact("lens.step")
    lens_glb = _artifact("lens.glb")
    fins_stl = _artifact("fins.stl")
    design_file = _artifact("design.json")
    verify_dir = _artifact("verify")
    report_html = _artifact("report.html")

    def target_file(self, wall: str) -> Path:
        """A wall's prepared target: a 16-bit linear PNG."""
        return self.out.joinpath("targets", f"{wall}.png")

    def target_preview(self, wall: str) -> Path:
        """A wall's prepared target as an 8-bit sRGB PNG to look at."""
        return self.out.joinpath("targets", f"{wall}_preview.png")

    def plan_picture(self, wall: str) -> Path:
        return self.out.joinpath("plan", f"{wall}.png")

    def preview_picture(self, step: int, wall: str) -> Path:
        """The optimizer's picture of a wall at ``step``, as ``pictures.optimization_gif`` reads it."""
        from ..pictures import preview_name

        return self.previews_dir / preview_name(step, wall)

    def verify_pictures(self, wall: str) -> tuple[Path, Path, Path]:
        """verify's renders of a wall: (point light PNG, LED PNG, the images as .npz)."""
        from ..verify import wall_files

        return wall_files(self.verify_dir, wall)

    def report_picture(self, name: str) -> Path:
        """One of report.html's own pictures (room, lens, heightmap)."""
        return self.out.joinpath("report", f"{name}.png")

    # -- reading and writing them -------------------------------------------------------------
    def targets(self, width_px: int) -> list[np.ndarray]:
        """Each wall's prepared target resampled to ``width_px`` wide (rows, cols)."""
        from .. import image

        return [image.letterbox(artifacts.read_linear_png16(self.target_file(w.name)),
                                *room.image_shape(w, width_px)) for w in self.walls]

    def target_paths(self) -> dict:
        """The prepared targets as a stage report's inputs."""
        return {f"target_{w.name}": self.target_file(w.name) for w in self.walls}

    def save_targets(self, prepared: dict[str, np.ndarray]) -> None:
        """Each wall's (rows, cols) linear target in [0, 1], and its preview."""
        for name, img in prepared.items():
            artifacts.write_linear_png16(self.target_file(name), img)
            artifacts.write_png(self.target_preview(name), img, normalize=False)

    def first_lens(self):
        """The first design (init.npz): (nu, nv) mm heights, checked against the profile's
        grid, and ``limits`` with the slopes it chose (``limits.Limits.steepened``), which
        the refinement keeps."""
        saved = artifacts.read_npz(self.init_file)
        heights = saved["heights"]
        opt = self.design.optimize
        if heights.shape != (opt.grid_u, opt.grid_v):
            raise LampfabError(f"{self.init_file}: grid {heights.shape} is not the profile's "
                               f"({opt.grid_u}, {opt.grid_v}); re-run init")
        if not np.all(np.isfinite(heights)):
            raise LampfabError(f"{self.init_file}: {int(np.sum(~np.isfinite(heights)))} heights are NaN or "
                               f"Inf; re-run init (make init), and report it if it happens again")
        if "slope_limit_deg" not in saved:
            raise LampfabError(f"{self.init_file}: made by an older lampfab (no slope limit); re-run init")
        return heights, self.limits.with_slope(float(saved["slope_limit_deg"]))

    def save_init(self, heights: np.ndarray, slope_limit_deg: float) -> None:
        """The first design and the slope limit it chose."""
        artifacts.write_npz(self.init_file, heights=heights, slope_limit_deg=slope_limit_deg)

    def heights(self) -> np.ndarray:
        """The optimized outer layer: (nu, nv) float64 mm offsets (heightmap.npz)."""
        return artifacts.read_npz(self.heightmap_file)["heights"]

    def save_heights(self, heights: np.ndarray, **lens_size: float) -> None:
        """The optimized heights, with ``lens_size`` (the lamp's radius_mm and height_mm)
        so the file describes its surface without the profile."""
        artifacts.write_npz(self.heightmap_file, heights=heights, **lens_size)

    def solid_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The solid (solid.npz): ((n, 3) float64 mm vertices, (m, 3) int faces)."""
        saved = artifacts.read_npz(self.solid_file)
        return saved["vertices"], saved["faces"]

    def save_solid(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        artifacts.write_npz(self.solid_file, vertices=vertices, faces=faces)

    def stage_report(self, stage: str) -> dict | None:
        """A finished stage's report, None before it ran."""
        path = self.report_file(stage)
        return artifacts.read_json(path) if path.exists() else None

    def wall_texts(self) -> dict[str, str]:
        """{wall name: its phrase} for the walls prepare set words on ({} before it ran)."""
        prepared = self.stage_report("prepare")
        figures = prepared["figures"] if prepared else {}
        return {w.name: str(figures[f"{w.name}_source"])[len(TEXT_SOURCE):] for w in self.walls
                if str(figures.get(f"{w.name}_source", "")).startswith(TEXT_SOURCE)}

    def texts_to_read(self) -> dict[str, str]:
        """``wall_texts`` where Tesseract is installed to read them back ({} otherwise)."""
        from .. import ocr

        return self.wall_texts() if ocr.available() else {}

    def checks_report(self) -> dict | None:
        """The fabrication check's report, passed or failed (None before it ran)."""
        for path in (self.report_file("fabcheck"), self.failed_checks_file):
            if path.exists():
                return artifacts.read_json(path)
        return None
