"""The outer surface: a smooth radial heightmap over the cylinder's angle u and height z.

The heightmap ``h`` holds radial offsets in mm at the nodes of a (u, v) grid:
``u_i = 2*pi*i/nu`` (periodic) and ``z_j = height*j/(nv-1)`` (both ends included).
The surface is the cubic spline through those nodes in each direction (not-a-knot in
z); in u it is one of two kinds, set by the fabrication profile (``Cylinder.creased``):

* smooth: the C2 periodic cubic through all u nodes (a milling tool cannot cut a sharp
  concave edge);
* creased: one not-a-knot cubic per 90° sector, joined with C0 continuity at the sector
  boundaries u = 45° + k·90° (``SEAMS_DEG``).  Each sector projects onto its own wall,
  so the light's direction jumps at a boundary: a crease lets it jump, where a smooth
  surface sweeps it across the walls' dark margins.  A printer makes a crease as easily
  as anything else.

    X(u, z) = (R + s(u, z)) * (cos u, sin u, 0) + (0, 0, z)

Every consumer uses this one surface: the optimizer traces its tessellation with true
facet normals, the STL is a tessellation of it, the STEP interpolates it.  Sampling
is a linear operator ``A_u @ h @ A_v.T``, so gradients pull back with the transposes.
Both kinds are B-splines with one coefficient per node (``UBasis``, ``VBasis``): local
bases for the ray-mapping solver, node interpolation for everything else.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

# Sector boundaries (degrees): where a creased surface may bend sharply.
SEAMS_DEG = (45.0, 135.0, 225.0, 315.0)


@dataclass(frozen=True)
class Cylinder:
    """The plain outer cylinder the heightmap displaces (mm), and the kind of spline in u."""
    radius_mm: float
    height_mm: float
    creased: bool = False

    def node_u(self, nu: int) -> np.ndarray:
        """(nu,) float64 rad."""
        return np.arange(nu) * (2 * np.pi / nu)

    def node_z(self, nv: int) -> np.ndarray:
        """(nv,) float64 mm."""
        return np.linspace(0.0, self.height_mm, nv)


class UBasis:
    """The cubic B-spline basis in u with one coefficient per node.

    Smooth: the uniform periodic basis.  Creased: per sector, the clamped basis on
    scipy's not-a-knot knots of that sector's ``n/4 + 1`` nodes; the coefficient at a seam
    (the sectors' common end value) is shared by the two sectors that meet there.
    """

    def __init__(self, n: int, creased: bool):
        if creased and n % 8:
            raise ValueError(f"a creased surface needs a multiple of 8 nodes around (seams on nodes), got {n}")
        self.n, self.creased = n, creased
        if creased:
            from scipy.interpolate import make_interp_spline

            self.q = n // 4
            self.local = make_interp_spline(np.linspace(0.0, 1.0, self.q + 1), np.eye(self.q + 1), k=3)
            self.coef_from_nodes = np.zeros((n, n))
            for s in range(4):
                rows = (self.first_node(s) + np.arange(self.q)) % n
                cols = (self.first_node(s) + np.arange(self.q + 1)) % n
                self.coef_from_nodes[np.ix_(rows, cols)] = self.local.c[: self.q]
        else:
            eigen = (4 + 2 * np.cos(2 * np.pi * np.arange(n) / n)) / 6
            col = np.real(np.fft.ifft(1.0 / eigen))  # first column of the circulant inverse
            self.coef_from_nodes = col[(np.arange(n)[:, None] - np.arange(n)[None, :]) % n]

    def first_node(self, sector: int) -> int:
        """Index of the node at a creased sector's low-u seam."""
        return self.n // 8 + sector * self.q

    def design(self, u: np.ndarray, d: int = 0) -> sp.csr_matrix:
        """(len(u), n) sparse: the d-th derivative (per rad^d) of each basis function at u (rad)."""
        u = np.asarray(u, np.float64)
        if d > 2:
            raise ValueError("derivative order 0..2")
        if self.creased:
            return self._creased_design(u, d)
        step = 2 * np.pi / self.n
        t = np.mod(u, 2 * np.pi) / step
        j = np.floor(t + 1e-12).astype(np.int64)
        f = t - j
        w = {0: [(1 - f) ** 3 / 6, (3 * f**3 - 6 * f**2 + 4) / 6, (-3 * f**3 + 3 * f**2 + 3 * f + 1) / 6, f**3 / 6],
             1: [-(1 - f) ** 2 / 2, 1.5 * f**2 - 2 * f, -1.5 * f**2 + f + 0.5, f**2 / 2],
             2: [1 - f, 3 * f - 2, 1 - 3 * f, f]}[d]
        rows = np.repeat(np.arange(len(u)), 4)
        cols = ((j[:, None] + np.arange(-1, 3)[None, :]) % self.n).ravel()
        vals = np.stack(w, 1).ravel() / step**d
        return sp.csr_matrix((vals, (rows, cols)), shape=(len(u), self.n))

    def _creased_design(self, u: np.ndarray, d: int) -> sp.csr_matrix:
        from scipy.interpolate import BSpline

        span = np.pi / 2
        rel = np.mod(u - np.radians(SEAMS_DEG[0]), 2 * np.pi) / span
        sector = np.minimum(np.floor(rel + 1e-12).astype(np.int64), 3)
        xi = np.clip(rel - sector, 0.0, 1.0)
        unique, inverse = np.unique(xi, return_inverse=True)
        local = BSpline(self.local.t, np.eye(self.q + 1), 3)
        values = (local.derivative(d) if d else local)(unique) / span**d  # (k, q + 1), zero off support
        rows, cols, vals = [], [], []
        for s in range(4):
            pick = np.flatnonzero(sector == s)
            block = values[inverse[pick]]
            r, c = np.nonzero(block)
            rows.append(pick[r])
            cols.append((self.first_node(s) + c) % self.n)
            vals.append(block[r, c])
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(len(u), self.n))


