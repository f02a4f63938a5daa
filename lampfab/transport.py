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
from .room import SECTOR_CENTRE_DEG, SECTOR_WIDTH_DEG, Wall

# Share of the largest deflection a slope-limited surface can make that the transport
# plans with: the rest is left for the tilt that inner-layer refraction already needs.
REACH_MARGIN = 0.8

# The slope projection aims this far under the limit: the fabrication check samples
# the spline at other points than the projection does.
SLOPE_MARGIN_DEG = 0.2

# A sector follows its image's light centroid at most this far (degrees): beyond it the
# sector would face the next wall more than its own.
MAX_SECTOR_SHIFT_DEG = 30.0

# Least-squares weight of nodes whose light reaches no target (back sector, nodes
# without photons): they only follow their neighbours smoothly.
UNASSIGNED_WEIGHT = 1e-2


def node_light(cyl: surface.Cylinder, heights: np.ndarray, tessellation: int,
               inner_vertices: np.ndarray, inner_faces: np.ndarray, light_mm: np.ndarray,
               ior: float, photons: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Light passing the outer surface, binned on the heightmap nodes.

    Photons are refracted at the inner layer's facets and at the outer surface's
    facets (no Fresnel loss: only where light goes matters here).  Returns
    ((nu, nv) flux fraction per node, (nu, nv, 3) mean unit direction inside the glass,
    (nu, nv, 3) mean unit direction after leaving it), float64.
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
    d_out = refract_or_reflect(mi, d, si.n, ior, dr.full(mi.Float, 1.0, photons))
    dr.eval(valid, si.p, d, d_out)
    keep = dr.compress(valid)
    p = _np(_take(mi.Point3f, si.p, keep))
    din = _np(_take(mi.Vector3f, d, keep))
    dout = _np(_take(mi.Vector3f, d_out, keep))
    r_inner = np.hypot(inner_vertices[:, 0], inner_vertices[:, 1]).max()
    radius = np.hypot(p[:, 0], p[:, 1])
    on_outer = (radius > r_inner + 1e-3) & (p[:, 2] > 1e-3) & (p[:, 2] < cyl.height_mm - 1e-3)
    # Total internal reflection sends light back in: it reaches no wall from here.
    on_outer &= np.einsum("ij,ij->i", dout, p * [1.0, 1.0, 0.0]) > 0
    p, din, dout = p[on_outer], din[on_outer], dout[on_outer]
    iu = np.round(np.arctan2(p[:, 1], p[:, 0]) / (2 * np.pi / nu)).astype(np.int64) % nu
    iz = np.clip(np.round(p[:, 2] / cyl.height_mm * (nv - 1)).astype(np.int64), 0, nv - 1)
    cell = iu * nv + iz
    flux = np.bincount(cell, minlength=nu * nv) / photons

    def mean_direction(d):
        m = np.stack([np.bincount(cell, weights=d[:, k], minlength=nu * nv) for k in range(3)], 1)
        return (m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-12)).reshape(nu, nv, 3)

    return flux.reshape(nu, nv), mean_direction(din), mean_direction(dout)


def sector_nodes(sector_deg: tuple[float, float], nu: int) -> np.ndarray:
    """Indices of the u nodes in a sector (lo, hi) degrees, in increasing u (wrapping)."""
    lo, hi = np.radians(sector_deg)
    u = np.arange(nu) * (2 * np.pi / nu)
    rel = (u - lo) % (2 * np.pi)
    inside = np.nonzero(rel < hi - lo)[0]
    return inside[np.argsort(rel[inside])]


