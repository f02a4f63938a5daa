"""A first lens from optimal transport: seconds, not thousands of gradient steps.

1. Trace photons from the LED through the actual inner layer to the outer surface and
   bin them on the heightmap grid: how much light each (u, z) node receives, and from
   which direction inside the glass.
2. For each wall, transport the light of the lens sector that faces it onto the
   wall's target image (entropic OT on the grids, see ``ot``).
3. Snell's law gives the outer normal that sends each node's light to its target
   point; the normals are integrated into the radial heightmap by least squares
   (log-radius, periodic in u).  Positions and normals are iterated a few rounds since
   the walls are at a finite distance.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from . import lens, ot, surface
from .room import Wall

# Least-squares weight of nodes whose light reaches no target (back sector, nodes
# without photons): they only follow their neighbours smoothly.
UNASSIGNED_WEIGHT = 1e-2


def source_density(cyl: surface.Cylinder, heights: np.ndarray, tessellation: int,
                   inner_vertices: np.ndarray, inner_faces: np.ndarray, light_mm: np.ndarray,
                   ior: float, photons: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Light arriving at the outer surface from inside, binned on the heightmap nodes.

    Returns ((nu, nv) float64 flux fraction per node, (nu, nv, 3) float64 mean unit
    direction inside the glass).  Photons are refracted at the inner layer's facets
    (no Fresnel loss: only where light goes matters here).
    """
    import drjit as dr

    from .trace import MeshScene, _np, _take, emit, refract_or_reflect

    nu, nv = heights.shape
    verts, faces = lens.optical_mesh(cyl, heights, tessellation, inner_vertices, inner_faces)
    scene = MeshScene(verts, faces)
    mi = scene.mi
    rng = mi.PCG32(photons, dr.opaque(mi.UInt64, seed), dr.opaque(mi.UInt64, 0))
    o, d = emit(mi, light_mm, 0.0, photons, rng)
    si = scene.scene.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
    dr.eval(si.p, si.n)
    d = refract_or_reflect(mi, d, si.n, ior, dr.full(mi.Float, 1.0, photons))  # never reflect
    o = si.p + 1e-4 * d
    si = scene.scene.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
    valid = si.is_valid()
    dr.eval(valid, si.p, d)
    keep = dr.compress(valid)
    p = _np(_take(mi.Point3f, si.p, keep))
    din = _np(_take(mi.Vector3f, d, keep))
    r_inner = np.hypot(inner_vertices[:, 0], inner_vertices[:, 1]).max()
    radius = np.hypot(p[:, 0], p[:, 1])
    on_outer = (radius > r_inner + 1e-3) & (p[:, 2] > 1e-3) & (p[:, 2] < cyl.height_mm - 1e-3)
    p, din = p[on_outer], din[on_outer]
    iu = np.round(np.arctan2(p[:, 1], p[:, 0]) / (2 * np.pi / nu)).astype(np.int64) % nu
    iz = np.clip(np.round(p[:, 2] / cyl.height_mm * (nv - 1)).astype(np.int64), 0, nv - 1)
    cell = iu * nv + iz
    flux = np.bincount(cell, minlength=nu * nv) / photons
    mean_d = np.stack([np.bincount(cell, weights=din[:, k], minlength=nu * nv) for k in range(3)], 1)
    mean_d /= np.maximum(np.linalg.norm(mean_d, axis=1, keepdims=True), 1e-12)
    return flux.reshape(nu, nv), mean_d.reshape(nu, nv, 3)


def sector_nodes(wall: Wall, nu: int) -> np.ndarray:
    """Indices of the u nodes in the wall's 90° sector, in increasing u (wrapping)."""
    lo, hi = np.radians(wall.sector_deg())
    u = np.arange(nu) * (2 * np.pi / nu)
    rel = (u - lo) % (2 * np.pi)
    inside = np.nonzero(rel < hi - lo)[0]
    return inside[np.argsort(rel[inside])]


def orientation(wall: Wall) -> tuple[bool, bool]:
    """Whether the image's right axis runs with increasing u and its down axis with
    increasing z, for light leaving the lens towards this wall.

    Right: compare with the tangent e_theta at the sector centre.  Down: on a vertical
    wall higher light lands higher (down runs against z); on the floor light leaving
    higher lands farther out (along e_r).
    """
    uc = np.radians(np.mean(wall.sector_deg()))
    e_r = np.array([np.cos(uc), np.sin(uc), 0.0])
    e_t = np.array([-np.sin(uc), np.cos(uc), 0.0])
    right_with_u = float(wall.right @ e_t) > 0
    down_with_z = float(wall.down @ np.array([0.0, 0.0, 1.0]) + wall.down @ e_r) > 0
    return right_with_u, down_with_z


