"""Fabrication checks: can this lens be printed or milled as designed?

``run_checks`` measures the lens against a fabrication profile (``profile.Fabrication``)
and returns one dict per check:

    {"name": str, "value": float | None, "limit": float | None, "unit": str,
     "passed": bool, "applies": bool,
     "worst": {"u_deg": float, "z_mm": float, "xyz_mm": [x, y, z]} | None,
     "note": str}

``value`` is the measured figure in ``unit`` (None where there is nothing to measure, e.g.
a check that does not apply, or no concave region at all); ``passed`` is True for a check
that does not apply.  ``worst`` is the place that decided the value: ``xyz_mm`` in the
lamp frame (mm, Z up, base on z = 0) and its cylinder coordinates (u in [0, 360) deg,
z in mm).  ``paint_checks`` draws the unrolled outer surface (u across, z up) coloured by
wall thickness, one panel per check with its failing cells red (``checks.png``).

The checks (what and why):
  min_wall         thinnest material between the outer surface and the cavity or bore,
                   and the thickness of the two caps (fab.min_wall_mm)
  max_slope        steepest tilt of the outer surface against the radial direction
                   (fab.max_slope_deg)
  tool_radius      smallest concave radius of curvature vs the ball-end radius (CNC only)
  tool_axis        3-axis milling: steepest surface against the tool axis of its best
                   indexed setup (fab.setups, fab.max_tool_angle_deg; checks_cnc)
  overhang         outer surface leaning past OVERHANG_DEG from vertical, printed upright
                   (SLA only)
  cavity_overhang  cavity ceiling leaning past OVERHANG_DEG from vertical (SLA only)
  build_volume     bounding box vs the machine (fab.build_*_mm)
  mesh_valid       watertight, manifold, consistently wound, no self-intersections, one body
  drain            no sealed void; the cavity opens to the outside (and the LED is not in
                   material)
  cavity_access    no cavity surface hidden from a tool entering through the bore (not
                   SLA; checks_cnc)

Geometry (heightmap + inner layer) is measured on a fine (u, z) grid of the outer
surface (``checks_geometry``); topology on the solid's mesh (``checks_mesh``).
"""

from __future__ import annotations

import math

import numpy as np

from . import tolerances
from .checks_cnc import cavity_access, tool_axis, tool_axis_cells
from .checks_geometry import Fields, compute_fields
from .curvature import SAMPLES
from .checks_mesh import MeshReport, face_area_nz, inspect_mesh
from .limits import OVERHANG_DEG, overhang_limit_deg
from .profile import Fabrication
from .surface import Cylinder

# Formlabs' recommended minimum drain hole diameter (SLA design guides quoting it); the
# bore is the cavity's only opening, so resin drains through it.
DRAIN_HOLE_MM = 3.5

# Machining design guides ask for inside corner radii >= the tool radius and suggest 1.3
# x; below that but above 1 x the tool still reaches, with a note.
TOOL_MARGIN = 1.3

NAMES = ("min_wall", "max_slope", "tool_radius", "tool_axis", "overhang", "cavity_overhang",
         "build_volume", "mesh_valid", "drain", "cavity_access")


