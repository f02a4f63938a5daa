"""The panel's relief from optimal transport: the classic collimated caustic design.

Collimated light crosses the flat back face unbent, so the light each relief node
passes is fixed: the same for every node (the beam is uniform), leaving the glass along
+y.  Design:

1. Entropic OT (``ot``) from the uniform beam on the node grid to the target image on
   the wall, both in wall coordinates (mm, x across and z up): with collimated light
   and a quadratic cost the map is the gradient of a convex function, like the
   deflection field of a refracting surface, so it integrates with little residual.
2. Snell's law gives the relief normal that sends each node's light to its target
   point; least squares integrates the normals into the relief.  A few rounds move the
   nodes' points with the relief (the wall is at a finite distance).
3. Corrections: the spline's exact normals at the nodes refract the light somewhere a
   little off (least-squares residual, slope clamp); the aim is pushed past the miss.
"""

from __future__ import annotations

import warnings
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from .. import ot
from ..limits import SLOPE_MARGIN_DEG
from ..room import Wall
from ..transport import snell_normals
from . import geometry as panel

# The beam's direction inside the glass: collimated, at normal incidence on the back face.
AXIS = np.array([0.0, 1.0, 0.0])

# Source nodes per axis of the transport problem, at most.  The map is only as sharp as
# the target (64 px wide at most in init) and smooth, so a finer grid of nodes gets it
# interpolated: the transport's cost grows with the product of both grids' sizes.
OT_NODES = 65


def beam_mass(nx: int, nz: int) -> np.ndarray:
    """(nx, nz) share of the uniform beam each node carries: its cell of the node grid
    (edge nodes half a cell, corner nodes a quarter)."""
    wx = np.ones(nx)
    wz = np.ones(nz)
    wx[[0, -1]] = wz[[0, -1]] = 0.5
    m = np.outer(wx, wz)
    return m / m.sum()


def target_map(shape: panel.PanelShape, wall: Wall, target: np.ndarray, grid: tuple[int, int],
               blur_px: float = 1.0) -> tuple[np.ndarray, float]:
    """Where each node's light should land on the wall.

    target (rows, cols) non-negative luminance on the wall's rectangle; grid (nx, nz)
    nodes.  Returns ((nx, nz, 3) mm points on the wall plane, OT marginal error).
    The entropic blur is ``blur_px`` target pixels: sharp, yet smooth enough to integrate.
    """
    from scipy.interpolate import RectBivariateSpline

    nx, nz = grid
    rows, cols = target.shape
    sx, sz = min(nx, OT_NODES), min(nz, OT_NODES)
    x = shape.node_x(sx)
    z = shape.node_z(sz)
    a = (np.arange(cols) + 0.5) / cols
    b = (np.arange(rows) + 0.5) / rows
    tx = wall.origin[0] + a * wall.right[0]  # columns along x (the wall's right axis is +x)
    tz = wall.origin[2] + b * wall.down[2]   # rows down the wall
    scale = wall.width_mm
    # The barycentric map takes logs of the coordinates: shift both sides alike (the
    # cost only sees differences) so every coordinate is at least 1.
    off_x = min(x.min(), tx.min()) / scale - 1.0
    off_z = min(z.min(), tz.min()) / scale - 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # log(0) for black cells is meant
        mx, mz, err = ot.barycentric_map(beam_mass(sx, sz), target.T, x / scale - off_x, z / scale - off_z,
                                            tx / scale - off_x, tz / scale - off_z,
                                            (blur_px / cols) ** 2)
    if (sx, sz) != (nx, nz):
        mx, mz = (RectBivariateSpline(x, z, m)(shape.node_x(nx), shape.node_z(nz)) for m in (mx, mz))
    goal = np.stack([(mx + off_x) * scale, np.full((nx, nz), wall.origin[1]), (mz + off_z) * scale], axis=-1)
    return goal, err


def refracted(normals: np.ndarray, ior: float) -> np.ndarray:
    """(..., 3) unit directions of the beam (along ``AXIS`` in the glass) after the
    relief with outward unit ``normals`` (..., 3).  Total internal reflection: NaN."""
    cos_i = normals @ AXIS
    sin2_t = ior**2 * (1.0 - cos_i**2)
    with np.errstate(invalid="ignore"):
        cos_t = np.sqrt(1.0 - sin2_t)
    return ior * AXIS + (cos_t - ior * cos_i)[..., None] * normals