class VBasis:
    """The not-a-knot cubic B-spline basis in v (z normalized to [0, 1]), one coefficient per node."""

    def __init__(self, n: int):
        from scipy.interpolate import make_interp_spline

        self.n = n
        self.degree = 3 if n >= 4 else n - 1
        spline = make_interp_spline(np.linspace(0.0, 1.0, n), np.eye(n), k=self.degree)
        self.knots = spline.t
        self.coef_from_nodes = spline.c

    def design(self, x: np.ndarray, d: int = 0) -> sp.csr_matrix:
        """(len(x), n) sparse: the d-th derivative (per unit^d) of each basis function at x in [0, 1]."""
        from scipy.interpolate import BSpline

        x = np.asarray(x, np.float64)
        if d > self.degree:
            return sp.csr_matrix((len(x), self.n))
        basis = BSpline(self.knots, np.eye(self.n), self.degree)
        unique, inverse = np.unique(x, return_inverse=True)
        values = (basis.derivative(d) if d else basis)(unique)[inverse]
        return sp.csr_matrix(np.where(np.abs(values) > 1e-15, values, 0.0))


@lru_cache(maxsize=32)
def u_basis(n: int, creased: bool) -> UBasis:
    return UBasis(n, creased)


@lru_cache(maxsize=32)
def v_basis(n: int) -> VBasis:
    return VBasis(n)


@lru_cache(maxsize=32)
def u_design(n: int, m: int, d: int = 0, creased: bool = False) -> sp.csr_matrix:
    """(m, n) sparse: the d-th derivative (per radian^d) of each u basis function at m
    samples u = 2*pi*k/m (``u_matrix`` without the nodes' interpolation)."""
    return u_basis(n, creased).design(np.arange(m) * (2 * np.pi / m), d)


@lru_cache(maxsize=32)
def v_design(n: int, m: int, d: int = 0) -> sp.csr_matrix:
    """(m, n) sparse: the d-th derivative (per unit^d) of each v basis function at m
    samples on [0, 1], ends included (``open_matrix`` without the nodes' interpolation)."""
    return v_basis(n).design(np.linspace(0.0, 1.0, m), d)


@lru_cache(maxsize=32)
def u_matrix(n: int, m: int, d: int = 0, creased: bool = False) -> np.ndarray:
    """(m, n) float64: values at n nodes -> d-th derivative (per radian^d) of the u spline
    through them, at m samples u = 2*pi*k/m."""
    return np.asarray(u_design(n, m, d, creased) @ u_basis(n, creased).coef_from_nodes)


@lru_cache(maxsize=32)
def open_matrix(n: int, m: int, d: int = 0) -> np.ndarray:
    """(m, n) float64: values at n nodes on [0, 1] -> d-th derivative (per unit^d) of the
    not-a-knot cubic spline through them, at m samples (ends included)."""
    return np.asarray(v_design(n, m, d) @ v_basis(n).coef_from_nodes)


def sample(cyl: Cylinder, heights: np.ndarray, mu: int, mv: int) -> np.ndarray:
    """(nu, nv) mm at nodes -> (mu, mv) mm on the finer grid of the same spline."""
    nu, nv = heights.shape
    return u_matrix(nu, mu, 0, cyl.creased) @ heights @ open_matrix(nv, mv).T


def sample_adjoint(cyl: Cylinder, grad_fine: np.ndarray, nu: int, nv: int) -> np.ndarray:
    """Pull a gradient on the (mu, mv) samples back to the (nu, nv) nodes."""
    mu, mv = grad_fine.shape
    return u_matrix(nu, mu, 0, cyl.creased).T @ grad_fine @ open_matrix(nv, mv)