def target_points(wall: Wall, flux: np.ndarray, target: np.ndarray, nodes: np.ndarray,
                  eps_final: float) -> tuple[np.ndarray, float]:
    """OT from the sector's node flux to the wall's target image.

    flux: (nu, nv) per node; target: (rows, cols) desired irradiance on the wall.
    Returns ((len(nodes), nv, 3) float64 mm target point per node, OT marginal error).
    """
    src = flux[nodes]  # (n1, nv), u increasing
    right_with_u, down_with_z = orientation(wall)
    if not right_with_u:
        src = src[::-1]
    if not down_with_z:
        src = src[:, ::-1]
    n1, n2 = src.shape
    rows, cols = target.shape
    x1 = (np.arange(n1) + 0.5) / n1
    x2 = (np.arange(n2) + 0.5) / n2
    y1 = (np.arange(cols) + 0.5) / cols
    y2 = (np.arange(rows) + 0.5) / rows
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # log(0) for black cells is meant
        a_map, b_map, err = ot.barycentric_map(src + 1e-9 * src.max(), target.T, x1, x2, y1, y2,
                                               eps_final)
    if not right_with_u:
        a_map, b_map = a_map[::-1], b_map[::-1]
    if not down_with_z:
        a_map, b_map = a_map[:, ::-1], b_map[:, ::-1]
    points = wall.origin + a_map[..., None] * wall.right + b_map[..., None] * wall.down
    return points, err


def snell_normals(d_in: np.ndarray, d_out: np.ndarray, ior: float) -> np.ndarray:
    """Outward unit normals that refract d_in (in glass) into d_out (in air).

    n_glass d_in - n_air d_out is parallel to the outward normal (and never zero
    for n_glass > n_air).  (..., 3) in, (..., 3) out.
    """
    n = ior * d_in - d_out
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def integrate_normals(cyl: surface.Cylinder, normals: np.ndarray, heights: np.ndarray,
                      weights: np.ndarray, smoothness: float, max_tilt_deg: float) -> np.ndarray:
    """Radial heightmap whose surface has the given normals, in the least-squares sense.

    With rho = ln(R + h):  d rho/du = -n_theta / n_r,  d rho/dz = -n_z / (n_r (R + h)).
    normals (nu, nv, 3), heights (nu, nv) mm (current, for R + h), weights (nu, nv).
    Periodic in u; ``smoothness`` weighs second differences.  The free constant is set
    so the offsets are centred (max + min = 0).
    """
    nu, nv = heights.shape
    u = np.arange(nu) * (2 * np.pi / nu)
    e_r = np.stack([np.cos(u), np.sin(u), np.zeros(nu)], 1)[:, None, :]
    e_t = np.stack([-np.sin(u), np.cos(u), np.zeros(nu)], 1)[:, None, :]
    n_r = np.sum(normals * e_r, -1)
    n_t = np.sum(normals * e_t, -1)
    n_z = normals[..., 2]
    r = cyl.radius_mm + heights
    # Slopes beyond max_tilt_deg are clamped: that light misses its spot, but the lens
    # stays makeable and one steep node cannot drag the whole surface.
    limit = np.tan(np.radians(max_tilt_deg))
    tan_u = -n_t / np.maximum(n_r, 1e-6)
    tan_z = -n_z / np.maximum(n_r, 1e-6)
    scale = np.minimum(1.0, limit / np.maximum(np.hypot(tan_u, tan_z), 1e-12))
    g_u = tan_u * scale
    g_z = tan_z * scale / r
    du = 2 * np.pi / nu
    dz = cyl.height_mm / (nv - 1)
    idx = np.arange(nu * nv).reshape(nu, nv)
    # Vectorized assembly of first-difference equations in u (periodic) and z.
    a_u = idx.ravel()
    b_u = np.roll(idx, 1, axis=0).ravel()
    val_u = (du * 0.5 * (g_u + np.roll(g_u, 1, axis=0))).ravel()
    wt_u = np.sqrt(weights * np.roll(weights, 1, axis=0)).ravel()
    a_z = idx[:, 1:].ravel()
    b_z = idx[:, :-1].ravel()
    val_z = (dz * 0.5 * (g_z[:, 1:] + g_z[:, :-1])).ravel()
    wt_z = np.sqrt(weights[:, 1:] * weights[:, :-1]).ravel()
    a_all = np.concatenate([a_u, a_z])
    b_all = np.concatenate([b_u, b_z])
    m = len(a_all)
    d1 = sp.csr_matrix((np.concatenate([np.ones(m), -np.ones(m)]),
                        (np.concatenate([np.arange(m)] * 2), np.concatenate([a_all, b_all]))),
                       shape=(m, nu * nv))
    wd = sp.diags(np.concatenate([wt_u, wt_z]))
    rhs_all = np.concatenate([val_u, val_z])
    # Second differences for smoothness (u periodic, z interior).
    lap_u = sp.csr_matrix(
        (np.tile([1.0, -2.0, 1.0], nu * nv),
         (np.repeat(np.arange(nu * nv), 3),
          np.stack([np.roll(idx, 1, 0).ravel(), idx.ravel(), np.roll(idx, -1, 0).ravel()], 1).ravel())),
        shape=(nu * nv, nu * nv))
    inner = idx[:, 1:-1].ravel()
    lap_z = sp.csr_matrix(
        (np.tile([1.0, -2.0, 1.0], len(inner)),
         (np.repeat(np.arange(len(inner)), 3), np.stack([inner - 1, inner, inner + 1], 1).ravel())),
        shape=(len(inner), nu * nv))
    lhs = d1.T @ wd @ wd @ d1 + smoothness * (lap_u.T @ lap_u + lap_z.T @ lap_z)
    lhs = lhs + sp.identity(nu * nv) * 1e-9  # pins the free constant
    rho = spsolve(lhs.tocsc(), d1.T @ (wd @ wd @ rhs_all))
    radius = np.exp(rho.reshape(nu, nv) - rho.mean()) * cyl.radius_mm
    offsets = radius - cyl.radius_mm
    return offsets - 0.5 * (offsets.max() + offsets.min())