def sectors(walls: list[Wall], targets: list[np.ndarray], light_mm: np.ndarray,
            dump_share: float) -> dict[str, tuple[float, float]]:
    """The span of u (degrees, lo < hi) whose light each wall receives.

    A sector centred on its wall must shift its light sideways on average when the
    image's light is off-centre (a portrait lit from one side).  Every sector then
    winds the radius the same way round the lamp, and a closed surface cannot do that:
    integrating such normals costs tens of millimetres and degrees of error.  So each
    sector is centred on the angle of its image's light centroid instead (its light then
    needs no net sideways shift); neighbouring sectors meet half-way between their
    centres.  A side without a neighbouring wall reaches at least as far as the centred
    sector would: beyond it the lens sends its light on unbent (``design``), and that
    light must not land on the image's edge.
    """
    centre = {}
    for wall, target in zip(walls, targets):
        padded, (pad_r, pad_c) = _with_margin(target, dump_share)
        across, _ = _wall_angles(wall, light_mm, padded.shape[1] - 2 * pad_c, padded.shape[0] - 2 * pad_r,
                                 pad_c, pad_r)
        column_mass = padded.sum(0)
        shift = float(np.degrees(column_mass @ across / column_mass.sum()))
        shift = float(np.clip(shift, -MAX_SECTOR_SHIFT_DEG, MAX_SECTOR_SHIFT_DEG))
        right_with_u, _ = orientation(wall)
        centre[wall.name] = SECTOR_CENTRE_DEG[wall.name] + (shift if right_with_u else -shift)
    half = SECTOR_WIDTH_DEG / 2
    out = {}
    for name, c in centre.items():
        nominal = SECTOR_CENTRE_DEG[name]
        lo, hi = min(c, nominal) - half, max(c, nominal) + half
        for other, c2 in centre.items():
            gap = (SECTOR_CENTRE_DEG[other] - SECTOR_CENTRE_DEG[name]) % 360
            if gap == SECTOR_WIDTH_DEG:  # the neighbour on the high-u side
                hi = 0.5 * (c + c2 + (360 if c2 < c else 0))
            elif gap == 360 - SECTOR_WIDTH_DEG:  # the neighbour on the low-u side
                lo = 0.5 * (c + c2 - (360 if c2 > c else 0))
        out[name] = (lo, hi)
    return out


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