def coefficients(cyl: Cylinder, heights: np.ndarray) -> np.ndarray:
    """(nu, nv) mm node offsets -> (nu, nv) the spline's B-spline coefficients."""
    nu, nv = heights.shape
    return u_basis(nu, cyl.creased).coef_from_nodes @ heights @ v_basis(nv).coef_from_nodes.T


def evaluate(cyl: Cylinder, heights: np.ndarray, u: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The spline s(u, z) at arbitrary points: (N,) rad, (N,) mm -> (N,) mm."""
    nu, nv = heights.shape
    ub, vb = u_basis(nu, cyl.creased), v_basis(nv)
    coef = coefficients(cyl, np.asarray(heights, np.float64))
    u, z = np.asarray(u, np.float64), np.asarray(z, np.float64)
    out = np.empty(len(u))
    for start in range(0, len(u), 65536):
        part = slice(start, start + 65536)
        in_u = ub.design(u[part]) @ coef                      # (k, nv): each point's coefficients in v
        in_v = vb.design(z[part] / cyl.height_mm)
        out[part] = np.asarray(in_v.multiply(in_u).sum(axis=1)).ravel()
    return out


def fine_shape(nu: int, nv: int, tessellation: int) -> tuple[int, int]:
    """Sample counts of a tessellation with ``tessellation`` vertices per cell edge."""
    return nu * tessellation, (nv - 1) * tessellation + 1


def refine(cyl: Cylinder, heights: np.ndarray, factor: int = 4) -> np.ndarray:
    """The same surface on a grid ``factor`` times finer in u and v (coarse-to-fine):
    (nu, nv) mm node offsets -> (nu * factor, (nv - 1) * factor + 1) mm."""
    nu, nv = heights.shape
    return sample(cyl, heights, nu * factor, (nv - 1) * factor + 1)


def points(cyl: Cylinder, fine: np.ndarray) -> np.ndarray:
    """(mu, mv) mm radial offsets -> (mu, mv, 3) float64 mm surface points."""
    mu, mv = fine.shape
    u = cyl.node_u(mu)[:, None]
    z = cyl.node_z(mv)[None, :]
    r = cyl.radius_mm + fine
    return np.stack([r * np.cos(u), r * np.sin(u), np.broadcast_to(z, r.shape)], axis=-1)


def radial_dirs(mu: int, mv: int) -> np.ndarray:
    """(mu*mv, 3) float64: d point / d offset for each vertex (unit radial vectors)."""
    u = np.repeat(np.arange(mu) * (2 * np.pi / mu), mv)
    return np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], axis=-1)


def grid_faces(mu: int, mv: int) -> np.ndarray:
    """(2*mu*(mv-1), 3) int64 triangles of a periodic (mu, mv) vertex grid, outward winding.

    Vertex (i, j) has index i*mv + j.  Each quad is split along the diagonal that
    alternates with i+j parity so the tessellation has no preferred direction.
    """
    i, j = np.meshgrid(np.arange(mu), np.arange(mv - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    a = i * mv + j
    b = ((i + 1) % mu) * mv + j
    c = b + 1
    d = a + 1
    flip = ((i + j) % 2).astype(bool)
    # Outward normal: (b - a) is +u (tangent e_theta), (d - a) is +z; e_theta x e_z = e_r.
    t1 = np.where(flip[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(flip[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.concatenate([t1, t2]).astype(np.int64)


def cap_faces(mu: int, mv: int, centre_bottom: int, centre_top: int) -> np.ndarray:
    """Fans closing the bottom (z=0) and top rims of a (mu, mv) vertex grid (index
    i * mv + j) to two centre vertices: (2 * mu, 3) int64 faces.

    Winding makes the bottom face -z and the top face +z (outward for a solid).
    """
    i = np.arange(mu)
    nxt = (i + 1) % mu
    bottom = np.stack([np.full(mu, centre_bottom), nxt * mv, i * mv], 1)
    top = np.stack([np.full(mu, centre_top), i * mv + mv - 1, nxt * mv + mv - 1], 1)
    return np.concatenate([bottom, top]).astype(np.int64)


def closed_outer_faces(mu: int, mv: int) -> np.ndarray:
    """The faces of ``closed_outer_mesh`` on a (mu, mv) vertex grid: the grid's, then
    the fans to the two centre vertices after it; (F, 3) int64."""
    return np.vstack([grid_faces(mu, mv), cap_faces(mu, mv, mu * mv, mu * mv + 1)])


def closed_outer_vertices(cyl: Cylinder, heights: np.ndarray, tessellation: int) -> np.ndarray:
    """The vertices of ``closed_outer_mesh``: the tessellation's grid, then the two fans'
    centres on the axis; (mu * mv + 2, 3) float64 mm."""
    fine = sample(cyl, heights, *fine_shape(*heights.shape, tessellation))
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, cyl.height_mm]])
    return np.vstack([points(cyl, fine).reshape(-1, 3), centres])


def closed_outer_mesh(cyl: Cylinder, heights: np.ndarray, tessellation: int) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface closed by flat caps at z = 0 and z = height: a closed mesh (mm)."""
    return (closed_outer_vertices(cyl, heights, tessellation),
            closed_outer_faces(*fine_shape(*heights.shape, tessellation)))


def radius_derivatives(cyl: Cylinder, heights: np.ndarray, mu: int, mv: int, order: int = 2,
                       rows: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """The radius (mm) and its derivatives by u (rad) and z (mm) on the (mu, mv) sample
    grid, from the spline itself (exact: curvature needs second derivatives, which
    differencing would make noisy).  Returns (r, r_u, r_z), each (mu, mv), and with
    ``order`` 2 also (r_uu, r_uz, r_zz); with ``rows`` (k,) int, only those sample rows
    around (each (k, mv))."""
    nu, nv = heights.shape
    pick = slice(None) if rows is None else rows
    # The spline's coefficients once, then each sample from the four basis functions
    # over it (sparse): a tenth of the work of the dense node-to-sample matrices.
    coef = coefficients(cyl, heights)
    along_u = [u_design(nu, mu, d, cyl.creased)[pick] @ coef for d in range(order + 1)]
    pz = [v_design(nv, mv, d) / cyl.height_mm**d for d in range(order + 1)]

    def across(samples_u, d):
        return (pz[d] @ samples_u.T).T

    first = (cyl.radius_mm + across(along_u[0], 0), across(along_u[1], 0), across(along_u[0], 1))
    if order < 2:
        return first
    return (*first, across(along_u[2], 0), across(along_u[1], 1), across(along_u[0], 2))


def tilt_tangent(r: np.ndarray, r_u: np.ndarray, r_z: np.ndarray) -> np.ndarray:
    """tan of the angle between the surface normal and the radial direction, from the
    radius r (mm), dr/du (mm per rad) and dr/dz (1) of the same shape; float64, 1."""
    # In place rather than np.hypot, whose care for overflow (needless at these sizes)
    # took 2.5 times as long on the projection's million samples.
    t = r_u / r
    t *= t
    t += r_z * r_z
    return np.sqrt(t, out=t)


def slopes_deg(cyl: Cylinder, heights: np.ndarray, mu: int, mv: int) -> tuple[np.ndarray, np.ndarray]:
    """Angle between the surface normal and the radial direction, from the spline's
    exact derivatives, and its part along z.

    Returns ((mu, mv) float64 deg total tilt, (mu, mv) float64 deg tilt along z: positive
    where the radius grows upward, i.e. the surface faces down).
    """
    r, r_u, r_z = radius_derivatives(cyl, heights, mu, mv, order=1)
    tilt = np.degrees(np.arctan(tilt_tangent(r, r_u, r_z)))
    return tilt, np.degrees(np.arctan(r_z))


def slope_penalty(cyl: Cylinder, heights: np.ndarray, max_tilt_deg: float, max_rise_deg: float | None = None,
                  samples_per_cell: int = 2) -> tuple[float, np.ndarray]:
    """Mean squared excess of tan(tilt) over tan(max_tilt_deg) on a grid finer than the
    nodes, plus, with ``max_rise_deg`` (a print's overhang limit), that of dr/dz over
    tan(max_rise_deg) where the surface faces down; and its exact gradient on the nodes
    ((nu, nv) per mm).

    Keeps a gradient-based optimizer inside the fabrication profile's limits instead of
    projecting it back after every step."""
    nu, nv = heights.shape
    mu, mv = fine_shape(nu, nv, samples_per_cell)
    p0, p1 = u_matrix(nu, mu, 0, cyl.creased), u_matrix(nu, mu, 1, cyl.creased)
    z0, z1 = open_matrix(nv, mv), open_matrix(nv, mv, 1) / cyl.height_mm
    r, r_u, r_z = radius_derivatives(cyl, heights, mu, mv, order=1)
    t = tilt_tangent(r, r_u, r_z)
    excess = np.maximum(t - np.tan(np.radians(max_tilt_deg)), 0.0)
    n = excess.size
    d_t = 2.0 * excess / n / np.maximum(t, 1e-12)
    d_rz = d_t * r_z
    penalty = float(np.sum(excess**2) / n)
    if max_rise_deg is not None:
        rise_excess = np.maximum(r_z - np.tan(np.radians(max_rise_deg)), 0.0)
        penalty += float(np.sum(rise_excess**2) / n)
        d_rz = d_rz + 2.0 * rise_excess / n
    grad = p1.T @ (d_t * r_u / r**2) @ z0 + p0.T @ d_rz @ z1 - p0.T @ (d_t * r_u**2 / r**3) @ z0
    return penalty, grad
