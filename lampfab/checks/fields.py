"""Per-cell fields of the outer surface that the fabrication checks read (see ``lamp``).

Everything is evaluated on one fine (mu, mv) sample grid of the outer surface: u_i =
2*pi*i/mu (periodic) and z_j = H*j/(mv-1), the same grid ``surface.sample`` uses, so a
cell of any field maps to one pixel of the unrolled surface in ``checks.png``.

Units: mm, rad inside, degrees where a name says ``deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import surface
from ..curvature import SAMPLES, concave_radius_of, sample_counts
from .distance import distance_to_mesh

@dataclass
class Fields:
    """Per-cell quantities on the (mu, mv) grid of the outer surface (mm, deg).

    ``u`` (mu,) rad and ``z`` (mv,) mm are the grid; ``xyz`` (mu, mv, 3) the surface points;
    ``normal`` (mu, mv, 3) the outward unit normals; ``area`` (mu, mv) mm^2 the surface area
    of each cell; ``wall`` (mu, mv) mm the signed distance from the outer surface to the
    inner layer or the bore (negative: the outer surface is inside the cavity);
    ``slope`` (mu, mv) deg the tilt against the radial direction (as ``surface.slopes_deg``);
    ``concave_radius`` (mu, mv) mm the smallest concave radius of curvature (inf where the
    surface is convex in every direction); ``overhang`` (mu, mv) deg how far a down-facing
    cell leans past vertical (0 for up-facing and vertical cells).  The caps are single
    numbers: ``wall_top``/``wall_base`` mm with the points where they are thinnest.
    """
    u: np.ndarray
    z: np.ndarray
    xyz: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    wall: np.ndarray
    slope: np.ndarray
    concave_radius: np.ndarray
    overhang: np.ndarray
    wall_top: float
    wall_top_xyz: np.ndarray
    wall_base: float
    wall_base_xyz: np.ndarray


def compute_fields(cyl: surface.Cylinder, heights: np.ndarray, inner_vertices: np.ndarray,
                   inner_faces: np.ndarray, mount_radius_mm: float,
                   samples: tuple[int, int] = SAMPLES) -> Fields:
    """All per-cell fields of the outer surface for heights (nu, nv) mm on a (mu, mv) grid.

    ``samples`` is raised to at least twice the node counts so that every spline cell is
    sampled inside, not only at its nodes.
    """
    heights = np.asarray(heights, np.float64)
    mu, mv = sample_counts(heights.shape, samples)
    H = cyl.height_mm
    r, r_u, r_z, r_uu, r_uz, r_zz = surface.radius_derivatives(cyl, heights, mu, mv)
    s = r - cyl.radius_mm

    u = cyl.node_u(mu)
    z = cyl.node_z(mv)
    xyz = surface.points(cyl, s)
    cu, su = np.cos(u)[:, None], np.sin(u)[:, None]

    # In the local frame (e_r, e_theta, e_z): X_u = (r_u, r, 0), X_z = (r_z, 0, 1), so the
    # outward normal X_u x X_z = (r, -r_u, -r r_z) and |X_u x X_z| du dz is the area.
    n_len = np.sqrt(r**2 + r_u**2 + (r * r_z) ** 2)
    n_r, n_t, n_z = r / n_len, -r_u / n_len, -r * r_z / n_len
    normal = np.stack([n_r * cu - n_t * su, n_r * su + n_t * cu, n_z], axis=-1)
    dz = np.full(mv, H / (mv - 1))
    dz[[0, -1]] *= 0.5  # the end rows own half a cell: the areas sum to the surface area
    area = n_len * (2 * np.pi / mu) * dz[None, :]

    # Overhang for an upright print: a cell faces down when n_z < 0; asin(-n_z) is how far
    # it leans past vertical (0 = vertical wall, 90 = horizontal ceiling).
    overhang = np.degrees(np.arcsin(np.clip(-n_z, 0.0, 1.0)))

    concave_radius = concave_radius_of(r, r_u, r_z, r_uu, r_uz, r_zz)
    slope = np.degrees(np.arctan(surface.tilt_tangent(r, r_u, r_z)))

    iv = np.asarray(inner_vertices, np.float64)
    fi = np.asarray(inner_faces, np.int64)
    dist, side = distance_to_mesh(xyz.reshape(-1, 3), iv, fi)
    dist = dist.reshape(mu, mv) * _settle_side(xyz, dist.reshape(mu, mv), side.reshape(mu, mv), iv, fi)
    # The bore (a cylinder of radius mount_radius around the axis, from the base up to the
    # cavity) is material removed too: below its top the wall is also r - mount_radius.
    bore_top = float(iv[:, 2].min())
    bore_wall = np.where(z[None, :] <= bore_top, r - mount_radius_mm, np.inf)
    wall = np.minimum(dist, bore_wall)

    # Caps are planes, so the thinnest cap wall is the plane's distance to the nearest
    # inner vertex (a mesh's extreme along a direction is always at a vertex).
    # Where a flat roof ties, point at the middle of the tied vertices (its centre).
    top_z = float(iv[:, 2].max())
    tied = iv[iv[:, 2] >= top_z - 1e-9]
    wall_top = float(H - top_z)
    top_xyz = np.array([*tied[:, :2].mean(axis=0), H])
    # The base only exists outside the bore: inner vertices over the bore sit over air.
    rho = np.hypot(iv[:, 0], iv[:, 1])
    over_base = rho > mount_radius_mm
    if over_base.any():
        cand = np.where(over_base, iv[:, 2], np.inf)
        wall_base = float(cand.min())
        tied = iv[cand <= wall_base + 1e-9]
        base_xyz = np.array([*tied[:, :2].mean(axis=0), 0.0])
    else:
        wall_base, base_xyz = float("inf"), np.zeros(3)

    return Fields(u=u, z=z, xyz=xyz, normal=normal, area=area, wall=wall, slope=slope,
                  concave_radius=concave_radius, overhang=overhang, wall_top=wall_top,
                  wall_top_xyz=top_xyz, wall_base=wall_base, wall_base_xyz=base_xyz)


def _settle_side(xyz: np.ndarray, dist: np.ndarray, side: np.ndarray, vertices: np.ndarray,
                 faces: np.ndarray) -> np.ndarray:
    """(mu, mv) +1 where the outer surface is outside the inner layer, -1 inside it.

    The outer surface can only pass from one side of the inner layer to the other where
    it crosses it, and there its distance goes through 0.  Two neighbouring cells whose
    distances both exceed half their spacing are on the same side (|d1| + |d2| > |p1 - p2|
    rules out a crossing between them), so every connected region of such cells has one
    side, settled by the winding number of the inner layer at its clearest cell.  Cells
    closer than that are near the mesh, where the local side from the nearest triangle is
    reliable.
    """
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from ..inner import winding_number

    step_u = np.linalg.norm(np.roll(xyz, -1, axis=0) - xyz, axis=-1).max()
    step_z = np.linalg.norm(np.diff(xyz, axis=1), axis=-1).max() if xyz.shape[1] > 1 else 0.0
    clear = dist > 0.55 * max(step_u, step_z)             # 10 % margin over the half spacing
    labels, n = ndimage.label(clear)
    out = side.copy()
    if n == 0:
        return out
    # u is periodic: regions touching both ends of the u range are one region.
    a, b = labels[0], labels[-1]
    both = (a > 0) & (b > 0)
    graph = coo_matrix((np.ones(both.sum()), (a[both] - 1, b[both] - 1)), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    region = np.where(labels > 0, comp[np.maximum(labels, 1) - 1], -1)
    for r in np.unique(region[region >= 0]):
        cells = region == r
        pick = np.unravel_index(np.argmax(np.where(cells, dist, -np.inf)), dist.shape)
        inside = winding_number(vertices, faces, xyz[pick]) > 0.5
        out[cells] = -1.0 if inside else 1.0
    return out


def faces_on_grid(iv: np.ndarray, faces: np.ndarray, f: Fields) -> np.ndarray:
    """(mu, mv) bool: the cells of ``f``'s grid at the angles and heights of the faces'
    corners and centroids (iv (n, 3) mm, faces (k, 3) int), so ``checks.png`` can mark
    the cavity's faces on the unrolled outer surface."""
    out = np.zeros(f.wall.shape, bool)
    if not len(faces):
        return out
    tri = iv[faces]
    pts = np.concatenate([tri.reshape(-1, 3), tri.mean(axis=1)])
    mu, mv = out.shape
    u = np.arctan2(pts[:, 1], pts[:, 0]) % (2 * np.pi)
    i = np.round(u / (2 * np.pi) * mu).astype(int) % mu
    j = np.clip(np.round(pts[:, 2] / f.z[-1] * (mv - 1)).astype(int), 0, mv - 1)
    out[i, j] = True
    return out