def spline_normals(shape: panel.PanelShape, heights: np.ndarray) -> np.ndarray:
    """(nx, nz, 3) outward unit normals of the relief spline at its nodes."""
    nx, nz = heights.shape
    gx = panel.sample(shape, heights, nx, nz, dx=1)
    gz = panel.sample(shape, heights, nx, nz, dz=1)
    n = np.stack([-gx, np.ones_like(gx), -gz], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@lru_cache(maxsize=4)
def _normal_equations(nx: int, nz: int, smoothness: float):
    """(first differences along x, along z, LU of the normal equations) of the
    integration on an (nx, nz) grid: the same for every round, so factorized once."""
    idx = np.arange(nx * nz).reshape(nx, nz)

    def stencil(centre, offsets, weights):
        m = len(centre)
        cols = np.stack([centre + o for o in offsets], 1).ravel()
        return sp.csr_matrix((np.tile(weights, m), (np.repeat(np.arange(m), len(offsets)), cols)),
                             shape=(m, nx * nz))

    d_x = stencil(idx[:-1].ravel(), (nz, 0), (1.0, -1.0))
    d_z = stencil(idx[:, :-1].ravel(), (1, 0), (1.0, -1.0))
    l_x = stencil(idx[1:-1].ravel(), (-nz, 0, nz), (1.0, -2.0, 1.0))
    l_z = stencil(idx[:, 1:-1].ravel(), (-1, 0, 1), (1.0, -2.0, 1.0))
    lhs = d_x.T @ d_x + d_z.T @ d_z + smoothness * (l_x.T @ l_x + l_z.T @ l_z) + sp.identity(nx * nz) * 1e-9
    return d_x, d_z, splu(lhs.tocsc())


def integrate_gradient(gx: np.ndarray, gz: np.ndarray, dx_mm: float, dz_mm: float,
                       smoothness: float) -> np.ndarray:
    """The (nx, nz) mm heights whose differences best match the gradient (gx, gz)
    (dimensionless, (nx, nz) each at the nodes), in the least-squares sense.

    ``smoothness`` weighs second differences.  The free constant centres the heights
    (max + min = 0).
    """
    nx, nz = gx.shape
    d_x, d_z, lu = _normal_equations(nx, nz, float(smoothness))
    v_x = (dx_mm * 0.5 * (gx[1:] + gx[:-1])).ravel()
    v_z = (dz_mm * 0.5 * (gz[:, 1:] + gz[:, :-1])).ravel()
    h = lu.solve(d_x.T @ v_x + d_z.T @ v_z).reshape(nx, nz)
    return h - 0.5 * (h.max() + h.min())


def design(shape: panel.PanelShape, wall: Wall, target: np.ndarray, ior: float, grid: tuple[int, int],
           rounds: int, corrections: int, smoothness: float, max_relief_mm: float, max_tilt_deg: float,
           log=print) -> tuple[np.ndarray, dict]:
    """The relief heightmap ((nx, nz) mm at the nodes) and figures about its design.

    target (rows, cols) linear luminance on ``wall``.  ``rounds`` position/normal
    iterations per pass, then ``corrections`` passes re-aiming by the spline's own
    normals.  Slopes are clamped to ``max_tilt_deg`` (less a margin) and offsets to
    ``max_relief_mm`` both ways.
    """
    nx, nz = grid
    goal, err = target_map(shape, wall, np.asarray(target, np.float64), grid)
    dx = shape.width_mm / (nx - 1)
    dz = shape.height_mm / (nz - 1)
    limit = np.tan(np.radians(max_tilt_deg - SLOPE_MARGIN_DEG))
    heights = np.zeros(grid)
    aim_offset = np.zeros((nx, nz, 3))
    errors = []
    for correction in range(corrections + 1):
        for _ in range(rounds):
            pts = panel.points(shape, heights)
            wanted = goal - pts
            wanted /= np.linalg.norm(wanted, axis=-1, keepdims=True)
            d_out = wanted + aim_offset
            d_out /= np.linalg.norm(d_out, axis=-1, keepdims=True)
            n = snell_normals(AXIS, d_out, ior)
            gx, gz = -n[..., 0] / n[..., 1], -n[..., 2] / n[..., 1]
            # Beyond the slope limit the light misses its spot, but the panel stays makeable.
            scale = np.minimum(1.0, limit / np.maximum(np.hypot(gx, gz), 1e-12))
            heights = np.clip(integrate_gradient(gx * scale, gz * scale, dx, dz, smoothness),
                              -max_relief_mm, max_relief_mm)
        actual = refracted(spline_normals(shape, heights), ior)
        miss = np.degrees(np.arccos(np.clip(np.sum(wanted * actual, -1), -1.0, 1.0)))
        errors.append(float(np.nanmean(miss)))
        log(f"panel transport: pass {correction + 1}/{corrections + 1}: relief {heights.min():.2f} to "
            f"{heights.max():.2f} mm, mean aim error {errors[-1]:.3f}°")
        aim_offset = aim_offset + np.nan_to_num(wanted - actual)
    fine = panel.fine_shape(nx, nz, 4)
    figures = {"ot_marginal_error": {wall.name: err}, "aim_error_deg": errors, "grid": list(grid),
               "offset_min_mm": float(heights.min()), "offset_max_mm": float(heights.max()),
               "max_tilt_deg": float(panel.tilt_deg(shape, heights, *fine).max())}
    return heights, figures
