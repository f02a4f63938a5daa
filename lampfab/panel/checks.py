"""Fabrication checks of a panel, as ``checks.run_checks``'s ``CheckResult`` in its order.

The relief is measured on a fine grid of its spline (exact derivatives); topology and
size on the solid's mesh, as for the lamp.  The cavity and bore checks have nothing to
measure on a panel: they are listed with ``applies`` false and the reason.

Places (``worst``) are ``checks.places.panel_place`` on the relief, in the STL frame.
"""

from __future__ import annotations

import numpy as np

from ..checks.mesh import inspect_mesh
from ..checks.part import build_volume, mesh_valid
from ..checks.places import panel_place
from ..checks.result import CheckResult, not_applicable
from ..limits import OVERHANG_DEG
from ..profile import Fabrication
from . import geometry as panel

NOT_A_PANEL = "not applicable to a panel"


def relief_fields(shape: panel.PanelShape, heights: np.ndarray, samples: tuple[int, int] = (512, 512)) -> dict:
    """Per-sample fields of the relief on a (mx, mz) grid (at least 2x the nodes):
    xyz (mx, mz, 3) mm, thickness (mm, back face to relief), tilt (deg from +y),
    concave_radius (mm, inf where convex), lean (deg a down-facing sample leans past
    vertical, the panel standing as the STL does)."""
    nx, nz = heights.shape
    mx, mz = max(samples[0], 2 * nx), max(samples[1], 2 * nz)
    s = panel.sample(shape, heights, mx, mz)
    gx, gz = (panel.sample(shape, heights, mx, mz, dx=a, dz=1 - a) for a in (1, 0))
    hxx, hxz, hzz = (panel.sample(shape, heights, mx, mz, dx=a, dz=2 - a) for a in (2, 1, 0))
    norm = np.sqrt(1 + gx**2 + gz**2)
    # Shape operator of the graph y = T + s(x, z) (normal towards +y): I^-1 II.  Its
    # larger eigenvalue > 0 is a hollow seen from outside, which a ball-end must fit.
    e, f, g = 1 + gx**2, gx * gz, 1 + gz**2
    det_i = e * g - f**2
    s11 = (g * hxx - f * hxz) / det_i / norm
    s12 = (g * hxz - f * hzz) / det_i / norm
    s21 = (e * hxz - f * hxx) / det_i / norm
    s22 = (e * hzz - f * hxz) / det_i / norm
    half_trace = 0.5 * (s11 + s22)
    k_max = half_trace + np.sqrt(np.maximum(half_trace**2 - (s11 * s22 - s12 * s21), 0.0))
    with np.errstate(divide="ignore"):
        concave = np.where(k_max > 1e-12, 1.0 / k_max, np.inf)
    return {"xyz": panel.points(shape, s), "thickness": shape.thickness_mm + s,
            "tilt": np.degrees(np.arctan(np.hypot(gx, gz))), "concave_radius": concave,
            "lean": np.degrees(np.arcsin(np.clip(gz / norm, 0.0, 1.0)))}


def run_checks(shape: panel.PanelShape, heights: np.ndarray, solid_vertices: np.ndarray, solid_faces: np.ndarray,
               fab: Fabrication, fields: dict | None = None) -> list[CheckResult]:
    """Every check of ``checks.NAMES`` for the panel (heights (nx, nz) mm; the solid's
    mesh (n, 3) mm, (m, 3) int); the cavity and bore checks do not apply."""
    f = fields or relief_fields(shape, heights)

    def at(field, pick):
        k = np.unravel_index(int(pick(f[field])), f[field].shape)
        return float(f[field][k]), panel_place(f["xyz"][k])

    thin, thin_at = at("thickness", np.argmin)
    out = [CheckResult("min_wall", thin, fab.min_wall_mm, "mm", thin >= fab.min_wall_mm, worst=thin_at,
                       note="thinnest panel: from the flat back face to the relief")]
    tilt, tilt_at = at("tilt", np.argmax)
    out.append(CheckResult("max_slope", tilt, fab.max_slope_deg, "deg", tilt <= fab.max_slope_deg, worst=tilt_at,
                           note="tilt of the relief's normal from the panel's normal"))
    if fab.tool_radius_mm <= 0:
        out.append(not_applicable("tool_radius", "mm", f"process {fab.process!r} has no cutting tool "
                                                       f"(tool_radius_mm = 0)"))
    else:
        radius, radius_at = at("concave_radius", np.argmin)
        out.append(CheckResult("tool_radius", radius if np.isfinite(radius) else None, fab.tool_radius_mm, "mm",
                               radius >= fab.tool_radius_mm, worst=radius_at if np.isfinite(radius) else None,
                               note="smallest concave radius of the relief (milled from above, through its face)"))
    if fab.process != "sla":
        out.append(not_applicable("overhang", "deg", f"process {fab.process!r} is not built in layers"))
    else:
        lean, lean_at = at("lean", np.argmax)
        out.append(CheckResult("overhang", lean, OVERHANG_DEG, "deg", lean <= OVERHANG_DEG,
                               worst=lean_at, note="printed standing on its lower edge, as the STL stands: how far "
                                                   "the relief's down-facing parts lean past vertical"))
    out.append(not_applicable("cavity_overhang", "deg", NOT_A_PANEL))
    sv = np.asarray(solid_vertices, np.float64)
    out.append(build_volume(sv, fab))
    out.append(mesh_valid(inspect_mesh(sv, np.asarray(solid_faces, np.int64), True), True))
    out.append(not_applicable("drain", "voids", NOT_A_PANEL))
    out.append(not_applicable("cavity_access", "mm", NOT_A_PANEL))
    return out


def paint(path_png, fields: dict, fab: Fabrication) -> None:
    """``checks.png`` for a panel: the relief seen from the beam's side, grey by thickness,
    red where a check fails (too thin, too steep, too tight for the tool, overhang)."""
    from PIL import Image

    from ..artifacts import atomic_path

    t = fields["thickness"]
    grey = 60 + 160 * (t - t.min()) / max(float(np.ptp(t)), 1e-9)
    bad = (t < fab.min_wall_mm) | (fields["tilt"] > fab.max_slope_deg)
    if fab.tool_radius_mm > 0:
        bad |= fields["concave_radius"] < fab.tool_radius_mm
    if fab.process == "sla":
        bad |= fields["lean"] > OVERHANG_DEG
    rgb = np.stack([np.where(bad, 230, grey), np.where(bad, 40, grey), np.where(bad, 40, grey)], -1)
    picture = rgb.transpose(1, 0, 2)[::-1].astype(np.uint8)  # x across, z up
    with atomic_path(path_png, suffix=".png") as tmp:
        Image.fromarray(picture).save(tmp, format="PNG")
