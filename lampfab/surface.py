"""The outer surface: a smooth radial heightmap over the cylinder's angle u and height z.

The heightmap ``h`` holds radial offsets in mm at the nodes of a (u, v) grid:
``u_i = 2*pi*i/nu`` (periodic) and ``z_j = height*j/(nv-1)`` (both ends included).
The surface is the bicubic spline through those nodes (periodic cubic in u,
not-a-knot cubic in z):

    X(u, z) = (R + s(u, z)) * (cos u, sin u, 0) + (0, 0, z)

Every consumer uses this one surface: the optimizer traces its tessellation with true
facet normals, the STL is a tessellation of it, the STEP interpolates it.  Sampling
is a linear operator ``A_u @ h @ A_v.T``, so gradients pull back with the transposes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np


@lru_cache(maxsize=32)
def periodic_matrix(n: int, m: int, d: int = 0) -> np.ndarray:
    """(m, n) float64: values at n periodic nodes -> d-th derivative (per radian^d) of
    the periodic cubic spline through them, at m samples.

    Nodes at 2*pi*i/n, samples at 2*pi*k/m.  Uniform cubic B-spline: the control
    points solve the circulant system (c[i-1] + 4 c[i] + c[i+1]) / 6 = y[i] (by FFT),
    then each sample mixes four control points with the B-spline weights (or their
    derivatives).
    """
    step = 2 * np.pi / n
    t = np.arange(m) * (n / m)
    j = np.floor(t + 1e-12).astype(np.int64)
    f = t - j
    if d == 0:
        w = [(1 - f) ** 3 / 6, (3 * f**3 - 6 * f**2 + 4) / 6, (-3 * f**3 + 3 * f**2 + 3 * f + 1) / 6, f**3 / 6]
    elif d == 1:
        w = [-(1 - f) ** 2 / 2, 1.5 * f**2 - 2 * f, -1.5 * f**2 + f + 0.5, f**2 / 2]
    elif d == 2:
        w = [1 - f, 3 * f - 2, 1 - 3 * f, f]
    else:
        raise ValueError("derivative order 0..2")
    basis = np.zeros((m, n))
    rows = np.arange(m)
    for off, wk in zip((-1, 0, 1, 2), w):
        np.add.at(basis, (rows, (j + off) % n), wk / step**d)
    eigen = (4 + 2 * np.cos(2 * np.pi * np.arange(n) / n)) / 6
    col = np.real(np.fft.ifft(1.0 / eigen))  # first column of the circulant inverse
    return basis @ col[(np.arange(n)[:, None] - np.arange(n)[None, :]) % n]


@lru_cache(maxsize=32)
def open_matrix(n: int, m: int, d: int = 0) -> np.ndarray:
    """(m, n) float64: values at n nodes on [0, 1] -> d-th derivative (per unit^d) of
    the not-a-knot cubic spline through them, at m samples (ends included)."""
    from scipy.interpolate import make_interp_spline

    x = np.linspace(0.0, 1.0, n)
    k = 3 if n >= 4 else n - 1
    if d > k:
        return np.zeros((m, n))
    spline = make_interp_spline(x, np.eye(n), k=k)
    return spline(np.linspace(0.0, 1.0, m), nu=d)


@dataclass(frozen=True)
class Cylinder:
    """The plain outer cylinder the heightmap displaces (mm)."""
    radius_mm: float
    height_mm: float

    def node_u(self, nu: int) -> np.ndarray:
        """(nu,) float64 rad."""
        return np.arange(nu) * (2 * np.pi / nu)

    def node_z(self, nv: int) -> np.ndarray:
        """(nv,) float64 mm."""
        return np.linspace(0.0, self.height_mm, nv)


def sample(heights: np.ndarray, mu: int, mv: int) -> np.ndarray:
    """(nu, nv) mm at nodes -> (mu, mv) mm on the finer grid of the same spline."""
    nu, nv = heights.shape
    return periodic_matrix(nu, mu) @ heights @ open_matrix(nv, mv).T


def sample_adjoint(grad_fine: np.ndarray, nu: int, nv: int) -> np.ndarray:
    """Pull a gradient on the (mu, mv) samples back to the (nu, nv) nodes."""
    mu, mv = grad_fine.shape
    return periodic_matrix(nu, mu).T @ grad_fine @ open_matrix(nv, mv)


def fine_shape(nu: int, nv: int, tessellation: int) -> tuple[int, int]:
    """Sample counts of a tessellation with ``tessellation`` vertices per cell edge."""
    return nu * tessellation, (nv - 1) * tessellation + 1


def refine(heights: np.ndarray, factor: int = 4) -> np.ndarray:
    """The same surface on a grid ``factor`` times finer in u and v (coarse-to-fine)."""
    nu, nv = heights.shape
    return sample(heights, nu * factor, (nv - 1) * factor + 1)


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


def outer_mesh(cyl: Cylinder, heights: np.ndarray, tessellation: int) -> tuple[np.ndarray, np.ndarray]:
    """Tessellated outer surface: ((mu*mv, 3) float64 mm vertices, (F, 3) int64 faces)."""
    mu, mv = fine_shape(*heights.shape, tessellation)
    fine = sample(heights, mu, mv)
    return points(cyl, fine).reshape(-1, 3), grid_faces(mu, mv)


def cap_faces(mu: int, mv: int, centre_bottom: int, centre_top: int) -> np.ndarray:
    """Fans closing the bottom (z=0) and top rims of the grid to two centre vertices.

    Winding makes the bottom face -z and the top face +z (outward for a solid).
    """
    i = np.arange(mu)
    nxt = (i + 1) % mu
    bottom = np.stack([np.full(mu, centre_bottom), nxt * mv, i * mv], 1)
    top = np.stack([np.full(mu, centre_top), i * mv + mv - 1, nxt * mv + mv - 1], 1)
    return np.concatenate([bottom, top]).astype(np.int64)


def closed_outer_mesh(cyl: Cylinder, heights: np.ndarray, tessellation: int) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface closed by flat caps at z = 0 and z = height: a closed mesh (mm)."""
    verts, faces = outer_mesh(cyl, heights, tessellation)
    mu, mv = fine_shape(*heights.shape, tessellation)
    n = len(verts)
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, cyl.height_mm]])
    caps = cap_faces(mu, mv, n, n + 1)
    return np.vstack([verts, centres]), np.vstack([faces, caps])


