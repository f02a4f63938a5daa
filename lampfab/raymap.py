"""Ray mapping: the outer surface that lands each photon where it should.

The light inside the glass does not depend on the outer surface.  Photons leave the LED
on a stratified grid of directions (uniform on the sphere, jittered), weighted by its
beam, and refract at the inner layer's facets in float64 (``stratified_photons``).

``RayMap.fit`` then finds the heightmap whose tessellation (the STL's facets) sends
each photon to its goal on its wall: Levenberg-Marquardt on

    sum_p w_p |landing_p(h) - goal_p|^2  +  slope excess^2  +  offset excess^2  +  smoothness

``landing_p`` is where photon p lands (mm along the wall image's right and down axes)
after refracting at the facet it meets (Mitsuba finds the facet).  It depends on the
radial offsets of that facet's three corners (central differences, float64), and those
on the spline's local B-spline coefficients (``surface.UBasis``/``VBasis``), so the
normal equations are sparse.  Fresnel reflection is left out: verify traces it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from . import surface
from .limits import Limits
from .room import Wall
from .source import Source
from .tolerances import RAY_EPSILON_MM

# Radial step of the central differences (mm): float64 landing positions keep ~1e-9 mm,
# so the derivative is good to ~1e-6 relative; curvature errors are ~(1e-3)^2.
DIFF_STEP_MM = 1e-3

# The slope term aims this far under the fabrication limit: the check samples the spline
# at other points than the fit, and the final projection (limits.limit_shape) then
# has little to do.
SLOPE_MARGIN_DEG = 1.0

# Weights, relative to the landing error (mm^2 on a wall about 1 m away, photon flux
# normalized to 1).  A slope's tangent over the limit by 0.01 costs like a landing error
# of ~100 mm over the whole lens; an offset past the bound by 1 mm like ~30 mm.
SLOPE_WEIGHT = 1e8
OFFSET_WEIGHT = 1e3
# Landing positions fix the surface's slopes firmly but its level (the offset shared by a
# whole sector) hardly at all: left free, sectors drift apart until one meets the offset
# bound.  A 10 mm level costs like a 1 mm landing error.
LEVEL_WEIGHT = 1e-2

# A ball-end tool of radius R reaches the bottom of a hollow only where the surface curves
# no tighter than 1/R; the fit aims this much wider, since it charges the curvature along
# u and z (the check takes the largest principal curvature, which can lie between them).
CURVATURE_MARGIN = 1.5
# Like the slope term: a curvature over the limit by 0.01 / mm on a tenth of the lens
# costs like a landing error of ~30 mm.
CURVATURE_WEIGHT = 1e8

# Levenberg-Marquardt damping: start, and the factors after a rejected / accepted step.
DAMPING_START = 1e-2
DAMPING_UP, DAMPING_DOWN = 4.0, 3.0
DAMPING_MAX = 1e6

# Conjugate gradients solve each step to this relative residual (a step only needs to be
# roughly right: the next one corrects it); past this many iterations, a direct solve.
CG_RTOL = 1e-4
CG_MAX_ITERATIONS = 2000


@dataclass
class Photons:
    """Photons inside the glass, after the inner layer.

    origin (n, 3) mm just inside the glass; direction (n, 3) unit, in the glass;
    emitted (n, 3) unit direction leaving the LED; weight (n,) share of the emitted
    light each carries after the inner layer; stratum (n, 2) float: continuous
    (azimuth, sin elevation) grid coordinates in [0, n_azimuth) x [0, n_elevation).
    """
    origin: np.ndarray
    direction: np.ndarray
    emitted: np.ndarray
    weight: np.ndarray
    stratum: np.ndarray
    n_azimuth: int
    n_elevation: int


def fresnel_transmission(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarized transmittance (0 under total internal reflection) for incidence cosines
    ``cos_i`` (>= 0) and eta = n_transmitted / n_incident."""
    sin2_t = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    rs = ((cos_i - eta * cos_t) / (cos_i + eta * cos_t)) ** 2
    rp = ((eta * cos_i - cos_t) / (eta * cos_i + cos_t)) ** 2
    return np.where(sin2_t >= 1.0, 0.0, 1.0 - 0.5 * (rs + rp))


