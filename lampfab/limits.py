"""The fabrication limits the design obeys, and the projection of a surface under them.

``Limits`` gathers what a lens may do from the design and fabrication profiles: how far
the outer surface may leave the plain cylinder, how steeply it may tilt, how far it may
face down past vertical (a print) and how tight a hollow the ball-end tool reaches (a
mill).  The transport fit, the refinement's penalties and projection, and the checks
read them from here.  ``limit_shape`` projects a heightmap under them: slopes and
overhangs (``limit_slopes``), hollows (``concavity.limit_concavity``).

Units: mm, degrees where a name says ``deg``; heights (nu, nv) are the spline's node
offsets from the cylinder.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from . import concavity, surface
from .curvature import cell_samples
from .profile import Design, Fabrication

# Printed upright, a surface leaning more than this past vertical (i.e. closer than 45 deg
# to horizontal) faces down steeply enough to need supports.  Formlabs' own figure for
# unsupported overhangs is >= 19 deg from level but only for overhangs <= 1 mm long
# (as quoted by SLA service design guides); the lens's overhangs run for centimetres and
# a support scar on an optical surface is a defect, so the common 45 deg rule is used.
# A rule of the upright print, not a profile field: the design obeys it too.
OVERHANG_DEG = 45.0

# The slope projection aims this far under the limit.  The fabrication check samples the
# spline at points the projection samples too, so it passes without the margin; the STL's
# facets and the STEP's refitted B-spline lie between those samples.
SLOPE_MARGIN_DEG = 0.2

# Where the spline overshoots a limit, the slope projection cuts the steep edges around
# that place from their own slope, not from their clamp: edges within this much of their
# clamp count as steep.  An overshoot often sits where slopes along u and z add up to the
# tilt, or where the spline bends past its node-to-node slopes, with every edge well under
# its clamp; tightening the clamps 0.5° a pass from the limit took ~20 passes to reach
# them (the 3-axis milled apple: 23.6 passes per call, 3.8 this way).  Cutting every edge
# around an overshoot instead moved the surface 46 % further than that old rule, the
# edges within 20° 35 %, within 10° 19 % (bench/RESULTS.md, "The slope projection in a
# few passes").  Where the place overshoots again after its clamps were cut once, every
# edge around it is cut from its own slope: at a creased seam the spline's end condition
# bends it past the limit with the edges 10° and more under their clamps, which took the
# horse's fine level 29-50 passes a call (4 s a step); this way at most 7, with the surface
# moved about as far (bench/RESULTS.md, "The slope projection where it stalled").
STEEP_EDGE_DEG = 10.0

# The least a clamp tightens per pass where the spline still overshoots: with a quarter
# degree the projection moved the surface 4 % less than the old rule, with half a degree
# 19 % more, in about as many passes.
CLAMP_STEP_DEG = 0.25

# Rounds of hollow smoothing and slope projection in turn (``limit_shape``).  On every lens
# measured the first round left both within their limits.
SHAPE_ROUNDS = 3


def overhang_limit_deg(fab: Fabrication) -> float | None:
    """How far the outer surface may face down past vertical (a print, built in layers), or
    None (a milled or ground part has no overhangs)."""
    return OVERHANG_DEG if fab.process == "sla" else None


@dataclass(frozen=True)
class Limits:
    """What the outer surface may do: ``max_offset_mm`` from the plain cylinder either
    way, ``max_slope_deg`` tilt against the radial direction, ``max_overhang_deg`` past
    vertical facing down (None: no overhang rule), hollows no tighter than
    ``tool_radius_mm`` (0: no tool).  ``steepest_slope_deg``: how far a design whose
    light cannot land under ``max_slope_deg`` may steepen its slopes (None: no further)."""
    max_offset_mm: float
    max_slope_deg: float
    max_overhang_deg: float | None = None
    tool_radius_mm: float = 0.0
    steepest_slope_deg: float | None = None

    @staticmethod
    def of(design: Design, fab: Fabrication) -> "Limits":
        """The lamp's limits from its design and fabrication profiles: slopes under the
        profile's preferred slope, steepened (``steepened``) up to its ``max_slope_deg``."""
        preferred = min(fab.preferred_slope_deg, fab.max_slope_deg)
        steepest = fab.max_slope_deg if fab.max_slope_deg > preferred else None
        return Limits(design.lens.max_offset_mm, preferred, overhang_limit_deg(fab), fab.tool_radius_mm, steepest)

    def steepened(self) -> "Limits":
        """These limits with slopes up to ``steepest_slope_deg``."""
        return self.with_slope(self.steepest_slope_deg)

    def with_slope(self, max_slope_deg: float) -> "Limits":
        """These limits with slopes up to ``max_slope_deg`` and no further (the limit a
        first design chose, which the refinement keeps)."""
        return dataclasses.replace(self, max_slope_deg=max_slope_deg, steepest_slope_deg=None)

    def project(self, cyl: surface.Cylinder, heights: np.ndarray) -> np.ndarray:
        """(nu, nv) mm ``heights`` within the offset bound and ``limit_shape``'s limits."""
        heights = np.clip(heights, -self.max_offset_mm, self.max_offset_mm)
        heights, _ = limit_shape(cyl, heights, self.max_slope_deg, self.max_overhang_deg, self.tool_radius_mm)
        return np.clip(heights, -self.max_offset_mm, self.max_offset_mm)


