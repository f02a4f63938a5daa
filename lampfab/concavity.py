"""Hollows a ball-end tool can reach: the outer surface's concave curvature, limited.

A ball-end mill of radius R leaves material at the bottom of any hollow whose radius of
curvature is below R (the ``tool_radius`` check measures this).  ``limit_concavity``
smooths the heightmap where such hollows are, on the very samples the check reads, so
the design stays a surface the shop can cut instead of failing the check afterwards.

Units: mm; heights (nu, nv) are the spline's node offsets from the cylinder.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter

from . import surface
from .curvature import concave_radius, fundamental_forms

# The projection aims this share of the tool's radius wider than the tool: smoothing
# stops at the first pass that clears it, and the spline between samples curves a little
# more than the samples show.
RADIUS_MARGIN = 0.02

# Each pass moves the nodes near a too-tight hollow part of the way to their four
# neighbours' mean: as far as the tightest hollow each shapes is too tight (goal / radius
# - 1), plus RATE_FLOOR so that the last passes still move, at most SMOOTHING (half
# removes a one-node ripple in a pass).
# A fixed half-way step smoothed every hollow's flanks as hard as its bottom, and the
# refinement's 40 steps widened the milled apple's seam valleys from ~6° of u (the
# transport's) to ~9°: its light sweeps across the black there.  Measured on the milled
# apple (bench/RESULTS.md, "Hollows opened no wider than the tool needs").
SMOOTHING = 0.5
RATE_FLOOR = 0.2

# A cubic B-spline node shapes the surface two cells to each side: flagged samples mark
# the nodes within this many cells.
SUPPORT_CELLS = 2

# The interpolating spline's response to one node's change falls by 2 - sqrt(3) ~ 0.27
# per node: beyond this many nodes from the nodes a pass moved it is below 1e-7 of the
# change, so a pass measures the hollows again only there (the passes took half of the
# milled apple's optimize when they measured all of it).  The result is measured whole.
REMEASURE_NODES = 12


def limit_concavity(cyl: surface.Cylinder, heights: np.ndarray, tool_radius_mm: float,
                    passes: int = 400) -> tuple[np.ndarray, float]:
    """Smooth every hollow tighter than ``tool_radius_mm`` until a ball of that radius
    reaches its bottom.  Returns (heights (nu, nv) mm, smallest concave radius mm).

    Only the nodes that shape a too-tight hollow move (a Laplacian step towards their
    neighbours as long as the hollow is too tight, periodic around, one-sided at the
    caps), so detail elsewhere is kept.
    With ``tool_radius_mm`` 0 (a print) the heights are returned as they are."""
    heights = np.asarray(heights, np.float64)
    radius = concave_radius(cyl, heights)
    if tool_radius_mm <= 0:
        return heights, float(radius.min())
    goal = tool_radius_mm * (1.0 + RADIUS_MARGIN)
    nu, nv = heights.shape
    mu, mv = radius.shape
    node_u = np.arange(mu) * nu // mu
    node_z = np.rint(np.arange(mv) * (nv - 1) / (mv - 1)).astype(int)
    size = 2 * SUPPORT_CELLS + 1
    neighbours = np.full(nv, 4.0)
    neighbours[[0, -1]] = 3.0  # the cap rows have one neighbour up or down
    moved = False
    for _ in range(passes):
        tight = radius < goal
        if not tight.any():
            break
        too_tight = np.zeros((nu, nv))
        rows, cols = np.nonzero(tight)
        np.maximum.at(too_tight, (node_u[rows], node_z[cols]), goal / radius[rows, cols] - 1.0)
        too_tight = maximum_filter(too_tight, size=size, mode=("wrap", "nearest"))
        rate = np.where(too_tight > 0, np.minimum(SMOOTHING, too_tight + RATE_FLOOR), 0.0)
        vertical = np.zeros_like(heights)
        vertical[:, :-1] += heights[:, 1:]
        vertical[:, 1:] += heights[:, :-1]
        mean = (np.roll(heights, 1, 0) + np.roll(heights, -1, 0) + vertical) / neighbours
        heights = heights + rate * (mean - heights)
        moved = True
        near_moved = maximum_filter((rate > 0).any(axis=1), size=2 * REMEASURE_NODES + 1, mode="wrap")
        rows = np.flatnonzero(near_moved[node_u])
        radius[rows] = concave_radius(cyl, heights, rows)
    if moved:  # the passes measured only near what they moved
        radius = concave_radius(cyl, heights)
    return heights, float(radius.min())


def hollow_penalty(cyl: surface.Cylinder, heights: np.ndarray, max_curvature: float,
                   samples_per_cell: int = 2) -> tuple[float, np.ndarray]:
    """Mean squared excess of the hollow normal curvature along u and along z over
    ``max_curvature`` (1/mm), in units of it, on a grid finer than the nodes; and its
    gradient on the (nu, nv) nodes (per mm).

    Keeps the refinement's steps from cutting hollows the projection must then open
    again (``limit_concavity``).  The gradient keeps the second-derivative terms only,
    which dominate where a hollow is tight (as the transport fit's Jacobian does): a
    descent direction, not the exact gradient."""
    nu, nv = heights.shape
    mu, mv = surface.fine_shape(nu, nv, samples_per_cell)
    derivatives = surface.radius_derivatives(cyl, heights, mu, mv, order=2)
    r, r_u, r_z = derivatives[:3]
    E, _, G, L, _, N = fundamental_forms(*derivatives)
    n_len = np.sqrt(r**2 + r_u**2 + (r * r_z) ** 2)
    excess_u = np.maximum(L / E - max_curvature, 0.0) / max_curvature
    excess_z = np.maximum(N / G - max_curvature, 0.0) / max_curvature
    n = excess_u.size
    penalty = float(np.sum(excess_u**2 + excess_z**2) / n)
    # d(L/E)/d r_uu = r / (n_len E), d(N/G)/d r_zz = r / (n_len G).
    d_uu = 2 * excess_u / (max_curvature * n) * r / (n_len * E)
    d_zz = 2 * excess_z / (max_curvature * n) * r / (n_len * G)
    creased = cyl.creased
    grad = (surface.u_matrix(nu, mu, 2, creased).T @ d_uu @ surface.open_matrix(nv, mv)
            + surface.u_matrix(nu, mu, 0, creased).T @ d_zz @ surface.open_matrix(nv, mv, 2) / cyl.height_mm**2)
    return penalty, grad