def run_checks(cyl: Cylinder, heights: np.ndarray, inner_vertices: np.ndarray, inner_faces: np.ndarray,
               solid_vertices: np.ndarray, solid_faces: np.ndarray, fab: Fabrication,
               light_mm: np.ndarray, fields: Fields | None = None, mesh: MeshReport | None = None,
               samples: tuple[int, int] = SAMPLES, self_intersections: bool = True) -> list[dict]:
    """Run every check; a list of JSON-able dicts in ``NAMES`` order (see module docstring).

    heights (nu, nv) mm radial offsets; inner_vertices (n, 3) mm and inner_faces (m, 3)
    int, wound outward (``inner.load_inner``); solid_vertices (p, 3) mm and solid_faces
    (q, 3) int, the final solid; light_mm (3,) the LED centre.  ``fields`` / ``mesh``
    reuse earlier measurements (``compute_fields`` / ``inspect_mesh``); ``samples`` is
    the (u, z) grid of the outer surface (raised to 2x the nodes).
    """
    if fields is None:
        fields = cached_fields(cyl, heights, inner_vertices, inner_faces, fab.mount_radius_mm, samples)
    if mesh is None:
        # Main thread only: pymeshlab run in a worker thread corrupted the heap (glibc
        # "malloc_consolidate(): unaligned fastbin chunk", abort at exit, 6 of 6 runs).
        mesh = inspect_mesh(solid_vertices, solid_faces, self_intersections)
    iv = np.asarray(inner_vertices, np.float64)
    fi = np.asarray(inner_faces, np.int64)
    sv = np.asarray(solid_vertices, np.float64)
    sf = np.asarray(solid_faces, np.int64)
    light = np.asarray(light_mm, np.float64)
    return [
        _min_wall(fields, fab),
        _max_slope(fields, fab),
        _tool_radius(fields, fab),
        tool_axis(fields, fab),
        _overhang(fields, fab),
        _cavity_overhang(iv, fi, fab),
        _build_volume(sv, fab),
        _mesh_valid(mesh, self_intersections),
        _drain(mesh, sv, sf, light, fab),
        cavity_access(iv, fi, fab),
    ]


_LAST_FIELDS: dict = {}


def cached_fields(cyl, heights, inner_vertices, inner_faces, mount_radius_mm, samples) -> Fields:
    """``compute_fields``, remembering the last answer by a hash of its inputs' contents,
    so ``paint_checks`` right after ``run_checks`` on the same lens costs nothing."""
    import hashlib

    h = hashlib.blake2b(digest_size=16)
    for arr in (heights, inner_vertices, inner_faces):
        a = np.ascontiguousarray(arr)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.tobytes())
    h.update(repr((cyl, float(mount_radius_mm), tuple(samples))).encode())
    key = h.hexdigest()
    if key not in _LAST_FIELDS:
        _LAST_FIELDS.clear()                            # one lens at a time: bounded memory
        _LAST_FIELDS[key] = compute_fields(cyl, heights, inner_vertices, inner_faces, mount_radius_mm, samples)
    return _LAST_FIELDS[key]


def failed(results: list[dict]) -> list[dict]:
    """The checks that apply and did not pass."""
    return [r for r in results if r["applies"] and not r["passed"]]


# ---------------------------------------------------------------- the checks

def _result(name, value, limit, unit, passed, applies=True, worst=None, note=""):
    return {"name": name, "value": None if value is None else float(value),
            "limit": None if limit is None else float(limit), "unit": unit,
            "passed": bool(passed), "applies": bool(applies), "worst": worst, "note": note}


def _place(xyz) -> dict:
    """{"u_deg", "z_mm", "xyz_mm"} of a point in the lamp frame (mm)."""
    x, y, z = (float(c) for c in xyz)
    u = math.degrees(math.atan2(y, x)) % 360.0
    return {"u_deg": round(u, 3), "z_mm": round(z, 4), "xyz_mm": [round(x, 4), round(y, 4), round(z, 4)]}


def _cell_place(f: Fields, i: int, j: int) -> dict:
    return _place(f.xyz[i, j])


def _argmin2(a: np.ndarray) -> tuple[int, int]:
    i, j = np.unravel_index(int(np.argmin(a)), a.shape)
    return int(i), int(j)


def wall_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells thinner than the minimum wall."""
    return f.wall < fab.min_wall_mm


def _min_wall(f: Fields, fab: Fabrication) -> dict:
    i, j = _argmin2(f.wall)
    side = float(f.wall[i, j])
    cands = [(side, _cell_place(f, i, j), "side"), (f.wall_top, _place(f.wall_top_xyz), "top cap"),
             (f.wall_base, _place(f.wall_base_xyz), "base")]
    value, worst, where = min(cands, key=lambda c: c[0])
    thin = wall_cells(f, fab)
    note = (f"thinnest: {where}. Side wall min {side:.3f} mm at u {np.degrees(f.u[i]):.1f} deg, "
            f"z {f.z[j]:.2f} mm ({thin.mean() * 100:.2f} % of the side below {fab.min_wall_mm} mm); "
            f"top cap {f.wall_top:.3f} mm; base {f.wall_base:.3f} mm. Side wall = exact distance "
            f"from the outer surface samples to the inner layer and the bore; negative = the outer "
            f"surface is inside the cavity.")
    return _result("min_wall", value, fab.min_wall_mm, "mm", value >= fab.min_wall_mm, worst=worst, note=note)


def slope_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells tilted past the profile's slope limit."""
    return f.slope > fab.max_slope_deg


