"""Where rays from inside the glass first meet the outer surface, without a BVH.

The outer surface is a radial heightmap tessellated on a periodic (mu, mv) vertex grid
(``surface.closed_outer_mesh``).  A ray's facet is found in two walks.  First from where
the ray meets a cylinder to where it meets the plane of the facet found there, and so
on: a Newton step on the surface each time (the facet's plane is its tangent plane).
Then across the mesh a facet at a time, leaving each facet across the edge its
barycentric weights point past, until one holds the hit point.  The fans that close
the top and bottom are found apart, by where the ray meets their planes.

The refinement moves every vertex on every step, and Mitsuba must then build its BVH
again (0.28 s a step for the default's 526 k facets on 2 cores, a fifth of a fine step,
and its intersection as long again).  The walk needs no structure and finds the facets
of a fine step's photons 2.6-3.8 times faster than Mitsuba builds and intersects.
It gave Mitsuba's facet to 99.97-99.999 % of the photons on the built lenses; the rest
lie on an edge two facets share, or the walk does not settle on a facet ahead of the
photon (under 3 in 10⁴, where a ray runs nearly along the surface), and the caller
leaves those out (``bench/facet_walk.py``; bench/log/2026-12-07.md).

Faces are numbered as ``closed_outer_mesh`` numbers them: the first triangle of each
cell (i, j) is ``i * (mv - 1) + j``, the second ``mu * (mv - 1)`` later, then the bottom
fan's ``mu`` triangles and the top fan's.
"""

from __future__ import annotations

import math

from .tolerances import FACET_WALK_BARYCENTRIC

# Steps of each walk.  On the apple's lens 6 + 6 left 206 of 2 M photons unsettled;
# 4 + 10 left 314, 8 + 12 left 187 (each step costs ~7 ms per million photons).
NEWTON_STEPS = 6
EDGE_STEPS = 6


def first_hits(mi, o, d, positions, mu: int, mv: int, height_mm: float, radius_mm: float):
    """The facet each ray (o, d) (Dr.Jit Point3f, Vector3f; origins inside the closed
    outer mesh, mm) crosses first, as the mesh's face index (Dr.Jit UInt32), and whether
    the walk settled on it (Dr.Jit Bool).

    ``positions`` (Dr.Jit Point3f, mm): the mesh's mu * mv grid vertices (index
    i * mv + j at angle 2 pi i / mu, height height_mm * j / (mv - 1)) and the two fan
    centres after them.  ``radius_mm``: a radius near the surface's, where the walk
    starts.
    """
    import drjit as dr

    du = 2.0 * math.pi / mu
    dz = height_mm / (mv - 1)
    cells = mu * (mv - 1)

    # Start where the ray meets the cylinder of radius_mm (the positive root: the
    # origin lies inside it).
    a = d.x * d.x + d.y * d.y
    b = o.x * d.x + o.y * d.y
    c = o.x * o.x + o.y * o.y - radius_mm * radius_mm
    t = (dr.safe_sqrt(b * b - a * c) - b) / dr.maximum(a, 1e-12)
    p = o + t * d
    for _ in range(NEWTON_STEPS):
        i, j, second = _cell_at(mi, p, du, dz, mu, mv)
        v0, v1, v2 = _corners(mi, positions, i, j, second, mu, mv)
        normal = dr.cross(v1 - v0, v2 - v0)
        t = dr.dot(v0 - o, normal) / dr.dot(d, normal)
        p = o + t * d
    # Then across the mesh, a facet at a time: each step leaves the facet across the edge
    # facing the corner whose barycentric weight is most negative, until it holds the hit.
    settled = mi.Bool(False)
    for _ in range(EDGE_STEPS):
        v0, v1, v2 = _corners(mi, positions, i, j, second, mu, mv)
        e1, e2 = v1 - v0, v2 - v0
        pv = dr.cross(d, e2)
        det = dr.dot(e1, pv)
        s = o - v0
        b1 = dr.dot(s, pv) / det
        qv = dr.cross(s, e1)
        b2 = dr.dot(d, qv) / det
        t = dr.dot(e2, qv) / det
        b0 = 1.0 - b1 - b2
        holds = (b0 >= -FACET_WALK_BARYCENTRIC) & (b1 >= -FACET_WALK_BARYCENTRIC) & (b2 >= -FACET_WALK_BARYCENTRIC)
        # A ray nearly along the surface can be led to the facet its line crosses behind
        # its origin, on the far side of the lens: that one does not count.
        settled = holds & (t > 0)
        away = ~holds
        # Which edge: opposite corner 0, 1 or 2 of the facet's (k0, k1, k2).
        k = dr.select((b0 <= b1) & (b0 <= b2), 0, dr.select(b1 <= b2, 1, 2))
        i, j, second = _across(mi, i, j, second, k, away, mu, mv)
    prim = mi.UInt32(i * (mv - 1) + j) + dr.select(second, mi.UInt32(cells), mi.UInt32(0))
    # A ray that reaches a fan's plane inside the fan's rim meets the fan first, in the
    # wedge its angle falls in (the fans' edges are radial; the rim is the grid's first
    # or last row, chords between its vertices).
    up = d.z > 0
    t_cap = (dr.select(up, height_mm, 0.0) - o.z) / d.z
    q = o + t_cap * d
    wedge = dr.clip(mi.Int32(dr.floor(_angle(q) / du)), 0, mu - 1)
    row = dr.select(up, mv - 1, 0)
    r0 = dr.gather(mi.Point3f, positions, mi.UInt32(wedge * mv + row))
    r1 = dr.gather(mi.Point3f, positions, mi.UInt32(dr.select(wedge + 1 == mu, 0, wedge + 1) * mv + row))
    inside_rim = (r1.x - r0.x) * (q.y - r0.y) - (r1.y - r0.y) * (q.x - r0.x) > 0
    cap = (t_cap > 0) & inside_rim
    fan = mi.UInt32(2 * cells + wedge) + dr.select(up, mi.UInt32(mu), mi.UInt32(0))
    return dr.select(cap, fan, prim), settled | cap


