"""What the stages do differently for each kind of lens (``[lens] kind``).

``LensKind`` declares it; ``Lamp`` is the lamp around its LED, ``panel.kind.Panel`` the
flat panel of the source's prior work.  ``Build.kind`` picks one, once.  Everything else
is the same for both and lives in the stages: prepare, the stage reports, the STL and its
read-back, verify's renders and comparison, report.html.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod

import numpy as np

from . import progress


class LensKind(ABC):
    """The parts of the stages that depend on the kind of lens; ``build`` is the
    ``build.Build`` a stage runs in."""

    # Whether optimize refines the first design; if not, the first design is the lens.
    refines: bool = True

    @abstractmethod
    def check_inputs(self, build) -> None:
        """Read what the stages will read besides the images; raise LampfabError."""

    @abstractmethod
    def plain_optics(self, build) -> tuple:
        """(the lens without relief as a ``trace.MeshScene``, its light's emitter: None for
        the LED), for the plan."""

    @abstractmethod
    def sharpness_budget(self, build) -> dict | None:
        """plan's figures on how much the LED will blur each wall (``budget.measure``), or
        None where the light has no emitter to blur with."""

    @abstractmethod
    def first_design(self, build) -> tuple[np.ndarray, dict]:
        """init: ((nu, nv) mm heights, figures for init.json, "method" first, with the
        ``slope_limit_deg`` it designed under)."""

    def slots(self, build, heights: np.ndarray):
        """The black-filled slots of a lens of ``heights`` (``slots.Slots``), or None."""
        return None

    @abstractmethod
    def solid(self, build, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """The closed solid of ``heights``: ((n, 3) mm vertices, (m, 3) int faces,
        figures for solid.json)."""

    @abstractmethod
    def check(self, build, vertices: np.ndarray, faces: np.ndarray) -> list:
        """Every ``checks.CheckResult`` of the solid, in ``checks.NAMES`` order; paints
        ``build.checks_picture``."""

    @abstractmethod
    def write_step(self, build, stl_volume_mm3: float) -> dict:
        """Write ``build.lens_step``, checked against the STL's volume; its figures
        (``step_file.write_step``'s)."""

    @abstractmethod
    def light_json(self, build) -> dict:
        """design.json's ``light``."""

    def paint_json(self, build) -> dict:
        """What design.json's ``lens`` says is painted black (``paint``): nothing, unless
        the kind paints."""
        return {"black_paint": "none"}

    @abstractmethod
    def finishing(self, build, walls: dict) -> dict:
        """verify.json's tolerance study and finishing advice ({} where there are none),
        which may cite verify's figures of the ``walls``."""

    @abstractmethod
    def report_light(self, build, design: dict) -> dict:
        """The glowing body of report.html's room pictures, as design.json's light:
        position (mm), radius (mm), and a filament's length."""

    @abstractmethod
    def heightmap_picture(self, build, wall_names: list[str], path) -> None:
        """The outer surface's relief as a colour map, written to ``path``."""

    @abstractmethod
    def report_pictures(self, build, pictures: dict) -> tuple:
        """report.html's room picture and its lens section: (a ``report.Picture``, a list
        of them), from ``report_page.pictures``'s paths."""

    @abstractmethod
    def next_steps(self, build) -> str:
        """What to do with the files (HTML)."""


class Lamp(LensKind):
    """The lamp: a lens around its LED, outer layer a radial heightmap over a cylinder."""

    def check_inputs(self, build) -> None:
        build.inner()

    def solid_maker(self, build):
        """``make(heights, slots=None)``: the lens solid (``solid.Solid``, mm) the solid
        stage builds from (nu, nv) heights in mm, the inner layer loaded once for every
        call; ``slots`` (``slots.Slots``) cut from it.

        The plan and the tolerance study trace it too, not the bore-less optical mesh: the
        bore through the base removes the glass under the cavity's floor, whose
        reflections would otherwise light a spot on a wall."""
        from .. import solid

        iv, if_ = build.inner()

        def make(heights: np.ndarray, slots=None):
            return solid.build_solid(build.cylinder, heights, build.design.optimize.tessellation, iv, if_,
                                     build.fab.mount_radius_mm, slots=slots)
        return make

    def plain_optics(self, build) -> tuple:
        from .. import trace

        grid = (build.design.optimize.grid_u, build.design.optimize.grid_v)
        plain = self.solid_maker(build)(np.zeros(grid))
        return trace.MeshScene(plain.vertices, plain.faces), None

    def sharpness_budget(self, build) -> dict:
        from . import budget

        return budget.measure(build)

    def first_design(self, build) -> tuple[np.ndarray, dict]:
        """The transport design (default), or the source's plain cylinder."""
        from .. import transport

        opt = build.design.optimize
        grid = (opt.grid_u, opt.grid_v)
        if opt.init == "cylinder":
            return np.zeros(grid), {"method": "cylinder", "slope_limit_deg": build.limits.max_slope_deg}
        bar = progress.steps_bar(transport.fit_steps(grid, opt.transport_rounds, opt.transport_corrections), "init")

        def step(figures):
            bar.update()
            bar.set_postfix(error=f"{figures['rms_landing_error_mm']:.1f} mm")

        heights, figs = build.transport_design(opt, build.inner(), log=bar.write, on_step=step)
        bar.update(bar.total - bar.n)  # a fit that converged early skips its last steps
        bar.close()
        return heights, {"method": "transport", **figs}

    def solid(self, build, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """Outer shell minus inner layer, LED bore and the profile's slots: one watertight
        solid in mm."""
        slots = self.slots(build, heights)
        s = self.solid_maker(build)(heights, slots)
        return s.vertices, s.faces, {"volume_mm3": s.volume_mm3, "triangles": int(len(s.faces)),
                                     "genus": s.genus, "bore": dataclasses.asdict(s.bore),
                                     "slots": None if slots is None else slots.to_json()}

    def slots(self, build, heights: np.ndarray):
        """The profile's slots (``slots.plan``) at init's sector edges, as far out as the
        outer surface of ``heights`` allows, or None."""
        from .. import slots, surface

        width = build.design.lens.slot_width_mm
        if not width:
            return None
        outer = surface.closed_outer_vertices(build.cylinder, heights, build.design.optimize.tessellation)[:-2]
        inner_vertices = build.inner()[0]
        cavity_reach = max(float(np.hypot(inner_vertices[:, 0], inner_vertices[:, 1]).max()),
                           build.fab.mount_radius_mm)
        return slots.plan(width, _sectors(build), cavity_reach, outer, build.design.lens.height_mm,
                          build.fab.min_wall_mm)

    @staticmethod
    def made_slots(build):
        """The slots the solid stage cut (``slots.Slots``), or None."""
        from ..slots import Slots

        return Slots.from_json((build.stage_report("solid") or {}).get("figures", {}).get("slots"))

    def check(self, build, vertices: np.ndarray, faces: np.ndarray) -> list:
        from .. import checks

        iv, if_ = build.inner()
        heights = build.heights()
        results = checks.run_checks(build.cylinder, heights, iv, if_, vertices, faces, build.fab, build.light)
        checks.paint_checks(build.checks_picture, build.cylinder, heights, iv, if_, build.fab, results)
        return results

    def write_step(self, build, stl_volume_mm3: float) -> dict:
        from ..export import step_file

        iv, if_ = build.inner()
        export = build.design.export
        return step_file.write_step(build.lens_step, build.cylinder, build.heights(), iv, if_,
                                    build.fab.mount_radius_mm, export.step_samples_u, export.step_samples_v,
                                    expected_volume_mm3=stl_volume_mm3, slots=self.made_slots(build))

    def light_json(self, build) -> dict:
        """The LED: its centre, its emitting shape and size, the part."""
        led, source = build.led, build.source
        return {"position": build.light.tolist(), "shape": led.shape, "radius": led.radius_mm,
                "length": led.length_mm, "facing_deg": list(source.facing_deg), "offset_mm": source.offset_mm,
                "fin_radius_mm": source.fin_radius_mm, "fin_height_mm": source.fin_height_mm,
                "part": led.part, "flux_lm": led.flux_lm}

    def paint_json(self, build) -> dict:
        """The profile's black paint, the arc of u (deg) of the outer surface that lights
        no wall where it paints there (``_sectors``), and the black-filled slots the solid
        stage cut."""
        from .. import paint

        choice = build.design.lens.black_paint
        back = paint.free_span_deg(_sectors(build)) if choice == "top_base_and_back" else None
        slots = self.made_slots(build)
        return {"black_paint": choice, "painted_u_deg": None if back is None else [round(a, 2) for a in back],
                "slots": None if slots is None else slots.to_json()}

    def finishing(self, build, walls: dict) -> dict:
        """The tolerance study and the post-processing guidance (``guidance``)."""
        from .. import artifacts, guidance, tolerance_study

        d, v, fab = build.design, build.design.verify, build.fab
        make = self.solid_maker(build)

        def lens_mesh(heights):
            made = make(heights)
            return made.vertices, made.faces

        study = tolerance_study.study(build.cylinder, build.heights(), lens_mesh, build.source.point(),
                                      fab.ior, build.walls, build.targets(v.image_px), v.study_photons,
                                      d.optimize.seed + 11, v.max_bounces, fab.surface_error_mm)
        progress.log(f"verify: polishing allowance {'>= ' if study['allowance_at_least'] else ''}"
                     f"{study['allowance_mm'] * 1000:.0f} µm; the profile's {fab.surface_error_mm * 1000:.0f} µm "
                     f"costs r {study['profile_error_drop']:.3f}")
        return {"tolerance": study,
                "guidance": guidance.advice(fab, build.led, [w.name for w in build.walls], build.light, study,
                                            artifacts.read_json(build.design_file)["lens"], walls)}

    def report_light(self, build, design: dict) -> dict:
        return design["light"]

    def heightmap_picture(self, build, wall_names: list[str], path) -> None:
        """The unrolled heightmap, each sector labelled with its wall."""
        from .. import pictures

        pictures.heightmap_map(build.cylinder, build.heights(), wall_names, path)

    def report_pictures(self, build, pictures: dict) -> tuple:
        from ..report import Picture

        room = Picture("The lamp in its room", pictures["room"], note=(
            "What a person standing behind the lamp sees in a dark room: lens.stl path-traced as glass, the walls "
            "lit by the LED's light traced through the same file, bounce light and a little ambient light."))
        return room, [
            Picture("The lens, close up", pictures["closeup"], note="lens.stl as glass, its LED lit"),
            Picture("Its shape", pictures["lens"], note="lens.stl as a matte object: the bumps of the outer layer "
                                                        "make the pictures"),
            Picture("The outer layer, unrolled", pictures["heightmap"], note="radial offset from the plain cylinder; "
                    "each 90° sector lights the wall named above it; orange bulges out, blue goes in")]

    def next_steps(self, build) -> str:
        return (f"<p>Send <code>lens.stl</code> to the printer's slicer (binary STL, millimetres, Z up, standing on "
                f"its base) or <code>lens.step</code> to the CNC shop or into FreeCAD / Fusion (one solid; the outer "
                f"surface is a single B-spline face). Material: {build.fab.material} (n = {build.fab.ior}). The LED "
                f"goes into the bore in the base (radius {build.fab.mount_radius_mm} mm); place the lamp with its +y "
                f"side facing the front wall, {build.design.room.wall_distance_mm:.0f} mm from the front, left and "
                f"right walls.</p>")


def _sectors(build) -> dict[str, tuple[float, float]]:
    """Each wall's sector of u (deg): init's (each wall's own, as the design shifted
    them), or the walls' centred sectors for a first design without."""
    init = build.stage_report("init") or {}
    return init.get("figures", {}).get("sectors_deg") or {w.name: w.sector_deg() for w in build.walls}
