"""The lens as the optics see it: outer surface and caps, with the inner layer as a void.

The LED bore through the base (solid stage) is left out here, so the mesh is cheap to
rebuild at every step of the ptracer method.  Without the bore, glass stays under the
cavity's floor and reflects a little light back up, a faint spot near a wall's centre
that the made lens does not have.  Figures that must describe the made lens trace the
solid instead: verify traces the exported STL, the plan and the tolerance study
``pipeline.kind.Lamp.solid_maker``.
"""

from __future__ import annotations

import numpy as np

from . import surface


def optical_mesh(cyl: surface.Cylinder, heights: np.ndarray, tessellation: int,
                 inner_vertices: np.ndarray, inner_faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed solid with outward normals: (vertices (n, 3) float64 mm, faces (m, 3) int64).

    The inner layer's faces are reversed so its normals point into the cavity, which is
    outward for the glass.
    """
    verts, faces = surface.closed_outer_mesh(cyl, heights, tessellation)
    inner = inner_faces[:, ::-1] + len(verts)
    return np.vstack([verts, inner_vertices]), np.vstack([faces, inner])