def design(cyl: surface.Cylinder, walls: list[Wall], targets: list[np.ndarray],
           inner_vertices: np.ndarray, inner_faces: np.ndarray, light_mm: np.ndarray,
           ior: float, grid: tuple[int, int], tessellation: int, rounds: int, photons: int,
           smoothness: float, max_offset_mm: float, max_tilt_deg: float, seed: int, log=print) -> tuple[np.ndarray, dict]:
    """The transport-based initial heightmap on a ``grid`` = (nu, nv) node grid.

    targets: per wall (rows, cols) linear luminance.  Returns ((nu, nv) mm offsets,
    figures).  Offsets are clipped to ±max_offset_mm (the clip is reported).
    """
    nu, nv = grid
    heights = np.zeros(grid)
    flux, d_in = source_density(cyl, heights, tessellation, inner_vertices, inner_faces, light_mm,
                                ior, photons, seed)
    goal = np.full((nu, nv, 3), np.nan)
    weights = np.full(grid, UNASSIGNED_WEIGHT)
    figures = {"ot_marginal_error": {}}
    eps_final = (1.0 / max(nv, 16)) ** 2
    for wall, target in zip(walls, targets):
        nodes = sector_nodes(wall, nu)
        points, err = target_points(wall, flux, target, nodes, eps_final)
        goal[nodes] = points
        # Nodes matter as much as the light they carry (dim nodes near the caps would
        # otherwise demand steep slopes for little light).
        share = flux[nodes] / max(flux[nodes].mean(), 1e-300)
        weights[nodes] = np.clip(share, UNASSIGNED_WEIGHT, 1.0)
        figures["ot_marginal_error"][wall.name] = err
    # Nodes that send to no wall stay a plain cylinder (radial normals): bending their
    # light anywhere useful is not asked for, and a sphere around the LED would cost
    # tens of millimetres of sag.
    unassigned = np.isnan(goal[..., 0])
    u = np.arange(nu) * (2 * np.pi / nu)
    radial = np.broadcast_to(np.stack([np.cos(u), np.sin(u), np.zeros(nu)], 1)[:, None, :], goal.shape)
    for k in range(rounds):
        pts = surface.points(cyl, heights)
        d_out = np.where(unassigned[..., None], d_in, goal - pts)
        d_out /= np.linalg.norm(d_out, axis=-1, keepdims=True)
        normals = np.where(unassigned[..., None], radial, snell_normals(d_in, d_out, ior))
        new = integrate_normals(cyl, normals, heights, weights, smoothness, max_tilt_deg)
        change = float(np.abs(new - heights).max())
        heights = new
        log(f"transport round {k + 1}/{rounds}: offsets {heights.min():.2f} to {heights.max():.2f} mm, "
            f"change {change:.3f} mm")
    clipped = float(np.mean(np.abs(heights) > max_offset_mm))
    heights = np.clip(heights, -max_offset_mm, max_offset_mm)
    figures.update(offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()),
                   clipped_fraction=clipped, last_change_mm=change, grid=list(grid))
    return heights, figures