def limit_shape(cyl: surface.Cylinder, heights: np.ndarray, max_tilt_deg: float,
                max_overhang_deg: float | None = None, tool_radius_mm: float = 0.0) -> tuple[np.ndarray, float]:
    """``limit_slopes``, then ``concavity.limit_concavity`` for a ball-end tool of
    ``tool_radius_mm`` (0: none) and ``limit_slopes`` again, in turn until neither changes
    the surface: smoothing a hollow can steepen its rim, and the slope projection can make
    a new hollow.  The slopes are always projected last.
    Returns (heights (nu, nv) mm, max tilt deg)."""
    heights, max_tilt = limit_slopes(cyl, heights, max_tilt_deg, max_overhang_deg)
    if tool_radius_mm <= 0:
        return heights, max_tilt
    for _ in range(SHAPE_ROUNDS):
        smoothed, _ = concavity.limit_concavity(cyl, heights, tool_radius_mm)
        if np.array_equal(smoothed, heights):
            break
        # Smoothing leaves no hollow too tight; if the slopes hold too, both do.
        heights, max_tilt = limit_slopes(cyl, smoothed, max_tilt_deg, max_overhang_deg)
        if np.array_equal(heights, smoothed):
            break
    return heights, max_tilt


def projection_samples(grid: tuple[int, int]) -> int:
    """Samples per spline cell edge where ``limit_slopes`` measures the (nu, nv) node
    ``grid``'s surface: at every point the checks sample (a multiple of
    ``curvature.cell_samples``), and at least 4.  The spline steepens between samples (a
    creased one within the last cell before a seam): sampled as finely as the check but
    at other points, a lens the projection held to 59.8° failed the check at 60.2°."""
    k_check = cell_samples(grid)
    return k_check * -(-4 // k_check)


def limit_slopes(cyl: surface.Cylinder, heights: np.ndarray, max_tilt_deg: float,
                 max_overhang_deg: float | None = None, passes: int = 60) -> tuple[np.ndarray, float]:
    """The surface closest to ``heights`` whose spline tilts at most ``max_tilt_deg``
    against the radial direction and, with ``max_overhang_deg`` (a print), faces down at
    most that far past vertical, measured at every point the fabrication check samples
    (``projection_samples``).

    Node-to-node slopes steeper than a clamp are cut back to it, and only that
    correction is integrated (least squares), so detail elsewhere is kept.  Where the
    spline still overshoots between nodes (or at the caps and seams, where its end
    condition bends it), the clamps of the steep edges around that place (of every edge
    there, once it overshoots again) drop to the edges' own slopes less the overshoot (at
    least ``CLAMP_STEP_DEG``) per pass; elsewhere they stay just under the limit.  The
    overhang bounds how fast the radius may grow upward (atan(dr/dz), never less than the
    overhang).
    Returns (heights (nu, nv) mm, max tilt deg).
    """
    nu, nv = heights.shape
    k = projection_samples((nu, nv))
    fine = surface.fine_shape(nu, nv, k)
    # Aim a little under the limits (``SLOPE_MARGIN_DEG``).
    max_tilt_deg -= SLOPE_MARGIN_DEG
    max_rise_deg = 90.0 if max_overhang_deg is None else max_overhang_deg - SLOPE_MARGIN_DEG

    def overshoot():
        r, r_u, r_z = surface.radius_derivatives(cyl, heights, *fine, order=1)
        tan_tilt = surface.tilt_tangent(r, r_u, r_z)
        return (float(np.degrees(np.arctan(tan_tilt.max()))), _overshoot_deg(tan_tilt, max_tilt_deg),
                _overshoot_deg(r_z, max_rise_deg))

    max_tilt, over_tilt, over_rise = overshoot()
    if over_tilt.max() <= 0 and over_rise.max() <= 0:
        return heights, max_tilt
    du = 2 * np.pi / nu
    dz = cyl.height_mm / (nv - 1)
    a, b, diff, normal_eq = _edge_system(nu, nv)
    m = len(a)
    along_z = np.arange(m) >= nu * nv
    scale = np.concatenate([np.full(nu * nv, du), np.full(nu * (nv - 1), dz)])
    clamp = np.full(m, max_tilt_deg - 0.5)
    rise_clamp = np.where(along_z, min(max_rise_deg, max_tilt_deg) - 0.5, 89.0)
    start_clamp, start_rise = clamp.copy(), rise_clamp.copy()

    def edge_tangents():
        # Along u, d ln r / du = (dr/du) / r; along z, dr/dz.  Returns them and r per edge.
        r_edge = np.concatenate([np.full(nu * nv, 1.0), (cyl.radius_mm + heights[:, 1:]).ravel()])
        return diff @ np.log(cyl.radius_mm + heights).ravel() / scale * r_edge, r_edge

    tangent, r_edge = edge_tangents()
    for _ in range(passes):
        limit = np.tan(np.radians(clamp))
        upper = np.minimum(limit, np.tan(np.radians(rise_clamp)))
        excess = np.maximum(tangent - upper, 0.0) + np.minimum(tangent + limit, 0.0)
        delta = normal_eq.solve(diff.T @ (-excess / r_edge * scale))
        heights = (cyl.radius_mm + heights) * np.exp(delta.reshape(nu, nv) - delta.mean()) - cyl.radius_mm
        max_tilt, over_tilt, over_rise = overshoot()
        if over_tilt.max() <= 0 and over_rise.max() <= 0:
            break
        tangent, r_edge = edge_tangents()
        _tighten(clamp, start_clamp, _around_nodes_max(over_tilt, k).ravel(), np.abs(tangent), a, b)
        over_rise = np.where(np.isfinite(over_rise), over_rise, -1.0)
        _tighten(rise_clamp, start_rise, _around_nodes_max(over_rise, k).ravel(), tangent, a, b)
        rise_clamp[~along_z] = 89.0
    return heights, max_tilt


def _tighten(clamps: np.ndarray, start: np.ndarray, over: np.ndarray, edge_tangent: np.ndarray,
             a: np.ndarray, b: np.ndarray) -> None:
    """Tighten, in place, the clamps (m,) deg of the edges (nodes ``a``, ``b`` (m,)) around
    nodes whose neighbourhood overshoots its limit by ``over`` (n,) deg (<= 0: not at
    all): the steep edges there, and every edge there whose clamp is already under its
    ``start`` (m,) deg (the place overshoots again after a cut), from their own slopes
    (``edge_tangent`` (m,), tan), the others from their clamps; each by the overshoot, at
    least ``CLAMP_STEP_DEG`` (``STEEP_EDGE_DEG`` says why)."""
    over_edge = np.maximum(over[a], over[b])
    hit = np.flatnonzero(over_edge > 0)
    # The edges' slopes (deg) only there: arctan for the few, not every edge.
    edge_deg = np.degrees(np.arctan(edge_tangent[hit]))
    # An edge sloping the other way (a rise clamp's edge facing up) is not cut from its
    # slope, and no clamp falls below 0°: a negative overhang clamp would demand that the
    # surface face up, and on a 32 x 9 grid such clamps drove the radius to 0.
    steep = (edge_deg > clamps[hit] - STEEP_EDGE_DEG) | ((clamps[hit] < start[hit]) & (edge_deg > 0))
    clamps[hit[steep]] = np.minimum(clamps[hit[steep]], edge_deg[steep])
    clamps[hit] = np.maximum(clamps[hit] - np.maximum(CLAMP_STEP_DEG, over_edge[hit]), 0.0)


def _overshoot_deg(tangent: np.ndarray, limit_deg: float) -> np.ndarray:
    """How far atan(tangent) exceeds ``limit_deg`` (deg) where it does, -1 elsewhere (only
    the overshoots count): arctan for the few samples near the limit, not for millions."""
    over = np.full(tangent.shape, -1.0)
    # A hair under the limit's tangent, so that rounding cannot drop a sample that overshoots.
    near = tangent > np.tan(np.radians(limit_deg)) * (1.0 - 1e-9)
    over[near] = np.degrees(np.arctan(tangent[near])) - limit_deg
    return over


def _around_nodes_max(field: np.ndarray, k: int) -> np.ndarray:
    """(nu, nv): the largest value of ``field`` (nu*k, (nv-1)*k + 1) samples, k per node
    cell, within one cell of each node (periodic around u, clipped at the ends of z).

    ``maximum_filter(field, 2k + 1, mode=("wrap", "nearest"))[::k, ::k]`` without
    filtering every sample: from the maxima of the cells on either side of each node and
    the sample one cell beyond it."""
    mu, mv = field.shape
    nu, nv = mu // k, (mv - 1) // k + 1
    cells = field.reshape(nu, k, mv).max(axis=1)            # cell i: samples i*k .. i*k + k - 1
    node_rows = field[::k]
    around_u = np.maximum(np.maximum(np.roll(cells, 1, axis=0), cells), np.roll(node_rows, -1, axis=0))
    cells = around_u[:, :-1].reshape(nu, nv - 1, k).max(axis=2)
    out = around_u[:, ::k].copy()                           # the node's own sample
    out[:, 1:] = np.maximum(out[:, 1:], cells)              # the cell below it
    out[:, :-1] = np.maximum(np.maximum(out[:, :-1], cells), around_u[:, k::k])  # the cell above, its top sample
    return out


@lru_cache(maxsize=8)
def _edge_system(nu: int, nv: int):
    """The node grid's edges for ``limit_slopes``: (first nodes (m,), second nodes (m,),
    differences along them (m, nu*nv), a solver of their normal equations).  Edges run
    around (periodic) then up.  The same for every pass and every call on a grid, so
    built once."""
    import scipy.sparse as sp

    idx = np.arange(nu * nv).reshape(nu, nv)
    a = np.concatenate([idx.ravel(), idx[:, 1:].ravel()])
    b = np.concatenate([np.roll(idx, 1, axis=0).ravel(), idx[:, :-1].ravel()])
    m = len(a)
    diff = sp.csr_matrix((np.concatenate([np.ones(m), -np.ones(m)]),
                          (np.concatenate([np.arange(m)] * 2), np.concatenate([a, b]))), shape=(m, nu * nv))
    return a, b, diff, _GridLaplacian(nu, nv)


class _GridLaplacian:
    """Solves (diff.T @ diff + 1e-9 I) x = rhs for ``_edge_system``'s edges: a ring's
    Laplacian around (periodic) plus a path's up, which the Fourier transform around and
    the cosine transform (DCT-II) up diagonalize.  Agrees with a sparse LU to rounding, in
    a twelfth of its time on the default grid (1.3 against 15.5 ms a solve)."""

    def __init__(self, nu: int, nv: int):
        ring = 2 - 2 * np.cos(2 * np.pi * np.arange(nu // 2 + 1) / nu)
        path = 2 - 2 * np.cos(np.pi * np.arange(nv) / nv)
        self.nu, self.nv = nu, nv
        self.eigen = ring[:, None] + path[None, :] + 1e-9

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        from scipy import fft

        spectrum = fft.rfft(fft.dct(rhs.reshape(self.nu, self.nv), type=2, norm="ortho", axis=1), axis=0)
        x = fft.idct(fft.irfft(spectrum / self.eigen, n=self.nu, axis=0), type=2, norm="ortho", axis=1)
        return x.ravel()