def _max_slope(f: Fields, fab: Fabrication) -> dict:
    i, j = np.unravel_index(int(np.argmax(f.slope)), f.slope.shape)
    value = float(f.slope[i, j])
    note = (f"tilt of the outer normal from the radial direction; "
            f"{slope_cells(f, fab).mean() * 100:.2f} % of the surface above {fab.max_slope_deg} deg")
    if fab.process == "cnc4":
        note += ". On the rotary axis the tool axis is radial: this is the slope against the tool axis"
    elif fab.process == "cnc3":
        note += " (the design's limit; the slope against the 3-axis tool is tool_axis)"
    return _result("max_slope", value, fab.max_slope_deg, "deg", value <= fab.max_slope_deg,
                   worst=_cell_place(f, int(i), int(j)), note=note)


def tool_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells hollower than the ball-end tool (none without a tool)."""
    if fab.tool_radius_mm <= 0:
        return np.zeros(f.wall.shape, bool)
    return f.concave_radius < fab.tool_radius_mm


def _tool_radius(f: Fields, fab: Fabrication) -> dict:
    tool = fab.tool_radius_mm
    if tool <= 0:
        return _result("tool_radius", None, None, "mm", True, applies=False,
                       note=f"process {fab.process!r} has no cutting tool (tool_radius_mm = 0)")
    i, j = _argmin2(f.concave_radius)
    value = float(f.concave_radius[i, j])
    if not np.isfinite(value):
        return _result("tool_radius", None, tool, "mm", True,
                       note="the outer surface is convex everywhere: any ball-end reaches it")
    passed = value >= tool
    note = (f"smallest concave radius of curvature (largest principal curvature from the "
            f"fundamental forms); a ball of radius {tool} mm cannot reach the bottom of a "
            f"hollow tighter than itself. {tool_cells(f, fab).mean() * 100:.2f} % of the surface "
            f"is tighter than the tool.")
    if passed and value < TOOL_MARGIN * tool:
        note += f" Passes, but below the {TOOL_MARGIN} x tool radius machining guides suggest."
    return _result("tool_radius", value, tool, "mm", passed, worst=_cell_place(f, i, j), note=note)


def overhang_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells leaning down past the print's overhang limit (none
    when the process has no such limit)."""
    limit = overhang_limit_deg(fab)
    if limit is None:
        return np.zeros(f.wall.shape, bool)
    return f.overhang > limit + tolerances.ANGLE_TOL_DEG


def _overhang(f: Fields, fab: Fabrication) -> dict:
    if overhang_limit_deg(fab) is None:
        return _result("overhang", None, None, "deg", True, applies=False,
                       note=f"process {fab.process!r} is not built in layers")
    i, j = np.unravel_index(int(np.argmax(f.overhang)), f.overhang.shape)
    value = float(f.overhang[i, j])
    cells = overhang_cells(f, fab)
    note = (f"printed upright (base on the platform): how far a down-facing part of the outer "
            f"surface leans past vertical (0 = vertical, 90 = a ceiling). "
            f"{f.area[cells].sum():.1f} mm^2 lean past {OVERHANG_DEG:.0f} deg and would need "
            f"supports on the optical surface (support scars).")
    return _result("overhang", value, OVERHANG_DEG, "deg", value <= OVERHANG_DEG + tolerances.ANGLE_TOL_DEG,
                   worst=_cell_place(f, int(i), int(j)), note=note)


