"""What the stages do differently for a panel (``[lens] kind = "panel"``): the panel's
``pipeline.kind.LensKind``.

The panel's geometry is in ``geometry``, its design in ``transport``, its checks in
``checks``, its STEP in ``brep``; the stages do the rest as for the lamp.
"""

from __future__ import annotations

import numpy as np

from ..errors import GeometryError
from ..pipeline import progress
from ..pipeline.kind import LensKind
from . import geometry as panel


def shape(build) -> panel.PanelShape:
    p = build.design.panel
    return panel.PanelShape(p.width_mm, p.height_mm, p.thickness_mm)


def _grid(build) -> tuple[int, int]:
    return build.design.optimize.grid_u, build.design.optimize.grid_v


class Panel(LensKind):
    """A flat clear panel in a collimated beam, its relief facing the wall."""

    # The transport design is the panel: the profile allows no refinement steps.
    refines = False

    def check_inputs(self, build) -> None:
        """A panel has no inner layer: nothing more to read."""

    def plain_optics(self, build) -> tuple:
        """The flat panel (no relief) and its parallel beam."""
        from .. import trace

        verts, faces = panel.closed_mesh(shape(build), np.zeros(_grid(build)), build.design.optimize.tessellation)
        return trace.MeshScene(verts, faces), panel.collimated_emitter(shape(build))

    def sharpness_budget(self, build) -> None:
        """A collimated beam's spread has no LED picture to measure: verify renders it."""
        return None

    def first_design(self, build) -> tuple[np.ndarray, dict]:
        """The relief by collimated transport (``transport``)."""
        from . import transport

        opt = build.design.optimize
        heights, figs = transport.design(
            shape(build), build.walls[0], build.targets(min(64, opt.grid_u))[0], build.fab.ior, _grid(build),
            opt.transport_rounds, opt.transport_corrections, opt.smoothness, build.design.panel.max_relief_mm,
            build.limits.max_slope_deg, log=progress.log)
        return heights, {"method": "transport (collimated panel)", "slope_limit_deg": build.limits.max_slope_deg,
                         **figs}

    def solid(self, build, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
        """The panel's closed mesh (relief, sides, back face), checked closed and one body."""
        from .. import solid

        verts, faces = panel.closed_mesh(shape(build), heights, build.design.optimize.tessellation)
        edges = solid.edge_check(faces)
        volume = solid.mesh_volume(verts, faces)
        if not (edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1 and volume > 0):
            raise GeometryError(f"panel mesh is not one closed, outward-wound body: {edges}, volume {volume:.3f} mm^3")
        return verts, faces, {"volume_mm3": volume, "triangles": int(len(faces)), "genus": 0}

    def check(self, build, vertices: np.ndarray, faces: np.ndarray) -> list:
        from . import checks

        heights = build.heights()
        fields = checks.relief_fields(shape(build), heights)
        results = checks.run_checks(shape(build), heights, vertices, faces, build.fab, fields)
        checks.paint(build.checks_picture, fields, build.fab)
        return results

    def write_step(self, build, stl_volume_mm3: float) -> dict:
        from . import brep

        return brep.write_step(build.lens_step, shape(build), build.heights(), stl_volume_mm3)

    def light_json(self, build) -> dict:
        return panel.light_json(shape(build), build.design.panel.divergence_deg)

    def finishing(self, build, walls: dict) -> dict:
        """The lamp's tolerance study and finishing advice are not made for a panel."""
        return {}

    def report_light(self, build, design: dict) -> dict:
        """The collimated lamp stands for the beam: a bright ball behind the panel."""
        s = shape(build)
        return {"position": [0.0, -3 * s.thickness_mm - s.width_mm, s.height_mm / 2], "radius": s.width_mm / 4}

    def heightmap_picture(self, build, wall_names: list[str], path) -> None:
        """The relief as a colour map."""
        relief_map(shape(build), build.heights(), path)

    def report_pictures(self, build, pictures: dict) -> tuple:
        from ..report import Picture

        room = Picture("The panel in its room", pictures["room"], note=(
            "The exported panel path-traced as glass, a bright ball behind it standing for the collimated lamp; "
            "the wall lit by the beam (its real spread) traced through the same file."))
        return room, [
            Picture("The panel, close up", pictures["closeup"], note="lens.stl as glass"),
            Picture("Its shape", pictures["lens"], note="lens.stl as a matte object: the relief makes the picture"),
            Picture("The relief", pictures["heightmap"], note="offset from the middle plane, seen from the beam's "
                                                              "side, x across and z up")]

    def next_steps(self, build) -> str:
        p, fab = build.design.panel, build.fab
        return (f"<p>Send <code>lens.stl</code> to the printer's slicer (binary STL, millimetres, Z up, standing on "
                f"its lower edge) or <code>lens.step</code> to the CNC shop (one solid; the relief is a single "
                f"B-spline face, the other five faces are planes). Material: {fab.material} (n = {fab.ior}). Light "
                f"the flat back face with a collimated beam at least {p.width_mm:.0f} × {p.height_mm:.0f} mm "
                f"(spread within ±{p.divergence_deg}°) and stand the panel with its relief towards the wall, the "
                f"back face {build.design.room.wall_distance_mm:.0f} mm from it.</p>")


def relief_map(s: panel.PanelShape, heights: np.ndarray, out_path, width_px: int = 480) -> None:
    """The relief seen from the beam's side (x across, z up), coloured by its offset
    from the middle plane (the lamp's diverging ramp), with its range written under it."""
    from PIL import Image, ImageDraw

    from ..artifacts import atomic_path
    from ..pictures import diverging

    rows = max(2, int(round(width_px * s.height_mm / s.width_mm)))
    fine = panel.sample(s, np.asarray(heights, np.float64), width_px, rows)
    span = max(float(np.abs(fine).max()), 1e-6)
    canvas = Image.new("RGB", (width_px, rows + 22), (13, 15, 18))
    canvas.paste(Image.fromarray(diverging(fine / span).transpose(1, 0, 2)[::-1]), (0, 0))
    ImageDraw.Draw(canvas).text((4, rows + 4), f"relief {fine.min():+.2f} to {fine.max():+.2f} mm "
                                f"(orange: towards the wall)", fill=(200, 200, 200))
    with atomic_path(out_path, suffix=".png") as tmp:
        canvas.save(tmp, format="PNG")