def _cell_at(mi, p, du, dz, mu, mv):
    """The cell (i, j) under point p's angle and height, and which of its two facets
    (``second``) holds p's (u, z) in the grid's own coordinates."""
    import drjit as dr

    fu = _angle(p) / du
    fz = dr.clip(p.z / dz, 0.0, float(mv - 1))
    i = mi.Int32(dr.floor(fu))
    j = dr.clip(mi.Int32(dr.floor(fz)), 0, mv - 2)
    i = dr.select(i >= mu, i - mu, dr.select(i < 0, i + mu, i))
    fu -= mi.Float(i)
    fz -= mi.Float(j)
    odd = ((i + j) & 1) == 1
    return i, j, dr.select(odd, fz > fu, fu + fz > 1.0)


def _angle(p):
    """The angle of points p around the axis, in [0, 2 pi) (Dr.Jit Float, rad)."""
    import drjit as dr

    u = dr.atan2(p.y, p.x)
    return dr.select(u < 0, u + 2.0 * math.pi, u)


def _corners(mi, positions, i, j, second, mu, mv):
    """The three corners of facet (i, j, second), in grid_faces' order (outward winding).

    Odd cells are split along a-c into (a, b, c), (a, c, d); even ones along b-d into
    (a, b, d), (b, c, d); a = (i, j), b = (i+1, j), c = (i+1, j+1), d = (i, j+1)."""
    import drjit as dr

    odd = ((i + j) & 1) == 1
    va = mi.UInt32(i * mv + j)
    vb = mi.UInt32(dr.select(i + 1 == mu, 0, i + 1) * mv + j)
    vc, vd = vb + 1, va + 1
    k0 = dr.select(odd | ~second, va, vb)
    k1 = dr.select(second, vc, vb)
    k2 = dr.select(odd, dr.select(second, vd, vc), vd)
    return tuple(dr.gather(mi.Point3f, positions, k) for k in (k0, k1, k2))


def _across(mi, i, j, second, k, move, mu, mv):
    """The facet across the edge opposite corner k (0, 1, 2) of facet (i, j, second),
    where ``move``; rows stay within the grid (the fans are found apart)."""
    import drjit as dr

    odd = ((i + j) & 1) == 1
    # Each corner's opposite edge, per facet (see _corners):
    #   odd first (a, b, c): b-c right, a-c diagonal, a-b bottom
    #   odd second (a, c, d): c-d top, a-d left, a-c diagonal
    #   even first (a, b, d): b-d diagonal, a-d left, a-b bottom
    #   even second (b, c, d): c-d top, b-d diagonal, b-c right
    right, left, top, bottom, diag = 0, 1, 2, 3, 4
    edge = dr.select(odd,
                     dr.select(second, dr.select(k == 0, top, dr.select(k == 1, left, diag)),
                               dr.select(k == 0, right, dr.select(k == 1, diag, bottom))),
                     dr.select(second, dr.select(k == 0, top, dr.select(k == 1, diag, right)),
                               dr.select(k == 0, diag, dr.select(k == 1, left, bottom))))
    ni = dr.select(edge == right, i + 1, dr.select(edge == left, i - 1, i))
    ni = dr.select(ni >= mu, ni - mu, dr.select(ni < 0, ni + mu, ni))
    nj = dr.clip(dr.select(edge == top, j + 1, dr.select(edge == bottom, j - 1, j)), 0, mv - 2)
    nodd = ((ni + nj) & 1) == 1
    # The neighbour's facet holding the shared edge: a cell's top edge is in its second
    # facet, its bottom edge in its first; its left edge in the second on odd cells and
    # the first on even ones, its right edge the other way round.
    nsecond = dr.select(edge == diag, ~second,
                        dr.select(edge == right, nodd,
                                  dr.select(edge == left, ~nodd, edge == bottom)))
    return (dr.select(move, ni, i), dr.select(move, nj, j), dr.select(move, nsecond, second))
