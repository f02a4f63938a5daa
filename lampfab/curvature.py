"""How tightly the outer surface curves, measured one way for the design and the checks.

A ball-end mill of radius R cannot reach the bottom of a hollow whose radius of
curvature is below R.  The transport fit, the refinement's hollow penalty, the hollow
smoothing (``concavity``) and the ``tool_radius`` check all read the curvature from the
fundamental forms here, on the same sample grid (``SAMPLES``), so a surface the design
lets through is the surface the check passes.

Frame: X(u, z) = r (cos u, sin u, 0) + (0, 0, z) with r = R + s(u, z) and the outward
unit normal n; the derivatives of r come from ``surface.radius_derivatives``.  Units:
mm, u in rad.
"""

from __future__ import annotations

import numpy as np

from . import surface

# The sample grid of the outer surface's checks (around, up): 0.35° and 0.35 mm apart on
# the default lens, finer than any feature a printer or a mill makes.  The design's slope
# and hollow limits sample at these very points (and more), or the check would find what
# they missed: a spline steepens between samples, most near a crease.
SAMPLES = (1024, 256)


def cell_samples(grid: tuple[int, int], samples: tuple[int, int] = SAMPLES) -> int:
    """Samples per spline cell edge of the checks' grid over the (nu, nv) node ``grid``:
    enough to reach ``samples`` each way, and at least 2, so that every cell is sampled
    inside, not only at its nodes."""
    nu, nv = grid
    return max(2, -(-samples[0] // nu), -(-(samples[1] - 1) // max(nv - 1, 1)))


def sample_counts(grid: tuple[int, int], samples: tuple[int, int] = SAMPLES) -> tuple[int, int]:
    """(mu, mv): the checks' sample grid over the (nu, nv) node ``grid``, ``cell_samples``
    per cell edge from the nodes on (``surface.fine_shape``): a projection that samples
    every cell k times as finely, k a multiple of it, sees every point the checks see."""
    return surface.fine_shape(*grid, cell_samples(grid, samples))


def fundamental_forms(r, r_u, r_z, r_uu, r_uz, r_zz) -> tuple[np.ndarray, ...]:
    """(E, F, G, L, M, N): the first and second fundamental forms of the surface on the
    sample grid, from the radius and its derivatives (``concave_radius_of`` has the
    frame and the sign).  L / E and N / G are the normal curvatures along u and z."""
    n_len = np.sqrt(r**2 + r_u**2 + (r * r_z) ** 2)
    return (r_u**2 + r**2, r_u * r_z, r_z**2 + 1.0, ((r_uu - r) * r - 2 * r_u**2) / n_len,
            (r_uz * r - r_z * r_u) / n_len, r_zz * r / n_len)


def concave_radius_of(r, r_u, r_z, r_uu, r_uz, r_zz) -> np.ndarray:
    """(mu, mv) mm: 1 / (largest principal curvature) where it is concave, inf elsewhere.

    In (e_r, e_theta, e_z): X_uu = (r_uu - r, 2 r_u, 0), X_uz = (r_uz, r_z, 0),
    X_zz = (r_zz, 0, 0).  With n outward, a convex bulge (the plain cylinder: kappa = -1/r)
    has negative normal curvature; positive curvature curves toward the outside, i.e. a
    hollow that a ball of radius > 1/kappa cannot touch the bottom of.
    """
    E, F, G, L, M, N = fundamental_forms(r, r_u, r_z, r_uu, r_uz, r_zz)
    det_i = E * G - F**2
    mean = (E * N - 2 * F * M + G * L) / (2 * det_i)
    gauss = (L * N - M**2) / det_i
    k_max = mean + np.sqrt(np.maximum(mean**2 - gauss, 0.0))
    with np.errstate(divide="ignore"):
        # Curvatures below 1e-9 / mm are flat for any tool (radius > 1 km).
        return np.where(k_max > 1e-9, 1.0 / np.maximum(k_max, 1e-300), np.inf)


def concave_radius(cyl: surface.Cylinder, heights: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """(mu, mv) mm: the smallest concave radius of curvature on the check's samples
    (``SAMPLES``), inf where the surface is convex; with ``rows`` (k,) int, only those
    sample rows around ((k, mv))."""
    mu, mv = sample_counts(heights.shape)
    return concave_radius_of(*surface.radius_derivatives(cyl, heights, mu, mv, rows=rows))