def cavity_overhang_faces(iv: np.ndarray, fi: np.ndarray):
    """Per inner-layer face (m faces): ((m,) deg the solid leans past vertical there, (m,) mm^2).

    The solid's surface in the cavity faces opposite to the inner layer's normals (those
    point into the glass), so a cavity face is down-facing where the inner normal points
    up: asin(n_z) past vertical.
    """
    area, nz = face_area_nz(iv, fi)
    angle = np.degrees(np.arcsin(np.clip(nz, 0.0, 1.0)))
    return angle, area


def _cavity_overhang(iv, fi, fab: Fabrication) -> dict:
    if fab.process != "sla":
        return _result("cavity_overhang", None, None, "deg", True, applies=False,
                       note=f"process {fab.process!r} is not built in layers")
    angle, area = cavity_overhang_faces(iv, fi)
    value = float(angle.max())
    steep = angle >= value - 1.0  # within a degree: the whole of a flat ceiling, not its noisiest facet
    centroids = iv[fi].mean(axis=1)
    # The middle of the steepest region: for a flat ceiling its centre, farthest from the
    # walls that hold it up.
    mid = (centroids[steep] * area[steep, None]).sum(axis=0) / max(area[steep].sum(), 1e-300)
    bad = angle > OVERHANG_DEG + tolerances.ANGLE_TOL_DEG
    note = (f"printed upright, the cavity's down-facing surfaces (its ceiling) are overhangs inside "
            f"the part, where supports could not be removed through the bore: {area[bad].sum():.1f} "
            f"mm^2 lean past {OVERHANG_DEG:.0f} deg from vertical. A self-supporting roof in the inner "
            f"layer (a cone or dome no flatter than {OVERHANG_DEG:.0f} deg from vertical) avoids it.")
    return _result("cavity_overhang", value, OVERHANG_DEG, "deg", value <= OVERHANG_DEG + tolerances.ANGLE_TOL_DEG,
                   worst=_place(mid), note=note)


def _build_volume(sv: np.ndarray, fab: Fabrication) -> dict:
    lo, hi = sv.min(axis=0), sv.max(axis=0)
    ext = hi - lo
    build = np.array([fab.build_x_mm, fab.build_y_mm, fab.build_z_mm])
    # The part may turn 90 deg about z on the platform: take the better x/y orientation.
    straight = ext / build
    turned = ext / build[[1, 0, 2]]
    ratios = straight if straight.max() <= turned.max() else turned
    axis = int(np.argmax(ratios))
    value = float(ratios[axis])
    # Where the part sticks out: across, the vertex farthest from the lamp axis along the
    # worst axis; upward, the highest vertex (the part stands on the platform).
    far = np.abs(sv[:, axis]) if axis < 2 else sv[:, 2]
    worst = _place(sv[int(np.argmax(far))])
    note = (f"bounding box {ext[0]:.1f} x {ext[1]:.1f} x {ext[2]:.1f} mm; build volume "
            f"{build[0]:.0f} x {build[1]:.0f} x {build[2]:.0f} mm (x/y may swap); value = largest "
            f"extent / build size, worst along {'xyz'[axis]}.")
    return _result("build_volume", value, 1.0, "ratio", value <= 1.0, worst=worst, note=note)


def _mesh_valid(m: MeshReport, self_intersections: bool) -> dict:
    bodies = int((m.shell_volume > 0).sum())
    parts = {
        "boundary_edges": m.boundary_edges,
        "non_manifold_edges": m.non_manifold_edges,
        "non_manifold_vertices": m.non_manifold_vertices,
        "self_intersecting_faces": m.self_intersecting_faces,
        "misoriented_edges": m.misoriented_edges,
        "extra_bodies": max(bodies - 1, 0) + (1 if bodies == 0 else 0),
    }
    value = sum(parts.values())
    worst = None
    for key, count in parts.items():
        if count and m.places.get(key) is not None:
            worst = _place(m.places[key])
            break
    if worst is None and parts["extra_bodies"] and len(m.shell_volume) > 1:
        pos = np.flatnonzero(m.shell_volume > 0)
        if len(pos) > 1:
            worst = _place(m.shell_point[pos[np.argsort(m.shell_volume[pos])[0]]])
    details = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in parts.items())
    note = (f"{m.faces} faces, {m.vertices} vertices; {details} (pymeshlab topological measures"
            f"{' and self-intersection selection' if self_intersections else '; self-intersections NOT tested'}). "
            f"Bodies = closed shells wound outward: {bodies}.")
    if m.welded:
        note += (f" Welded at {tolerances.WELD_MM * 1e3:g} um first (a triangle soup): {m.welded} vertices "
                 f"merged, {m.degenerate} faces collapsed.")
    return _result("mesh_valid", value, 0, "defects", value == 0, worst=worst, note=note)


