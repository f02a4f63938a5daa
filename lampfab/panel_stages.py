"""What the stages do differently for a panel (``[lens] kind = "panel"``).

``pipeline`` picks these by name (its ``_per_kind``); everything else (prepare, the
stage reports, the STL and its read-back, verify's comparison, report.html) is shared
with the lamp.  The panel's geometry is in ``panel``, its design in
``panel_transport``, its checks in ``panel_checks``, its STEP in ``panel_step``.
"""

from __future__ import annotations

import numpy as np

from . import artifacts, panel
from .errors import GeometryError, LampfabError


def shape(build) -> panel.PanelShape:
    p = build.design.panel
    return panel.PanelShape(p.width_mm, p.height_mm, p.thickness_mm)


def _grid(build) -> tuple[int, int]:
    return build.design.optimize.grid_u, build.design.optimize.grid_v


# -- plan ----------------------------------------------------------------------------
def _plain_optics(build):
    """The flat panel (no relief) and its parallel beam."""
    from . import trace

    verts, faces = panel.closed_mesh(shape(build), np.zeros(_grid(build)), build.design.optimize.tessellation)
    return trace.MeshScene(verts, faces), panel.collimated_emitter(shape(build))


# -- init, optimize ----------------------------------------------------------------------
def init(build) -> dict:
    """The relief by collimated transport (``panel_transport``)."""
    from . import panel_transport
    from .pipeline import _log

    opt = build.design.optimize
    report = build.begin("init", build.target_paths())
    heights, figs = panel_transport.design(
        shape(build), build.walls[0], build.targets(min(64, opt.grid_u))[0], build.fab.ior, _grid(build),
        opt.transport_rounds, opt.transport_corrections, opt.smoothness, build.design.panel.max_relief_mm,
        build.fab.max_slope_deg, log=_log)
    report.figure(method="transport (collimated panel)", **figs)
    artifacts.write_npz(build.path("init.npz"), heights=heights)
    report.write(build.path("init.json"))
    return report.data


def optimize(build) -> dict:
    """No refinement: the transport design is the panel (the profile allows no steps)."""
    report = build.begin("optimize", {"init": build.path("init.npz")})
    heights = artifacts.read_npz(build.path("init.npz"))["heights"]
    if heights.shape != _grid(build):
        raise LampfabError(f"{build.path('init.npz')}: grid {heights.shape} is not the profile's {_grid(build)}; "
                           f"re-run init")
    artifacts.write_npz(build.path("heightmap.npz"), heights=heights)
    report.figure(steps=0, final_loss=None, note="a panel is designed by transport alone",
                  offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()))
    report.write(build.path("optimize.json"))
    return report.data


# -- solid, check, export ------------------------------------------------------------------
def solid(build) -> dict:
    """The panel's closed mesh (relief, sides, back face), checked closed and one body."""
    from . import solid as solid_mod
    from .pipeline import load_heights

    report = build.begin("solid", {"heightmap": build.path("heightmap.npz")})
    verts, faces = panel.closed_mesh(shape(build), load_heights(build), build.design.optimize.tessellation)
    edges = solid_mod.edge_check(faces)
    volume = solid_mod.mesh_volume(verts, faces)
    if not (edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1 and volume > 0):
        raise GeometryError(f"panel mesh is not one closed, outward-wound body: {edges}, volume {volume:.3f} mm^3")
    artifacts.write_npz(build.path("solid.npz"), vertices=verts, faces=faces)
    report.figure(volume_mm3=volume, triangles=int(len(faces)), genus=0)
    report.write(build.path("solid.json"))
    return report.data


def _run_checks(build, vertices: np.ndarray, faces: np.ndarray) -> list:
    from . import panel_checks
    from .pipeline import load_heights

    fields = panel_checks.relief_fields(shape(build), load_heights(build))
    results = panel_checks.run_checks(shape(build), load_heights(build), vertices, faces, build.fab, fields)
    panel_checks.paint(build.path("checks.png"), fields, build.fab)
    return results


def _write_step(build, stl_volume_mm3: float) -> dict:
    from . import panel_step
    from .pipeline import load_heights

    return panel_step.write_step(build.path("lens.step"), shape(build), load_heights(build), stl_volume_mm3)


def _light_json(build) -> dict:
    return panel.light_json(shape(build), build.design.panel.divergence_deg)


# -- verify and the report ------------------------------------------------------------------
def _finishing(build) -> dict:
    """The lamp's tolerance study and finishing advice are not made for a panel."""
    return {}


def _report_light(build, design: dict) -> tuple[np.ndarray, float]:
    """The collimated lamp stands for the beam: a bright disk behind the panel."""
    s = shape(build)
    return np.array([0.0, -3 * s.thickness_mm - s.width_mm, s.height_mm / 2]), s.width_mm / 4


def _heightmap_picture(build, wall_names: list[str], path) -> None:
    """The relief as a colour map."""
    from .pipeline import load_heights

    relief_map(shape(build), load_heights(build), path)


def relief_map(s: panel.PanelShape, heights: np.ndarray, out_path, width_px: int = 480) -> None:
    """The relief seen from the beam's side (x across, z up), coloured by its offset
    from the middle plane (the lamp's diverging ramp), with its range written under it."""
    from PIL import Image, ImageDraw

    from .artifacts import atomic_path
    from .pictures import _diverging

    rows = max(2, int(round(width_px * s.height_mm / s.width_mm)))
    fine = panel.sample(s, np.asarray(heights, np.float64), width_px, rows)
    span = max(float(np.abs(fine).max()), 1e-6)
    canvas = Image.new("RGB", (width_px, rows + 22), (13, 15, 18))
    canvas.paste(Image.fromarray(_diverging(fine / span).transpose(1, 0, 2)[::-1]), (0, 0))
    ImageDraw.Draw(canvas).text((4, rows + 4), f"relief {fine.min():+.2f} to {fine.max():+.2f} mm "
                                f"(orange: towards the wall)", fill=(200, 200, 200))
    with atomic_path(out_path, suffix=".png") as tmp:
        canvas.save(tmp, format="PNG")


def _lens_sections(build, pics: dict, fig) -> tuple[list, list]:
    first = [("Your panel", '<div class="row">' + fig(
        "The panel in its room", pics["room"], "the exported panel path-traced as glass, a bright disk behind "
        "it standing for the collimated lamp; the wall shows the projection verify traced from the same file "
        "(the beam's real spread)") + fig(
        "The panel", pics["lens"], "lens.stl as a matte object: the relief makes the picture") + "</div>")]
    return first, [("The relief", fig("Offset from the middle plane", pics["heightmap"],
                                      "seen from the beam's side, x across and z up"))]


def _next_steps(build) -> str:
    p, fab = build.design.panel, build.fab
    return (f"<p>Send <code>lens.stl</code> to the printer's slicer (binary STL, millimetres, Z up, standing on "
            f"its lower edge) or <code>lens.step</code> to the CNC shop (one solid; the relief is a single "
            f"B-spline face, the other five faces are planes). Material: {fab.material} (n = {fab.ior}). Light "
            f"the flat back face with a collimated beam at least {p.width_mm:.0f} × {p.height_mm:.0f} mm "
            f"(spread within ±{p.divergence_deg}°) and stand the panel with its relief towards the wall, the "
            f"back face {build.design.room.wall_distance_mm:.0f} mm from it.</p>")
