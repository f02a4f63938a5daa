"""B-spline surfaces for the STEP files.

The lamp's outer surface is ONE periodic-in-u, degree-3 ``Geom_BSplineSurface`` that
interpolates the heightmap surface (``surface.py``) at ``samples_u x samples_v``
points.  Its poles are computed here (``bspline_poles``): an interpolating not-a-knot
cubic spline in v (parameter v = z in mm; with ``samples_v == nv`` this reproduces
surface.py's z spline exactly), then in u (parameter u = angle in rad) the same basis
the heightmap uses: the uniform periodic cubic (a circulant solve), or for a creased lens
one not-a-knot cubic per sector, joined by knots of multiplicity 3 (C0) at the sector
seams.  OCCT's ``GeomAPI_PointsToBSplineSurface`` is not used: its periodic
interpolation is wrong between samples near the seam (shared fabrication facts).

The lamp and the panel (``panel.brep``) share the rest: the not-a-knot cubic as a
clamped B-spline (``interpolating_cubic``), the OCCT surface from poles and knots
(``occ_surface``) and its evaluation on a grid (``evaluate``), from which each measures
how far its B-spline lies from its heightmap.  Units: mm.
"""

from __future__ import annotations

import time

import numpy as np

from .. import surface
from ..errors import GeometryError, LampfabError
from ..tolerances import BSPLINE_DEVIATION_MM


