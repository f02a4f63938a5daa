"""Checks of the part as a whole, the same for every kind of lens: whether it fits the
machine (``build_volume``) and whether its mesh is one valid closed body (``mesh_valid``).

Both read the solid's mesh: vertices (n, 3) mm in the STL's frame, the topology as
``mesh.inspect_mesh`` reports it.
"""

from __future__ import annotations

import numpy as np

from .. import tolerances
from ..profile import Fabrication
from .mesh import MeshReport
from .places import cylinder_place
from .result import CheckResult


def build_volume(sv: np.ndarray, fab: Fabrication) -> CheckResult:
    """The part's bounding box against the machine's build volume: (n, 3) mm vertices."""
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
    worst = cylinder_place(sv[int(np.argmax(far))])
    note = (f"bounding box {ext[0]:.1f} x {ext[1]:.1f} x {ext[2]:.1f} mm; build volume "
            f"{build[0]:.0f} x {build[1]:.0f} x {build[2]:.0f} mm (x/y may swap); value = largest "
            f"extent / build size, worst along {'xyz'[axis]}.")
    return CheckResult("build_volume", value, 1.0, "ratio", value <= 1.0, worst=worst, note=note)


def mesh_valid(m: MeshReport, self_intersections: bool) -> CheckResult:
    """Defects of the solid's mesh (open or non-manifold edges and vertices, crossing or
    misoriented faces, extra bodies), ``self_intersections`` whether they were looked for."""
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
            worst = cylinder_place(m.places[key])
            break
    if worst is None and parts["extra_bodies"] and len(m.shell_volume) > 1:
        pos = np.flatnonzero(m.shell_volume > 0)
        if len(pos) > 1:
            worst = cylinder_place(m.shell_point[pos[np.argsort(m.shell_volume[pos])[0]]])
    details = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in parts.items())
    note = (f"{m.faces} faces, {m.vertices} vertices; {details} (pymeshlab topological measures"
            f"{' and self-intersection selection' if self_intersections else '; self-intersections NOT tested'}). "
            f"Bodies = closed shells wound outward: {bodies}.")
    if m.welded:
        note += (f" Welded at {tolerances.WELD_MM * 1e3:g} um first (a triangle soup): {m.welded} vertices "
                 f"merged, {m.degenerate} faces collapsed.")
    return CheckResult("mesh_valid", value, 0, "defects", value == 0, worst=worst, note=note)