def slopes_deg(cyl: Cylinder, heights: np.ndarray, mu: int, mv: int) -> tuple[np.ndarray, np.ndarray]:
    """Angle between the surface normal and the radial direction, from the spline's
    exact derivatives, and its part along z.

    Returns ((mu, mv) float64 deg total tilt, (mu, mv) float64 deg tilt along z).
    """
    nu, nv = heights.shape
    pz = open_matrix(nv, mv)
    r = cyl.radius_mm + periodic_matrix(nu, mu) @ heights @ pz.T
    r_u = periodic_matrix(nu, mu, 1) @ heights @ pz.T
    r_z = periodic_matrix(nu, mu) @ heights @ open_matrix(nv, mv, 1).T / cyl.height_mm
    tilt = np.degrees(np.arctan(np.hypot(r_u / r, r_z)))
    return tilt, np.degrees(np.arctan(np.abs(r_z)))


def slope_penalty(cyl: Cylinder, heights: np.ndarray, max_tilt_deg: float,
                  samples_per_cell: int = 2) -> tuple[float, np.ndarray]:
    """Mean squared excess of tan(tilt) over tan(max_tilt_deg) on a grid finer than the
    nodes, and its exact gradient on the nodes ((nu, nv) per mm).

    Keeps a gradient-based optimizer inside the fabrication profile's slope limit
    instead of projecting it back after every step."""
    nu, nv = heights.shape
    mu, mv = fine_shape(nu, nv, samples_per_cell)
    p0, p1 = periodic_matrix(nu, mu), periodic_matrix(nu, mu, 1)
    z0, z1 = open_matrix(nv, mv), open_matrix(nv, mv, 1) / cyl.height_mm
    r = cyl.radius_mm + p0 @ heights @ z0.T
    r_u = p1 @ heights @ z0.T
    r_z = p0 @ heights @ z1.T
    t = np.hypot(r_u / r, r_z)
    excess = np.maximum(t - np.tan(np.radians(max_tilt_deg)), 0.0)
    n = excess.size
    d_t = 2.0 * excess / n / np.maximum(t, 1e-12)
    grad = p1.T @ (d_t * r_u / r**2) @ z0 + p0.T @ (d_t * r_z) @ z1 - p0.T @ (d_t * r_u**2 / r**3) @ z0
    return float(np.sum(excess**2) / n), grad