def refract(direction: np.ndarray, normal: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Snell's law: unit directions (k, 3) through interfaces whose unit normals (k, 3)
    point the way the light goes, eta = n_after / n_before.  Returns (refracted unit
    directions, cos of incidence, True where the light is totally reflected instead)."""
    cos_i = np.einsum("ij,ij->i", direction, normal)
    sin2_t = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    out = direction / eta + (cos_t - cos_i / eta)[:, None] * normal
    return out / np.linalg.norm(out, axis=1, keepdims=True), cos_i, sin2_t >= 1.0


def stratified_photons(inner_vertices: np.ndarray, inner_faces: np.ndarray, source: Source,
                       ior: float, n_azimuth: int, n_elevation: int, seed: int) -> Photons:
    """One photon per cell of an (azimuth, sin elevation) grid, jittered inside its cell,
    refracted into the glass at the inner layer: inner_vertices (n, 3) mm, inner_faces
    (m, 3) int wound outward (away from the light), ``source`` the LED (its point light,
    ``Source.origins``, and beam; below a flat LED's horizon, weightless photons)."""
    from .trace import first_hits

    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n_azimuth), np.arange(n_elevation), indexing="ij")
    a = (i + rng.random(i.shape)).ravel()
    s = (j + rng.random(j.shape)).ravel()
    phi = 2 * np.pi * a / n_azimuth
    sin_el = -1.0 + 2.0 * s / n_elevation
    cos_el = np.sqrt(1.0 - sin_el**2)
    emitted = np.stack([cos_el * np.cos(phi), cos_el * np.sin(phi), sin_el], axis=1)
    start = source.origins(emitted)
    valid, prim, t = first_hits(inner_vertices, inner_faces, start, emitted)
    if valid.mean() < 0.99:  # more than the few that slip between facets (below)
        raise ValueError("photons leave the inner layer without crossing it: the light is not inside it")
    # A few rays slip between two facets (float32 intersection is not watertight): dropped.
    emitted, start, prim, t = emitted[valid], start[valid], prim[valid], t[valid]
    a, s = a[valid], s[valid]
    tri = inner_vertices[inner_faces[prim]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    facing = np.einsum("ij,ij->i", emitted, normal) >= 0
    along = np.where(facing[:, None], normal, -normal)  # the facet normal on the glass side
    inside, cos_i, _ = refract(emitted, along, ior)
    transmitted = fresnel_transmission(cos_i, ior) * source.intensity(emitted)
    origin = start + t[:, None] * emitted + RAY_EPSILON_MM * inside
    return Photons(origin, inside, emitted, transmitted / len(valid), np.stack([a, s], axis=1),
                   n_azimuth, n_elevation)


class WallFrames:
    """The walls' planes as arrays, indexed by wall number."""

    def __init__(self, walls: list[Wall]):
        self.origin = np.array([w.origin for w in walls])
        self.right = np.array([w.right / w.width_mm for w in walls])
        self.down = np.array([w.down / w.height_mm for w in walls])
        self.normal = np.array([w.normal for w in walls])


def landing(origin: np.ndarray, direction: np.ndarray, v0: np.ndarray, v1: np.ndarray, v2: np.ndarray,
            ior: float, frames: WallFrames, wall: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where photons in the glass land after leaving through the facets (v0, v1, v2).

    All (k, 3) mm; the facets are wound outward.  ``wall`` (k,) int: the wall each
    photon is meant for.  Returns ((k, 2) mm along the wall image's right and down axes
    from its top-left corner, (k,) bool: the photon leaves (no total internal
    reflection) towards the wall's plane)."""
    normal = np.cross(v1 - v0, v2 - v0)
    t = np.einsum("ij,ij->i", v0 - origin, normal) / np.einsum("ij,ij->i", direction, normal)
    p = origin + t[:, None] * direction
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    out, cos_i, reflected = refract(direction, normal, 1.0 / ior)
    n_w = frames.normal[wall]
    denom = np.einsum("ij,ij->i", out, n_w)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_w = np.einsum("ij,ij->i", frames.origin[wall] - p, n_w) / denom
    rel = p + t_w[:, None] * out - frames.origin[wall]
    xy = np.stack([np.einsum("ij,ij->i", rel, frames.right[wall]), np.einsum("ij,ij->i", rel, frames.down[wall])], 1)
    ok = ~reflected & (cos_i > 0) & (denom < 0) & (t_w > 0) & np.isfinite(xy).all(axis=1)
    return xy, ok


@dataclass
class Landing:
    """Where the photons that meet the outer side surface land.

    index (k,) into the photon set; xy (k, 2) mm on their walls; ok (k,) bool;
    corners (k, 3) int fine-grid vertices of the facet crossed; facet: its corners'
    positions, three (k, 3) mm."""
    index: np.ndarray
    xy: np.ndarray
    ok: np.ndarray
    corners: np.ndarray
    facet: list[np.ndarray]


class _Grid:
    """Sparse maps from a node grid's B-spline coefficients to its tessellation."""

    def __init__(self, cyl: surface.Cylinder, nu: int, nv: int, tessellation: int):
        self.shape = (nu, nv)
        self.mu, self.mv = surface.fine_shape(nu, nv, tessellation)
        ub, vb = surface.u_basis(nu, cyl.creased), surface.v_basis(nv)
        u_fine = np.arange(self.mu) * (2 * np.pi / self.mu)
        z_fine = np.linspace(0.0, 1.0, self.mv)
        bu = [ub.design(u_fine, d) for d in (0, 1)]
        bv = [vb.design(z_fine, d) for d in (0, 1)]
        self.value = sp.kron(bu[0], bv[0]).tocsr()                          # (mu*mv, nu*nv)
        self.d_u = sp.kron(bu[1], bv[0]).tocsr()                            # per rad
        self.d_z = (sp.kron(bu[0], bv[1]) / cyl.height_mm).tocsr()          # per mm
        self.gram = (self.value.T @ self.value).tocsr()
        self.d_uu = sp.kron(ub.design(u_fine, 2), bv[0]).tocsr()                        # per rad^2
        self.d_zz = (sp.kron(bu[0], vb.design(z_fine, 2)) / cyl.height_mm**2).tocsr()  # per mm^2
        self.coef_from_nodes = (ub.coef_from_nodes, vb.coef_from_nodes)
        self.nodes_from_coef = (ub.design(cyl.node_u(nu)).toarray(), vb.design(np.linspace(0.0, 1.0, nv)).toarray())
        self.smooth = _second_differences(nu, nv, cyl.creased, ub)

    def coef(self, heights: np.ndarray) -> np.ndarray:
        cu, cv = self.coef_from_nodes
        return cu @ heights @ cv.T

    def nodes(self, coef: np.ndarray) -> np.ndarray:
        nu_, nv_ = self.nodes_from_coef
        return nu_ @ coef @ nv_.T


def _second_differences(nu: int, nv: int, creased: bool, ub) -> sp.csr_matrix:
    """Second differences of the coefficients along u (periodic; none across a crease)
    and along v: the curvature the fit is charged for."""
    rows_u = np.arange(nu)
    if creased:
        seams = {ub.first_node(s) % nu for s in range(4)}
        rows_u = np.array([i for i in rows_u if i not in seams])
    d_u = sp.csr_matrix((np.tile([1.0, -2.0, 1.0], len(rows_u)),
                         (np.repeat(np.arange(len(rows_u)), 3),
                          np.stack([(rows_u - 1) % nu, rows_u, (rows_u + 1) % nu], 1).ravel())),
                        shape=(len(rows_u), nu))
    d_v = sp.diags([np.ones(nv - 2), -2 * np.ones(nv - 2), np.ones(nv - 2)], [0, 1, 2], shape=(nv - 2, nv))
    return sp.vstack([sp.kron(d_u, sp.identity(nv)), sp.kron(sp.identity(nu), d_v)]).tocsr()


class RayMap:
    """Fits the outer surface to per-photon goals (see the module docstring)."""

    def __init__(self, cyl: surface.Cylinder, tessellation: int, photons: Photons, walls: list[Wall],
                 wall_of: np.ndarray, ior: float, limits: Limits, smoothness: float):
        self.cyl, self.tessellation, self.photons = cyl, tessellation, photons
        self.frames = WallFrames(walls)
        self.wall_of = wall_of
        self.ior = ior
        self.tan_limit = np.tan(np.radians(limits.max_slope_deg - SLOPE_MARGIN_DEG))
        self.max_offset = limits.max_offset_mm
        self.smoothness = smoothness
        tool, overhang = limits.tool_radius_mm, limits.max_overhang_deg
        self.max_curvature = 1.0 / (CURVATURE_MARGIN * tool) if tool > 0 else None
        self.sin_overhang = None if overhang is None else np.sin(np.radians(overhang - SLOPE_MARGIN_DEG))
        self._grids: dict = {}

    def grid(self, shape: tuple[int, int]) -> _Grid:
        if shape not in self._grids:
            self._grids[shape] = _Grid(self.cyl, *shape, self.tessellation)
        return self._grids[shape]

    def trace(self, heights: np.ndarray) -> Landing:
        """Trace every photon meant for a wall through the surface of (nu, nv) mm
        ``heights``, tessellated as the STL will be."""
        from .trace import first_hits

        mu, mv = surface.fine_shape(*heights.shape, self.tessellation)
        vertices, faces = surface.closed_outer_mesh(self.cyl, heights, self.tessellation)
        candidates = np.flatnonzero(self.wall_of >= 0)
        ph = self.photons
        valid, prim, _ = first_hits(vertices, faces, ph.origin[candidates], ph.direction[candidates])
        side = valid & (prim < 2 * mu * (mv - 1))  # not a cap
        index = candidates[side]
        corners = faces[prim[side]]
        v = [vertices[corners[:, c]] for c in range(3)]
        xy, ok = landing(ph.origin[index], ph.direction[index], *v, self.ior, self.frames, self.wall_of[index])
        return Landing(index, xy, ok, corners, v)

    def jacobian(self, land: Landing) -> np.ndarray:
        """(k, 2, 3) d xy / d radial offset of each corner of the facet each photon of
        ``land`` crosses (central differences; NaN where a difference is undefined)."""
        o, d = self.photons.origin[land.index], self.photons.direction[land.index]
        wall = self.wall_of[land.index]
        jac = np.zeros((len(land.index), 2, 3))
        for c in range(3):
            corner = land.facet[c]
            radial = corner * [1.0, 1.0, 0.0]
            radial *= DIFF_STEP_MM / np.linalg.norm(radial, axis=1, keepdims=True)
            moved = list(land.facet)
            moved[c] = corner + radial
            plus, _ = landing(o, d, *moved, self.ior, self.frames, wall)
            moved[c] = corner - radial
            minus, _ = landing(o, d, *moved, self.ior, self.frames, wall)
            jac[:, :, c] = (plus - minus) / (2 * DIFF_STEP_MM)
        return jac

    def _terms(self, grid: _Grid, coef: np.ndarray, goals: np.ndarray) -> dict:
        """The objective at ``coef``, with what ``_linearized`` needs besides."""
        land = self.trace(grid.nodes(coef))
        goal = goals[land.index]
        use = land.ok & np.isfinite(goal).all(axis=1)
        w = np.where(use, self.photons.weight[land.index], 0.0) / max(self.photons.weight[land.index].sum(), 1e-300)
        residual = np.where(use[:, None], land.xy - np.where(np.isfinite(goal), goal, 0.0), 0.0)
        data = float(np.sum(w[:, None] * residual**2))
        c = coef.ravel()
        offset = grid.value @ c
        r = self.cyl.radius_mm + offset
        r_u, r_z = grid.d_u @ c, grid.d_z @ c
        tan_tilt = surface.tilt_tangent(r, r_u, r_z)
        slope_excess = np.maximum(tan_tilt - self.tan_limit, 0.0)
        offset_excess = np.sign(offset) * np.maximum(np.abs(offset) - self.max_offset, 0.0)
        smooth = grid.smooth @ c
        n_fine = len(offset)
        limits = self._curvature_excess(grid, c, r, r_u, r_z) + self._overhang_excess(grid, r, r_u, r_z)
        value = (data + SLOPE_WEIGHT * float(slope_excess @ slope_excess) / n_fine
                 + OFFSET_WEIGHT * float(offset_excess @ offset_excess) / n_fine
                 + CURVATURE_WEIGHT * sum(float(e @ e) for e, _ in limits) / n_fine
                 + LEVEL_WEIGHT * float(offset @ offset) / n_fine + self.smoothness * float(smooth @ smooth))
        return {"value": value, "data": data, "max_tilt_deg": float(np.degrees(np.arctan(tan_tilt.max()))),
                "at": dict(land=land, use=use, w=w, residual=residual, offset=offset, r=r, r_u=r_u, r_z=r_z,
                           tan_tilt=tan_tilt, slope_excess=slope_excess, offset_excess=offset_excess,
                           smooth=smooth, limits=limits)}

    def _linearized(self, grid: _Grid, terms: dict) -> dict:
        """``terms`` with the objective's Gauss-Newton matrix and gradient added: the
        landing's Jacobian costs as much as the rest of ``_terms``, so only the steps
        taken pay for it."""
        at = terms["at"]
        land, use, w, residual, offset = at["land"], at["use"], at["w"], at["residual"], at["offset"]
        r, r_u, r_z, tan_tilt, slope_excess = at["r"], at["r_u"], at["r_z"], at["tan_tilt"], at["slope_excess"]
        n_fine = len(offset)
        k = len(land.index)
        sw = np.sqrt(w)
        jac = self.jacobian(land)
        # A photon whose landing has no derivative (one side of a difference totally
        # reflected) steers nothing in this step.
        use = use & np.isfinite(jac).all(axis=(1, 2))
        rows = np.broadcast_to(np.arange(2 * k).reshape(k, 2, 1), (k, 2, 3))
        cols = np.broadcast_to(land.corners[:, None, :], (k, 2, 3))
        jac_v = sp.csr_matrix(((np.where(use[:, None, None], jac, 0.0) * sw[:, None, None]).ravel(),
                               (rows.ravel(), cols.ravel())), shape=(2 * k, grid.mu * grid.mv))
        per_vertex = (jac_v.T @ jac_v).tocsr()
        matrix = grid.value.T @ per_vertex @ grid.value
        gradient = grid.value.T @ (jac_v.T @ (np.where(use[:, None], residual, 0.0) * sw[:, None]).ravel())
        over = np.flatnonzero(slope_excess > 0)
        if len(over):
            t = tan_tilt[over]
            # d tan_tilt = (r_u / r^2 d r_u - r_u^2 / r^3 d r + r_z d r_z) / tan_tilt
            slope_jac = (sp.diags(r_u[over] / r[over] ** 2 / t) @ grid.d_u[over]
                         - sp.diags(r_u[over] ** 2 / r[over] ** 3 / t) @ grid.value[over]
                         + sp.diags(r_z[over] / t) @ grid.d_z[over])
            matrix = matrix + (SLOPE_WEIGHT / n_fine) * (slope_jac.T @ slope_jac)
            gradient = gradient + (SLOPE_WEIGHT / n_fine) * (slope_jac.T @ slope_excess[over])
        for excess, jac in at["limits"]:
            matrix = matrix + (CURVATURE_WEIGHT / n_fine) * (jac.T @ jac)
            gradient = gradient + (CURVATURE_WEIGHT / n_fine) * (jac.T @ excess)
        matrix = matrix + (LEVEL_WEIGHT / n_fine) * grid.gram
        gradient = gradient + (LEVEL_WEIGHT / n_fine) * (grid.value.T @ offset)
        far = np.flatnonzero(at["offset_excess"] != 0)
        if len(far):
            matrix = matrix + (OFFSET_WEIGHT / n_fine) * (grid.value[far].T @ grid.value[far])
            gradient = gradient + (OFFSET_WEIGHT / n_fine) * (grid.value[far].T @ at["offset_excess"][far])
        matrix = matrix + self.smoothness * (grid.smooth.T @ grid.smooth)
        gradient = gradient + self.smoothness * (grid.smooth.T @ at["smooth"])
        return {**terms, "matrix": matrix.tocsr(), "gradient": gradient}

    def _curvature_excess(self, grid: _Grid, c: np.ndarray, r: np.ndarray, r_u: np.ndarray,
                          r_z: np.ndarray) -> list[tuple[np.ndarray, sp.csr_matrix]]:
        """[(excess (n_fine,) 1/mm, its Jacobian)] of the hollow curvature along u and along z
        over the tool's limit (none without a tool).  Normal curvatures from the fundamental
        forms as ``curvature.concave_radius_of`` has them; the Jacobian keeps their
        second-derivative terms, which dominate where a hollow is tight."""
        if self.max_curvature is None:
            return []
        n_len = np.sqrt(r**2 + r_u**2 + (r * r_z) ** 2)
        along_u = r_u**2 + r**2
        along_z = r_z**2 + 1.0
        k_u = ((grid.d_uu @ c - r) * r - 2 * r_u**2) / (n_len * along_u)
        k_z = (grid.d_zz @ c) * r / (n_len * along_z)
        out = []
        for k, scale, second in ((k_u, r / (n_len * along_u), grid.d_uu), (k_z, r / (n_len * along_z), grid.d_zz)):
            excess = np.maximum(k - self.max_curvature, 0.0)
            over = np.flatnonzero(excess)
            jac = sp.csr_matrix((len(k), c.size))
            if len(over):
                pick = sp.csr_matrix((np.ones(len(over)), (over, over)), shape=(len(k), len(k)))
                jac = pick @ sp.diags(scale) @ second
            out.append((excess, jac))
        return out

    def _overhang_excess(self, grid: _Grid, r: np.ndarray, r_u: np.ndarray,
                         r_z: np.ndarray) -> list[tuple[np.ndarray, sp.csr_matrix]]:
        """[(excess, its Jacobian)] of how far the surface faces down past the print's
        overhang limit: sin(overhang) = -n_z = r r_z / |X_u x X_z| (none without a limit).
        The Jacobian keeps the r_z term, which dominates."""
        if self.sin_overhang is None:
            return []
        n_len = np.sqrt(r**2 + r_u**2 + (r * r_z) ** 2)
        excess = np.maximum(r * r_z / n_len - self.sin_overhang, 0.0)
        over = np.flatnonzero(excess)
        jac = sp.csr_matrix((len(r), grid.d_z.shape[1]))
        if len(over):
            pick = sp.csr_matrix((np.ones(len(over)), (over, over)), shape=(len(r), len(r)))
            jac = pick @ sp.diags(r / n_len) @ grid.d_z
        return [(excess, jac)]

    def fit(self, heights: np.ndarray, goals: np.ndarray, iterations: int, on_step=None,
            min_gain: float = 0.0) -> tuple[np.ndarray, dict]:
        """Levenberg-Marquardt from ``heights`` (nu, nv) mm towards ``goals`` (n_photons, 2)
        mm (NaN: no goal), at most ``iterations`` steps; ``on_step(figures)`` after each step
        taken.  With ``min_gain`` > 0 it ends after a step that lowers the mean squared landing
        error by less than that share of it.  Returns (heights, figures of the last iterate)."""
        grid = self.grid(heights.shape)
        coef = grid.coef(heights)
        current = self._linearized(grid, self._terms(grid, coef, goals))
        damping = DAMPING_START
        taken = 0
        for _ in range(iterations):
            diagonal = current["matrix"].diagonal() + 1e-12
            while damping <= DAMPING_MAX:
                step = _solve(current["matrix"] + damping * sp.diags(diagonal), -current["gradient"])
                trial = self._terms(grid, coef + step.reshape(coef.shape), goals)
                if trial["value"] < current["value"]:
                    stalled = min_gain > 0 and trial["data"] > (1.0 - min_gain) * current["data"]
                    coef, current = coef + step.reshape(coef.shape), self._linearized(grid, trial)
                    damping = max(damping / DAMPING_DOWN, 1e-6)
                    taken += 1
                    break
                damping *= DAMPING_UP
            else:
                break  # no step lowers the objective: converged as far as it goes
            if on_step:
                on_step(_figures(current, taken))
            if stalled:
                break
        return grid.nodes(coef), _figures(current, taken)


def _figures(terms: dict, steps_taken: int) -> dict:
    return {"rms_landing_error_mm": float(np.sqrt(terms["data"])), "max_tilt_deg": terms["max_tilt_deg"],
            "steps_taken": steps_taken}


def _solve(matrix: sp.csr_matrix, rhs: np.ndarray) -> np.ndarray:
    """The damped normal equations (symmetric positive definite): conjugate gradients with
    a Jacobi preconditioner, to the accuracy a Levenberg-Marquardt step needs; a direct
    solve if they stall."""
    from scipy.sparse.linalg import LinearOperator, cg

    inverse_diagonal = 1.0 / matrix.diagonal()
    preconditioner = LinearOperator(matrix.shape, matvec=lambda x: inverse_diagonal * x)
    x, info = cg(matrix, rhs, rtol=CG_RTOL, maxiter=CG_MAX_ITERATIONS, M=preconditioner)
    return x if info == 0 else spsolve(matrix.tocsc(), rhs)