def _with_margin(target: np.ndarray, dump_share: float) -> tuple[np.ndarray, tuple[int, int]]:
    """The target padded with a band holding ``dump_share`` of the total mass."""
    rows, cols = target.shape
    pad_r, pad_c = max(1, rows // 6), max(1, cols // 6)
    total = target.sum()
    out = np.pad(target / total * (1.0 - dump_share), ((pad_r, pad_r), (pad_c, pad_c)))
    band = np.ones(out.shape, bool)
    band[pad_r:-pad_r, pad_c:-pad_c] = False
    out[band] = dump_share / band.sum()
    return out, (pad_r, pad_c)


def _wall_angles(wall: Wall, light_mm: np.ndarray, cols: int, rows: int, pad_c: int = 0,
                 pad_r: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Angles (rad) under which the light sees the centre lines of the wall's pixel
    columns (across) and rows (down), each increasing with the image axis; ``pad_*``
    more pixels of the same size continue the grid past each edge."""
    centre_dir = _unit(wall.centre - light_mm)
    across = _unit(wall.right - (wall.right @ centre_dir) * centre_dir)
    down = _unit(wall.down - (wall.down @ centre_dir) * centre_dir)
    a = (np.arange(-pad_c, cols + pad_c) + 0.5) / cols
    b = (np.arange(-pad_r, rows + pad_r) + 0.5) / rows
    d_a = wall.centre + (a[:, None] - 0.5) * wall.right - light_mm
    d_b = wall.centre + (b[:, None] - 0.5) * wall.down - light_mm
    return np.arctan2(d_a @ across, d_a @ centre_dir), np.arctan2(d_b @ down, d_b @ centre_dir)


def target_points(wall: Wall, flux: np.ndarray, d_plain: np.ndarray, target: np.ndarray,
                  nodes: np.ndarray, light_mm: np.ndarray, eps_final: float,
                  dump_share: float, warm: dict) -> tuple[np.ndarray, float]:
    """OT from the sector's node flux to the wall's target image, in angles.

    Both sides are laid out in the same units (radians of direction as seen from the
    light), so the quadratic cost is isotropic and the transport map is, like a
    refracting surface's deflection field, close to a gradient: the least-squares
    integration then has little curl to throw away.  flux (nu, nv), d_plain (nu, nv, 3):
    where each node's light goes through the plain cylinder; target (rows, cols).
    A band around the rectangle takes ``dump_share`` of the light: light that cannot
    reach the image with a makeable slope (a letterboxed image is narrower than its
    90° sector) is sent just past the rectangle's edge rather than into its dark parts.
    ``warm`` (wall name -> OT potentials) carries the solution from pass to pass.
    Returns ((len(nodes), nv, 3) mm target point per node, OT marginal error).
    """
    src = flux[nodes]  # (n1, nv), u increasing
    right_with_u, down_with_z = orientation(wall)
    ordered = d_plain[nodes]
    if not right_with_u:
        src, ordered = src[::-1], ordered[::-1]
    if not down_with_z:
        src, ordered = src[:, ::-1], ordered[:, ::-1]
    n1, n2 = src.shape
    target, (pad_r, pad_c) = _with_margin(target, dump_share)
    rows, cols = target.shape
    y1, y2 = _wall_angles(wall, light_mm, cols - 2 * pad_c, rows - 2 * pad_r, pad_c, pad_r)
    # The sector's own angles: across, the u spacing; down, the plain lens's exit angle
    # of each row (monotone in z), measured like the wall's.
    centre_dir = _unit(wall.centre - light_mm)
    down_axis = _unit(wall.down - (wall.down @ centre_dir) * centre_dir)
    column = ordered[n1 // 2]
    x2 = np.arctan2(column @ down_axis, column @ centre_dir)
    x2 = np.maximum.accumulate(x2)  # guard against noise in near-empty rows
    # Across: the nodes' own angles from the wall's centre direction, along the image's
    # right axis (the sector need not be centred on the wall, see ``sectors``).
    u_rel = (nodes * (2 * np.pi / len(flux)) - np.radians(SECTOR_CENTRE_DEG[wall.name]) + np.pi) % (2 * np.pi) - np.pi
    x1 = u_rel if right_with_u else -u_rel[::-1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # log(0) for black cells is meant
        ang1, ang2, err, potentials = ot.barycentric_map(
            src + 1e-9 * src.max(), target.T, x1 - y1.min() + 1.0, x2 - y2.min() + 1.0, y1 - y1.min() + 1.0,
            y2 - y2.min() + 1.0, eps_final, warm=warm.get(wall.name))
        warm[wall.name] = potentials
    a_map = np.interp(ang1 - 1.0 + y1.min(), y1, (np.arange(cols) + 0.5 - pad_c) / (cols - 2 * pad_c))
    b_map = np.interp(ang2 - 1.0 + y2.min(), y2, (np.arange(rows) + 0.5 - pad_r) / (rows - 2 * pad_r))
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
           smoothness: float, max_offset_mm: float, max_tilt_deg: float, seed: int,
           corrections: int = 3, dump_share: float = 0.2, log=print) -> tuple[np.ndarray, dict]:
    """The transport-based initial heightmap on a ``grid`` = (nu, nv) node grid.

    targets: per wall (rows, cols) linear luminance.  After ``rounds`` of
    position/normal iteration, ``corrections`` times: trace the tessellated surface,
    compare where each node's light really goes with where it should, and aim the
    normals past the error (this absorbs the least-squares residual of a field of
    normals that no surface has exactly, the slope clamp and the facets).
    Returns ((nu, nv) mm offsets, figures).  Offsets are clipped to ±max_offset_mm.
    """
    nu, nv = grid
    heights = np.zeros(grid)
    flux, d_in, d_plain = node_light(cyl, heights, tessellation, inner_vertices, inner_faces, light_mm,
                                     ior, photons, seed)
    figures = {"ot_marginal_error": {}}
    # Light that no makeable slope can bring onto a wall is left alone (it lights the
    # ceiling or floor) instead of being forced into steep, missing slopes.
    deflection = REACH_MARGIN * max_deflection_deg(ior, max_tilt_deg)
    plain_points = surface.points(cyl, heights)
    spans = sectors(walls, targets, light_mm, dump_share)
    figures["sectors_deg"] = {name: [round(lo, 2), round(hi, 2)] for name, (lo, hi) in spans.items()}
    usable = np.zeros((nu, nv), bool)
    for wall in walls:
        nodes = sector_nodes(spans[wall.name], nu)
        usable[nodes] = reachable(wall, plain_points[nodes], d_plain[nodes], deflection)
    figures["usable_node_share"] = float(usable.mean())
    u = np.arange(nu) * (2 * np.pi / nu)
    radial = np.broadcast_to(np.stack([np.cos(u), np.sin(u), np.zeros(nu)], 1)[:, None, :], (nu, nv, 3))
    aim_offset = np.zeros((nu, nv, 3))
    warm: dict = {}
    change = 0.0
    errors = []
    for correction in range(corrections + 1):
        # Where each node's light should go.  Redone every pass: as the surface moves,
        # the light each node catches moves with it.
        goal, weights = _goals(walls, targets, spans, flux, d_plain, usable, light_mm, dump_share, warm, figures)
        # Nodes that send to no wall stay a plain cylinder (radial normals): bending
        # their light anywhere useful is not asked for, and a sphere around the LED
        # would cost tens of millimetres of sag.
        unassigned = np.isnan(goal[..., 0])
        for _ in range(rounds):
            pts = surface.points(cyl, heights)
            wanted = _unit(np.where(unassigned[..., None], d_in, goal - pts))
            d_out = _unit(wanted + aim_offset)
            normals = np.where(unassigned[..., None], radial, snell_normals(d_in, d_out, ior))
            # Clipped every round: a radius at or below zero would wreck the next one.
            new = np.clip(integrate_normals(cyl, normals, heights, weights, smoothness, max_tilt_deg),
                          -max_offset_mm, max_offset_mm)
            change = float(np.abs(new - heights).max())
            heights = new
        flux, d_in, d_actual = node_light(cyl, heights, tessellation,
                                          inner_vertices, inner_faces, light_mm, ior, photons,
                                          seed + correction + 1)
        lit = (~unassigned) & (flux > 0)
        miss = np.degrees(np.arccos(np.clip(np.sum(wanted * d_actual, -1), -1, 1)))
        errors.append(float(np.average(miss[lit], weights=flux[lit])))
        log(f"transport: pass {correction + 1}/{corrections + 1}: offsets {heights.min():.2f} to "
            f"{heights.max():.2f} mm, mean aim error {errors[-1]:.2f}°")
        aim_offset = np.where(lit[..., None], aim_offset + (wanted - d_actual), aim_offset)
    clipped = float(np.mean(np.abs(heights) > max_offset_mm))
    heights, max_tilt = limit_slopes(cyl, np.clip(heights, -max_offset_mm, max_offset_mm), max_tilt_deg)
    heights = np.clip(heights, -max_offset_mm, max_offset_mm)
    figures.update(offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()),
                   clipped_fraction=clipped, last_change_mm=change, grid=list(grid),
                   aim_error_deg=errors, max_tilt_deg=max_tilt)
    return heights, figures


def max_deflection_deg(ior: float, max_tilt_deg: float) -> float:
    """How far a surface tilted at most ``max_tilt_deg`` can bend light leaving glass
    (light arriving along the radial direction)."""
    tilt = np.radians(max_tilt_deg)
    s = min(ior * np.sin(tilt), 1.0)
    return float(np.degrees(np.arcsin(s) - tilt))


def reachable(wall: Wall, points: np.ndarray, d_plain: np.ndarray, max_deflection: float) -> np.ndarray:
    """Which nodes can send their light into the wall's rectangle.

    points (..., 3) mm on the surface, d_plain (..., 3): where their light goes through
    the plain cylinder.  A node is reachable if the rectangle's nearest point is within
    ``max_deflection`` degrees of that direction.
    """
    normal = wall.normal
    denom = d_plain @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((wall.origin - points) @ normal) / denom
    hit = points + np.where(denom < 0, t, 1e6)[..., None] * d_plain
    rel = hit - wall.origin
    a = np.clip(rel @ wall.right / wall.width_mm**2, 0, 1)
    b = np.clip(rel @ wall.down / wall.height_mm**2, 0, 1)
    nearest = wall.origin + a[..., None] * wall.right + b[..., None] * wall.down
    to_nearest = _unit(nearest - points)
    angle = np.degrees(np.arccos(np.clip(np.sum(to_nearest * d_plain, -1), -1, 1)))
    return (denom < 0) & (angle <= max_deflection)


def surface_normals(cyl: surface.Cylinder, heights: np.ndarray) -> np.ndarray:
    """(nu, nv, 3) outward unit normals of the spline surface at its nodes."""
    nu, nv = heights.shape
    du = 2 * np.pi / nu
    dz = cyl.height_mm / (nv - 1)
    r = cyl.radius_mm + heights
    r_u = (np.roll(heights, -1, 0) - np.roll(heights, 1, 0)) / (2 * du)
    r_z = np.gradient(heights, dz, axis=1)
    u = np.arange(nu) * du
    e_r = np.stack([np.cos(u), np.sin(u), np.zeros(nu)], 1)[:, None, :]
    e_t = np.stack([-np.sin(u), np.cos(u), np.zeros(nu)], 1)[:, None, :]
    n = e_r - (r_u / r)[..., None] * e_t - r_z[..., None] * np.array([0.0, 0.0, 1.0])
    return _unit(n)


def limit_slopes(cyl: surface.Cylinder, heights: np.ndarray, max_tilt_deg: float,
                 passes: int = 30) -> tuple[np.ndarray, float]:
    """The surface closest to ``heights`` whose spline tilts at most ``max_tilt_deg``
    against the radial direction, measured as finely as the fabrication check does.

    Node-to-node slopes steeper than a clamp are cut back to it, and only that
    correction is integrated (least squares), so detail elsewhere is kept.  Where the
    spline still overshoots between nodes (or at the caps, where its end condition
    bends it), the clamp of the edges around that place tightens by the overshoot (at
    least half a degree) per pass; elsewhere it stays just under the limit.
    Returns (heights (nu, nv) mm, max tilt deg).
    """
    from scipy.ndimage import maximum_filter

    nu, nv = heights.shape
    k = 4
    fine = surface.fine_shape(nu, nv, k)
    # Aim a little under the limit: the check samples the spline at other points.
    max_tilt_deg -= SLOPE_MARGIN_DEG
    tilt = surface.slopes_deg(cyl, heights, *fine)[0]
    if tilt.max() <= max_tilt_deg:
        return heights, float(tilt.max())
    du = 2 * np.pi / nu
    dz = cyl.height_mm / (nv - 1)
    idx = np.arange(nu * nv).reshape(nu, nv)
    a = np.concatenate([idx.ravel(), idx[:, 1:].ravel()])
    b = np.concatenate([np.roll(idx, 1, axis=0).ravel(), idx[:, :-1].ravel()])
    m = len(a)
    diff = sp.csr_matrix((np.concatenate([np.ones(m), -np.ones(m)]),
                          (np.concatenate([np.arange(m)] * 2), np.concatenate([a, b]))), shape=(m, nu * nv))
    normal_eq = (diff.T @ diff + sp.identity(nu * nv) * 1e-9).tocsc()
    scale = np.concatenate([np.full(nu * nv, du), np.full(nu * (nv - 1), dz)])
    clamp = np.full(m, max_tilt_deg - 0.5)
    for _ in range(passes):
        # Edge slopes as tangents: along u, d ln r / du = (dr/du) / r; along z, dr/dz.
        rho = np.log(cyl.radius_mm + heights)
        edge = diff @ rho.ravel()
        r_edge = np.concatenate([np.full(nu * nv, 1.0), (cyl.radius_mm + heights[:, 1:]).ravel()])
        tangent = edge / scale * r_edge
        limit = np.tan(np.radians(clamp))
        excess = np.sign(tangent) * np.maximum(np.abs(tangent) - limit, 0.0)
        delta = spsolve(normal_eq, diff.T @ (-excess / r_edge * scale))
        heights = (cyl.radius_mm + heights) * np.exp(delta.reshape(nu, nv) - delta.mean()) - cyl.radius_mm
        tilt = surface.slopes_deg(cyl, heights, *fine)[0]
        if tilt.max() <= max_tilt_deg:
            break
        # How far each node's neighbourhood (one cell around) overshoots the limit.
        over = (maximum_filter(tilt, size=2 * k + 1, mode=("wrap", "nearest"))[::k, ::k] - max_tilt_deg).ravel()
        over_edge = np.maximum(over[a], over[b])
        clamp[over_edge > 0] -= np.maximum(0.5, over_edge[over_edge > 0])
    return heights, float(tilt.max())


def _goals(walls, targets, spans, flux, d_plain, usable, light_mm, dump_share, warm, figures):
    """Target point per node ((nu, nv, 3) mm, NaN where no wall) and least-squares weights.

    spans: each wall's sector (``sectors``); usable (nu, nv) bool: nodes whose light
    can reach their wall at all."""
    nu, nv = flux.shape
    goal = np.full((nu, nv, 3), np.nan)
    weights = np.full((nu, nv), UNASSIGNED_WEIGHT)
    # Blur of about one node spacing (rad^2): sharp, yet smooth enough to integrate.
    eps_final = (np.radians(SECTOR_WIDTH_DEG) / (nu / 4)) ** 2
    for wall, target in zip(walls, targets):
        nodes = sector_nodes(spans[wall.name], nu)
        ok = usable[nodes]
        points, err = target_points(wall, np.where(usable, flux, 0.0), d_plain, target, nodes, light_mm,
                                    eps_final, dump_share, warm)
        points[~ok] = np.nan
        goal[nodes] = points
        # Nodes matter as much as the light they carry (dim nodes near the caps would
        # otherwise demand steep slopes for little light).
        share = flux[nodes] / max(flux[nodes].mean(), 1e-300)
        weights[nodes] = np.clip(share, UNASSIGNED_WEIGHT, 1.0)
        figures["ot_marginal_error"][wall.name] = err
    return goal, weights


def _unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis (NaN rows, nodes without a goal, stay NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)
