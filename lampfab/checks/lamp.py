"""The lamp's fabrication checks: can this lens be printed or milled as designed?

``run_checks`` measures the lens against a fabrication profile (``profile.Fabrication``)
and returns one ``CheckResult`` per check, in ``result.NAMES`` order.  ``worst`` places
are ``places.cylinder_place``: the point in the lamp frame (mm, Z up, base on z = 0) and
its cylinder coordinates (u in [0, 360) deg, z in mm).  ``paint_checks`` draws the
unrolled outer surface (u across, z up) coloured by wall thickness, one panel per check
with its failing cells red (``checks.png``).

The checks (what and why):
  min_wall         thinnest material between the outer surface and the cavity or bore,
                   and the thickness of the two caps (fab.min_wall_mm)
  max_slope        steepest tilt of the outer surface against the radial direction
                   (fab.max_slope_deg)
  tool_radius      smallest concave radius of curvature vs the ball-end radius (CNC only)
  tool_axis        3-axis milling: steepest surface against the tool axis of its best
                   indexed setup (fab.setups, fab.max_tool_angle_deg; ``cnc``)
  overhang         outer surface leaning past OVERHANG_DEG from vertical, printed upright
                   (SLA only)
  cavity_overhang  cavity ceiling leaning past OVERHANG_DEG from vertical (SLA only)
  build_volume     bounding box vs the machine (fab.build_*_mm; ``part``)
  mesh_valid       watertight, manifold, consistently wound, no self-intersections, one body
                   (``part``)
  drain            no sealed void; the cavity opens to the outside (and the LED is not in
                   material)
  cavity_access    no cavity surface hidden from a tool entering through the bore (not
                   SLA; ``cnc``)

Geometry (heightmap + inner layer) is measured on a fine (u, z) grid of the outer
surface (``fields``); topology on the solid's mesh (``mesh``).
"""

from __future__ import annotations

import numpy as np

from .. import tolerances
from ..curvature import SAMPLES
from ..limits import OVERHANG_DEG, overhang_limit_deg
from ..profile import Fabrication
from ..surface import Cylinder
from .cnc import access_cells, cavity_access, tool_axis, tool_axis_cells
from .fields import Fields, compute_fields, faces_on_grid
from .mesh import MeshReport, face_area_nz, inspect_mesh
from .part import build_volume, mesh_valid
from .places import cylinder_place
from .result import CheckResult, not_applicable

# Formlabs' recommended minimum drain hole diameter (SLA design guides quoting it); the
# bore is the cavity's only opening, so resin drains through it.
DRAIN_HOLE_MM = 3.5

# Machining design guides ask for inside corner radii >= the tool radius and suggest 1.3
# x; below that but above 1 x the tool still reaches, with a note.
TOOL_MARGIN = 1.3


def run_checks(cyl: Cylinder, heights: np.ndarray, inner_vertices: np.ndarray, inner_faces: np.ndarray,
               solid_vertices: np.ndarray, solid_faces: np.ndarray, fab: Fabrication,
               light_mm: np.ndarray, fields: Fields | None = None, mesh: MeshReport | None = None,
               samples: tuple[int, int] = SAMPLES, self_intersections: bool = True) -> list[CheckResult]:
    """Run every check, in ``result.NAMES`` order (see the module docstring).

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
        build_volume(sv, fab),
        mesh_valid(mesh, self_intersections),
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


# ---------------------------------------------------------------- the checks

def _argmin2(a: np.ndarray) -> tuple[int, int]:
    i, j = np.unravel_index(int(np.argmin(a)), a.shape)
    return int(i), int(j)


def wall_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells thinner than the minimum wall."""
    return f.wall < fab.min_wall_mm


def _min_wall(f: Fields, fab: Fabrication) -> CheckResult:
    i, j = _argmin2(f.wall)
    side = float(f.wall[i, j])
    cands = [(side, cylinder_place(f.xyz[i, j]), "side"), (f.wall_top, cylinder_place(f.wall_top_xyz), "top cap"),
             (f.wall_base, cylinder_place(f.wall_base_xyz), "base")]
    value, worst, where = min(cands, key=lambda c: c[0])
    thin = wall_cells(f, fab)
    note = (f"thinnest: {where}. Side wall min {side:.3f} mm at u {np.degrees(f.u[i]):.1f} deg, "
            f"z {f.z[j]:.2f} mm ({thin.mean() * 100:.2f} % of the side below {fab.min_wall_mm} mm); "
            f"top cap {f.wall_top:.3f} mm; base {f.wall_base:.3f} mm. Side wall = exact distance "
            f"from the outer surface samples to the inner layer and the bore; negative = the outer "
            f"surface is inside the cavity.")
    return CheckResult("min_wall", value, fab.min_wall_mm, "mm", value >= fab.min_wall_mm, worst=worst, note=note)


def slope_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells tilted past the profile's slope limit."""
    return f.slope > fab.max_slope_deg


def _max_slope(f: Fields, fab: Fabrication) -> CheckResult:
    i, j = np.unravel_index(int(np.argmax(f.slope)), f.slope.shape)
    value = float(f.slope[i, j])
    note = (f"tilt of the outer normal from the radial direction; "
            f"{slope_cells(f, fab).mean() * 100:.2f} % of the surface above {fab.max_slope_deg} deg")
    if fab.process == "cnc4":
        note += ". On the rotary axis the tool axis is radial: this is the slope against the tool axis"
    elif fab.process == "cnc3":
        note += " (the design's limit; the slope against the 3-axis tool is tool_axis)"
    return CheckResult("max_slope", value, fab.max_slope_deg, "deg", value <= fab.max_slope_deg,
                       worst=cylinder_place(f.xyz[int(i), int(j)]), note=note)