def _drain(m: MeshReport, sv, sf, light, fab: Fabrication) -> dict:
    from .inner import winding_number

    voids = np.flatnonzero(m.shell_volume < 0)
    worst = _place(m.shell_point[voids[np.argmin(m.shell_volume[voids])]]) if len(voids) else None
    # The LED must sit in air (the cavity), not in material: the solid's winding number
    # there is ~0 in the cavity or a void, ~1 inside material.
    wn = winding_number(sv, sf, light) if len(sf) else 0.0
    led_in_material = wn > 0.5
    passed = len(voids) == 0 and not led_in_material
    note = (f"{len(voids)} sealed void(s) (closed shells wound into the solid: "
            f"{', '.join(f'{-v:.0f} mm^3' for v in m.shell_volume[voids]) or 'none'}); "
            f"the cavity drains through the bore (radius {fab.mount_radius_mm} mm).")
    if led_in_material:
        note += f" The LED at {np.round(light, 2).tolist()} mm is inside material."
        worst = worst or _place(light)
    if m.boundary_edges:
        note += " The mesh is open (see mesh_valid): shells and voids are uncertain."
    if fab.process == "sla":
        if 2 * fab.mount_radius_mm < DRAIN_HOLE_MM:
            note += (f" The bore ({2 * fab.mount_radius_mm} mm across) is below the {DRAIN_HOLE_MM} mm "
                     f"drain hole SLA guides ask for.")
        note += (" Printed upright with the base flat on the platform the bore is closed by it: the cavity "
                 "becomes a sealed cup while printing (suction on every peel, trapped resin); print it on "
                 "supports or raft with a gap under the bore.")
    elif fab.process in ("cnc3", "cnc4"):
        note += " A sealed void cannot be milled at all."
    return _result("drain", len(voids), 0, "voids", passed, worst=worst, note=note)


# ---------------------------------------------------------------- painting

def paint_checks(path_png, cyl: Cylinder, heights: np.ndarray, inner_vertices: np.ndarray,
                 inner_faces: np.ndarray, fab: Fabrication, results: list[dict],
                 fields: Fields | None = None, samples: tuple[int, int] = SAMPLES) -> None:
    """Write ``checks.png``: one panel per check, the unrolled outer surface (u across from
    0 to 360 deg, z up) coloured by wall thickness, failing cells red, the worst place
    ringed.  Arguments as ``run_checks``; ``results`` its output."""
    from .checks_paint import access_cells, cavity_cells, paint

    if fields is None:
        fields = cached_fields(cyl, heights, inner_vertices, inner_faces, fab.mount_radius_mm, samples)
    iv = np.asarray(inner_vertices, np.float64)
    fi = np.asarray(inner_faces, np.int64)
    cells = {
        "min_wall": wall_cells(fields, fab),
        "max_slope": slope_cells(fields, fab),
        "tool_radius": tool_cells(fields, fab),
        "overhang": overhang_cells(fields, fab),
        "tool_axis": tool_axis_cells(fields, fab),
        "cavity_overhang": cavity_cells(iv, fi, fields, fab),
        "cavity_access": access_cells(iv, fi, fields, fab),
    }
    # The caps are not on the unrolled side: a thin cap paints its edge row.
    if fields.wall_top < fab.min_wall_mm:
        cells["min_wall"][:, -1] = True
    if fields.wall_base < fab.min_wall_mm:
        cells["min_wall"][:, 0] = True
    paint(path_png, fields, results, cells, fab)