def interpolating_cubic(params: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The not-a-knot cubic through ``values`` (n, ...) at ``params`` (n,) as a clamped
    B-spline: (poles (n, ...), its distinct knots (k,), their multiplicities (k,) int)."""
    from scipy.interpolate import make_interp_spline

    n = len(params)
    spline = make_interp_spline(params, values.reshape(n, -1), k=3)
    knots, mults = np.unique(spline.t, return_counts=True)
    return spline.c.reshape(-1, *values.shape[1:]), knots, mults.astype(np.int64)


def occ_surface(poles: np.ndarray, u_knots, u_mults, v_knots, v_mults, u_periodic: bool):
    """The degree-3 OCCT ``Geom_BSplineSurface`` of (nu, nv, 3) mm ``poles``, distinct
    knots and their multiplicities in u and v; periodic in u or not, clamped in v."""
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array2OfPnt
    from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal

    nu, nv, _ = poles.shape
    arr = TColgp_Array2OfPnt(1, nu, 1, nv)
    for i in range(nu):
        for j in range(nv):
            x, y, z = poles[i, j]
            arr.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(z)))

    def reals(values):
        out = TColStd_Array1OfReal(1, len(values))
        for k, x in enumerate(values):
            out.SetValue(k + 1, float(x))
        return out

    def ints(values):
        out = TColStd_Array1OfInteger(1, len(values))
        for k, x in enumerate(values):
            out.SetValue(k + 1, int(x))
        return out

    return Geom_BSplineSurface(arr, reals(u_knots), reals(v_knots), ints(u_mults), ints(v_mults), 3, 3,
                               u_periodic, False)


def evaluate(occ, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(len(u), len(v), 3) mm: the OCCT surface ``occ`` at every (u, v) of the grid."""
    from OCP.gp import gp_Pnt

    out = np.empty((len(u), len(v), 3))
    p = gp_Pnt()
    for i, ui in enumerate(u):
        row = out[i]
        for j, vj in enumerate(v):
            occ.D0(float(ui), float(vj), p)
            row[j] = (p.X(), p.Y(), p.Z())
    return out


def bspline_poles(cyl: surface.Cylinder, heights: np.ndarray, samples_u: int,
                  samples_v: int) -> dict:
    """Poles and knots of the degree-3 B-spline through the surface samples (pure numpy).

    Samples: ``surface.points(cyl, surface.sample(cyl, heights, samples_u, samples_v))``,
    (samples_u, samples_v, 3) mm at u = 2*pi*k/samples_u, z = H*j/(samples_v - 1).
    In u the spline is periodic: the uniform cubic (smooth surface), or (creased) one
    not-a-knot cubic per sector with knots of multiplicity 3 at the seams, where it is
    C0, starting at the first seam.  Returns dict(poles (samples_u, samples_v, 3) float64
    mm, u_knots (k,) rad and u_mults (k,) int (periodic), v_knots (k,) mm and v_mults (k,)
    int (clamped), samples (samples_u, samples_v, 3) mm).
    """
    mu, mv = int(samples_u), int(samples_v)
    if mu < 8 or mv < 4 or (cyl.creased and mu % 8):
        raise LampfabError(f"STEP samples {mu} x {mv}: need at least 8 around (a multiple of 8 for a creased "
                           f"surface) and 4 up")
    pts = surface.points(cyl, surface.sample(cyl, heights, mu, mv))
    # v: not-a-knot cubic through the rows; its coefficients are clamped B-spline poles.
    coef, v_knots, v_mults = interpolating_cubic(cyl.node_z(mv), pts.transpose(1, 0, 2))
    rows = coef.transpose(1, 0, 2)
    # u: the same B-spline basis the heightmap uses, on the samples as nodes.  OCCT's
    # periodic poles start at the first knot: 0 (smooth) or the first seam (creased).
    basis = surface.u_basis(mu, cyl.creased)
    coef = np.einsum("ij,jvk->ivk", basis.coef_from_nodes, rows)
    if cyl.creased:
        first = basis.first_node(0)
        poles = np.roll(coef, -first, axis=0)
        inner = basis.local.t[4:-4]                      # one sector's interior knots on [0, 1]
        quarter = np.pi / 2
        u_knots = [np.radians(surface.SEAMS_DEG[0]) + quarter * np.concatenate([[s], s + inner]) for s in range(4)]
        u_knots = np.append(np.concatenate(u_knots), np.radians(surface.SEAMS_DEG[0]) + 2 * np.pi)
        u_mults = np.ones(len(u_knots), np.int64)
        u_mults[np.isin(np.arange(len(u_knots)), np.arange(0, len(u_knots), len(inner) + 1))] = 3
    else:
        # OCCT's uniform periodic basis gives the value at knot k as (P[k] + 4 P[k+1] + P[k+2]) / 6.
        poles = np.roll(coef, 1, axis=0)
        u_knots = np.arange(mu + 1) * (2 * np.pi / mu)
        u_mults = np.ones(mu + 1, np.int64)
    return {"poles": poles, "u_knots": u_knots, "u_mults": u_mults, "v_knots": v_knots, "v_mults": v_mults,
            "samples": pts}


def lamp_surface(fit: dict):
    """The OCCT surface of a ``bspline_poles`` fit: periodic in u, clamped in z."""
    return occ_surface(fit["poles"], fit["u_knots"], fit["u_mults"], fit["v_knots"], fit["v_mults"], True)


def deviation(cyl: surface.Cylinder, heights: np.ndarray, occ_surface, samples_u: int,
              samples_v: int) -> dict:
    """How far the B-spline is from the heightmap surface, at and between the samples (mm).

    Evaluates the OCCT surface on the doubled grid (u at samples and midpoints, v
    likewise).  ``interpolation_mm``: largest distance to the sample points;
    ``radial_mm``: largest |radius of the B-spline point - (R + s(angle, z))| at the
    points between samples (s evaluated at the B-spline point's own angle and z: the
    surface's radial error, an upper bound on the distance to the surface);
    ``parametric_mm``: largest |B(u, v) - X(u, v)| there (also an upper bound).
    """
    mu, mv = int(samples_u), int(samples_v)
    u = np.arange(2 * mu) * (np.pi / mu)
    z = np.linspace(0.0, cyl.height_mm, 2 * mv - 1)
    out = evaluate(occ_surface, u, z)
    uu, zz = np.meshgrid(u, z, indexing="ij")
    r_true = cyl.radius_mm + surface.sample(cyl, heights, 2 * mu, 2 * mv - 1)  # the grid above
    true = np.stack([r_true * np.cos(uu), r_true * np.sin(uu), zz], axis=-1)
    at_sample = np.zeros(out.shape[:2], bool)
    at_sample[::2, ::2] = True
    err = np.linalg.norm(out - true, axis=-1)
    between = out[~at_sample]
    phi = np.arctan2(between[:, 1], between[:, 0])
    radial = np.hypot(between[:, 0], between[:, 1]) - (cyl.radius_mm + surface.evaluate(cyl, heights, phi, between[:, 2]))
    k = int(np.argmax(np.abs(radial)))
    return {"interpolation_mm": float(err[at_sample].max()), "radial_mm": float(np.abs(radial).max()),
            "radial_at_mm": np.round(between[k], 3).tolist(), "parametric_mm": float(err[~at_sample].max())}


def fit_samples(cyl: surface.Cylinder, heights: np.ndarray, max_u: int, max_v: int) -> dict:
    """The B-spline through the coarsest interpolation grid, from the heightmap's own nodes
    doubling up to (max_u, max_v), that stays within ``tolerances.BSPLINE_DEVIATION_MM`` of
    the heightmap surface between its samples: a CAM program handles fewer poles faster.

    Returns dict(samples (mu, mv), fit (``bspline_poles``), surface (OCCT), deviation
    (``deviation``), seconds).  Raises GeometryError if even the finest allowed grid does
    not stay within it."""
    t0 = time.perf_counter()
    nu, nv = heights.shape
    mu, mv = nu, nv
    while True:
        mu_, mv_ = min(mu, max_u), min(mv, max_v)
        fit = bspline_poles(cyl, heights, mu_, mv_)
        occ = lamp_surface(fit)
        dev = deviation(cyl, heights, occ, mu_, mv_)
        if dev["radial_mm"] <= BSPLINE_DEVIATION_MM:
            return {"samples": (mu_, mv_), "fit": fit, "surface": occ, "deviation": dev,
                    "seconds": time.perf_counter() - t0}
        if (mu_, mv_) == (max_u, max_v) or (mu >= max_u and mv >= max_v):
            raise GeometryError(f"STEP: the B-spline through {mu_} x {mv_} samples deviates "
                                f"{dev['radial_mm'] * 1000:.2f} µm from the heightmap surface (limit "
                                f"{BSPLINE_DEVIATION_MM * 1000:g} µm); raise [export] step_samples_u / step_samples_v")
        mu, mv = 2 * mu, 2 * (mv - 1) + 1