def tool_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells hollower than the ball-end tool (none without a tool)."""
    if fab.tool_radius_mm <= 0:
        return np.zeros(f.wall.shape, bool)
    return f.concave_radius < fab.tool_radius_mm


def _tool_radius(f: Fields, fab: Fabrication) -> CheckResult:
    tool = fab.tool_radius_mm
    if tool <= 0:
        return not_applicable("tool_radius", "mm", f"process {fab.process!r} has no cutting tool (tool_radius_mm = 0)")
    i, j = _argmin2(f.concave_radius)
    value = float(f.concave_radius[i, j])
    if not np.isfinite(value):
        return CheckResult("tool_radius", None, tool, "mm", True,
                           note="the outer surface is convex everywhere: any ball-end reaches it")
    passed = value >= tool
    note = (f"smallest concave radius of curvature (largest principal curvature from the "
            f"fundamental forms); a ball of radius {tool} mm cannot reach the bottom of a "
            f"hollow tighter than itself. {tool_cells(f, fab).mean() * 100:.2f} % of the surface "
            f"is tighter than the tool.")
    if passed and value < TOOL_MARGIN * tool:
        note += f" Passes, but below the {TOOL_MARGIN} x tool radius machining guides suggest."
    return CheckResult("tool_radius", value, tool, "mm", passed, worst=cylinder_place(f.xyz[i, j]), note=note)


def overhang_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells leaning down past the print's overhang limit (none
    when the process has no such limit)."""
    limit = overhang_limit_deg(fab)
    if limit is None:
        return np.zeros(f.wall.shape, bool)
    return f.overhang > limit + tolerances.ANGLE_TOL_DEG


def _overhang(f: Fields, fab: Fabrication) -> CheckResult:
    if overhang_limit_deg(fab) is None:
        return not_applicable("overhang", "deg", f"process {fab.process!r} is not built in layers")
    i, j = np.unravel_index(int(np.argmax(f.overhang)), f.overhang.shape)
    value = float(f.overhang[i, j])
    cells = overhang_cells(f, fab)
    note = (f"printed upright (base on the platform): how far a down-facing part of the outer "
            f"surface leans past vertical (0 = vertical, 90 = a ceiling). "
            f"{f.area[cells].sum():.1f} mm^2 lean past {OVERHANG_DEG:.0f} deg and would need "
            f"supports on the optical surface (support scars).")
    return CheckResult("overhang", value, OVERHANG_DEG, "deg", value <= OVERHANG_DEG + tolerances.ANGLE_TOL_DEG,
                       worst=cylinder_place(f.xyz[int(i), int(j)]), note=note)


def cavity_overhang_faces(iv: np.ndarray, fi: np.ndarray):
    """Per inner-layer face (m faces): ((m,) deg the solid leans past vertical there, (m,) mm^2).

    The solid's surface in the cavity faces opposite to the inner layer's normals (those
    point into the glass), so a cavity face is down-facing where the inner normal points
    up: asin(n_z) past vertical.
    """
    area, nz = face_area_nz(iv, fi)
    angle = np.degrees(np.arcsin(np.clip(nz, 0.0, 1.0)))
    return angle, area


def cavity_cells(iv: np.ndarray, fi: np.ndarray, f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: cavity overhang faces marked on the (u, z) grid of the outer surface
    (the cavity is not on that surface; this marks the heights and directions where it
    overhangs)."""
    if fab.process != "sla":
        return np.zeros(f.wall.shape, bool)
    angle, _ = cavity_overhang_faces(iv, fi)
    return faces_on_grid(iv, fi[angle > OVERHANG_DEG + tolerances.ANGLE_TOL_DEG], f)


def _cavity_overhang(iv, fi, fab: Fabrication) -> CheckResult:
    if fab.process != "sla":
        return not_applicable("cavity_overhang", "deg", f"process {fab.process!r} is not built in layers")
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
    return CheckResult("cavity_overhang", value, OVERHANG_DEG, "deg",
                       value <= OVERHANG_DEG + tolerances.ANGLE_TOL_DEG, worst=cylinder_place(mid), note=note)


def _drain(m: MeshReport, sv, sf, light, fab: Fabrication) -> CheckResult:
    from ..inner import winding_number

    voids = np.flatnonzero(m.shell_volume < 0)
    worst = cylinder_place(m.shell_point[voids[np.argmin(m.shell_volume[voids])]]) if len(voids) else None
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
        worst = worst or cylinder_place(light)
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
    return CheckResult("drain", len(voids), 0, "voids", passed, worst=worst, note=note)


# ---------------------------------------------------------------- painting

def paint_checks(path_png, cyl: Cylinder, heights: np.ndarray, inner_vertices: np.ndarray,
                 inner_faces: np.ndarray, fab: Fabrication, results: list[CheckResult],
                 fields: Fields | None = None, samples: tuple[int, int] = SAMPLES) -> None:
    """Write ``checks.png``: one panel per check, the unrolled outer surface (u across from
    0 to 360 deg, z up) coloured by wall thickness, failing cells red, the worst place
    ringed.  Arguments as ``run_checks``; ``results`` its output."""
    from .paint import paint

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
