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

from . import checks_geometry, surface

# The projection aims this share of the tool's radius wider than the tool: smoothing
# stops at the first pass that clears it, and the spline between samples curves a little
# more than the samples show.
RADIUS_MARGIN = 0.02

# Each pass moves a flagged node this share of the way to its four neighbours' mean:
# half removes a one-node ripple in a pass and changes broad shape slowly.
SMOOTHING = 0.5

# A cubic B-spline node shapes the surface two cells to each side: flagged samples mark
# the nodes within this many cells.
SUPPORT_CELLS = 2


def concave_radius(cyl: surface.Cylinder, heights: np.ndarray) -> np.ndarray:
    """(mu, mv) mm: the smallest concave radius of curvature on the check's samples
    (``checks_geometry.SAMPLES``), inf where the surface is convex."""
    mu, mv = checks_geometry.sample_counts(heights.shape)
    return checks_geometry.concave_radius_of(*surface.radius_derivatives(cyl, heights, mu, mv))


def limit_concavity(cyl: surface.Cylinder, heights: np.ndarray, tool_radius_mm: float,
                    passes: int = 400) -> tuple[np.ndarray, float]:
    """Smooth every hollow tighter than ``tool_radius_mm`` until a ball of that radius
    reaches its bottom.  Returns (heights (nu, nv) mm, smallest concave radius mm).

    Only the nodes that shape a too-tight hollow move (a Laplacian step towards their
    neighbours, periodic around, one-sided at the caps), so detail elsewhere is kept.
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
    for _ in range(passes):
        tight = radius < goal
        if not tight.any():
            break
        flagged = np.zeros((nu, nv), bool)
        rows, cols = np.nonzero(tight)
        flagged[node_u[rows], node_z[cols]] = True
        flagged = maximum_filter(flagged, size=size, mode=("wrap", "nearest"))
        vertical = np.zeros_like(heights)
        vertical[:, :-1] += heights[:, 1:]
        vertical[:, 1:] += heights[:, :-1]
        mean = (np.roll(heights, 1, 0) + np.roll(heights, -1, 0) + vertical) / neighbours
        heights = np.where(flagged, heights + SMOOTHING * (mean - heights), heights)
        radius = concave_radius(cyl, heights)
    return heights, float(radius.min())
