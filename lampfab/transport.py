"""A first lens from optimal transport: each photon's goal on its wall, then the surface
that lands it there.

1. Photons leave the LED's point light (a post's: each face's centre) on a stratified grid
   of directions, traced through the actual inner layer (``raymap.stratified_photons``).
   Each 90° sector of the lens sends its light to the wall it faces (the source's 5.2).
2. For each wall, entropic optimal transport (``ot``) from the sector's light, laid out by
   emission angle, to the wall's target image gives every photon a goal (none to light
   that meets the outer surface in another sector).  A band above and below the image
   takes ``dump_share`` of the light, which the lens's top and bottom cannot squeeze in
   under the profile's slopes.
3. ``raymap.RayMap`` fits the heightmap (coarse grid, then the profile's) so that each
   photon, refracted at the facet of the tessellated surface it meets, lands at its goal.
4. Correction passes trace the lens, move the light from where it really lands part of
   the way towards the target (same band) along a smooth density flow (``flow``), and
   refit: this is what makes dark parts dark, since a field of goals that no surface
   realizes exactly leaves light where the first fit put it.  The passes share a budget
   of fitting steps; a pass ends when a step stops paying, and the next one starts from
   new goals, until the budget is spent or the lens stops following them; the lens whose
   light lands closest to the target is kept.

Finally the surface is projected under the fabrication limits (``limits.limit_shape``):
slopes, overhangs, and hollows a ball-end tool can reach.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.ndimage import map_coordinates

from . import flow, ot, raymap, surface
from .limits import Limits, limit_shape
from .profile import Optimize
from .room import SECTOR_WIDTH_DEG, Wall
from .source import Source

# Photon strata around the lens per heightmap node: four photons cross each node column.
AZIMUTH_STRATA_PER_NODE = 4

# Optimal transport runs on cells of 2 x 2 photon strata: enough light per cell for a
# smooth density, twice the node resolution around.
CELL_STRATA = 2

# Share of the deflection a slope at the profile's limit can make that a photon may need
# to reach its wall at all; beyond it the photon gets no goal (the floor's sector sends
# its upper half to the ceiling).
REACH_MARGIN = 0.8

# The band above and below the image that takes the dumped light is this share of the
# image's height; a correction pass sees landings this far (as a share of width and
# height) past the image's edges.
BAND_SHARE = 0.25

# A wall's sector follows its image's light centroid at most this far (degrees): beyond
# it the sector would face the next wall more than its own.
MAX_SECTOR_SHIFT_DEG = 30.0
# Below this shift (degrees) a sector stays on its nominal span, whose ends are the
# creases of a creased lens: a slight net tilt of the sector costs less than light
# crossing to the next wall away from a crease.
MIN_SECTOR_SHIFT_DEG = 3.0

# Entropic blur of the transport, in target pixels (rms): sharp, but smooth enough that
# nearby photons get nearby goals.
BLUR_PX = 0.5

# A correction pass moves the landed light this share of the way to the target's density
# (``flow``), in this many re-binned substeps.  Small moves that a smooth surface can
# follow, pass after pass: the full way (or the converged optimal transport) scatters the
# goals and the fit cannot realize them (bench/RESULTS.md).
FLOW_GAIN = 0.5
FLOW_SUBSTEPS = 4

# A correction pass ends after a step that lowers its landing error (mean square) by less
# than this share: its goals are then stale, and the rest of the passes' steps pay more
# on new goals.  The horse gains 0.01-0.04 of its SSIM ceiling, a panorama (whose every
# step still pays) keeps its lens (bench/RESULTS.md).
MIN_STEP_GAIN = 0.03
# The lens kept is the pass's whose light lands closest to the target's density
# (``landed_density_error``, mean over the walls); the passes' landing errors cannot
# judge this, since each is measured against its own goals.  The passes end after one
# that the fit could not follow (it ended after its first step) and that lands the light
# less than this share closer than the best lens so far: the lens is then held by its
# limits (a milled lens, whose tool's radius binds; the floor's sector: 0.1 % or less a
# pass), and further passes only cost traces.  A pass of several steps may land the light
# farther and the next ones closer again (scikit-image's cell), so it does not end them.
# A default image's passes gain 0.8 % or more (bench/RESULTS.md).
MIN_PASS_GAIN = 0.005

# Where the profile prefers gentler slopes than it can make (a print: steeper flanks
# reflect more of the light back in), a first fit that lands the light farther than this
# many of the images' pixels (rms) from its goals is made again under the steeper limit,
# and that one is kept if it lands the light at least this share closer: the gentle
# slopes then hold the light that must bend farthest (a dark sky above bright hills, the
# gaps under a silhouette).  The first fits of the horse, a panorama and scikit-image's
# rocket land their light 64-168 mm off (28 mm pixels) and 8-42 % closer with steeper
# slopes; the horse and the panorama then score +0.01 to +0.04 of SSIM, the rocket
# -0.005 to -0.007.  Nine more pictures whose first fit lands over a pixel off gain 4 % at
# most (bench/RESULTS.md).  The choice comes first: steepened after the first correction
# pass, the horse gained nothing.
STEEPEN_LANDING_PX = 2.0
STEEPEN_MIN_GAIN = 0.06


def design(cyl: surface.Cylinder, walls: list[Wall], targets: list[np.ndarray],
           inner_vertices: np.ndarray, inner_faces: np.ndarray, source: Source, ior: float,
           limits: Limits, opt: Optimize, log=print, on_step=None, on_pass=None) -> tuple[np.ndarray, dict]:
    """The transport-based heightmap within ``limits``, on the (grid_u, grid_v) node grid
    of ``opt`` (the ``[optimize]`` settings), for the LED ``source``'s point light (its
    beam from its centre, a post's from each face's centre: a design shapes where the
    light goes, the refinement then what the LED's size does to it).

    targets: per wall (rows, cols) linear luminance.  From ``opt``: ``transport_photons``
    traced from the light (``seed``), ``transport_rounds`` Levenberg-Marquardt steps per
    fit (twice that on the coarse grid) with the ``smoothness`` penalty on the
    ``tessellation``'s facets, ``transport_corrections`` times ``transport_rounds`` steps
    of trace-and-refit passes (up to ``transport_rounds`` steps each),
    ``dump_share`` of the light in the bands beside each image.
    ``on_step(figures)`` follows every fitting step (``fit_steps`` of them: a progress bar),
    ``on_pass(heights)`` sees the (nu, nv) surface after every fit (the benchmark times them).
    Where ``limits`` may steepen (``steepest_slope_deg``) and the first fit lands the light
    far from its goals, that fit is made again under the steeper limit and kept if it
    lands the light closer (``STEEPEN_LANDING_PX``, ``STEEPEN_MIN_GAIN``); figures'
    ``slope_limit_deg`` is the limit chosen, which the refinement keeps, and
    ``first_fit_rms_landing_error_mm`` the first fits' landing errors by limit.
    Returns ((nu, nv) mm offsets, figures).
    """
    grid, iterations, dump_share = (opt.grid_u, opt.grid_v), opt.transport_rounds, opt.dump_share
    nu, nv = grid
    n_azimuth = AZIMUTH_STRATA_PER_NODE * nu
    n_elevation = max(opt.transport_photons // n_azimuth, 8 * CELL_STRATA)
    ph = raymap.stratified_photons(inner_vertices, inner_faces, source, ior, n_azimuth, n_elevation, opt.seed)
    light_mm = source.position
    spans = sector_spans(walls, targets, light_mm)
    exit_deg = exit_azimuth_deg(ph, cyl.radius_mm)
    coarse = coarse_grid(grid)
    first_steps = 2 * iterations if coarse != grid else iterations

    def first_fit(limits: Limits, on_step) -> dict:
        """Goals from the source and the first fit (on the coarse grid if there is one)
        under ``limits``: what the passes start from."""
        wall_of = sector_of(ph.emitted, walls, spans, light_mm, ior, limits.max_slope_deg, exit_deg)
        fitter = raymap.RayMap(cyl, opt.tessellation, ph, walls, wall_of, ior, limits, opt.smoothness)
        plain = fitter.trace(np.zeros(coarse))
        lit = np.zeros(len(wall_of), bool)
        lit[plain.index[plain.ok]] = True
        goals, marginal = source_goals(ph, wall_of, lit, walls, spans, targets, light_mm, dump_share)
        heights, fit = fitter.fit(np.zeros(coarse), goals, first_steps, on_step)
        return dict(limits=limits, wall_of=wall_of, fitter=fitter, lit=lit, goals=goals, marginal=marginal,
                    heights=heights, fit=fit)

    start = first_fit(limits, on_step)
    pixel_mm = np.mean([wall.width_mm / target.shape[1] for wall, target in zip(walls, targets)])
    preferred_error = start["fit"]["rms_landing_error_mm"]
    first_errors = {f"{limits.max_slope_deg:g}": preferred_error}
    if limits.steepest_slope_deg is not None and preferred_error > STEEPEN_LANDING_PX * pixel_mm:
        log(f"transport: the first fit lands the light {preferred_error:.0f} mm from its goals; "
            f"trying slopes up to {limits.steepest_slope_deg:g} deg")
        steep = first_fit(limits.steepened(), None)
        first_errors[f"{limits.steepest_slope_deg:g}"] = steep["fit"]["rms_landing_error_mm"]
        if steep["fit"]["rms_landing_error_mm"] < (1.0 - STEEPEN_MIN_GAIN) * preferred_error:
            start = steep
    limits, wall_of, fitter, goals, heights, fit = (start[k] for k in ("limits", "wall_of", "fitter", "goals",
                                                                         "heights", "fit"))
    figures = {"photons": int(len(wall_of)), "ot_marginal_error": start["marginal"], "passes": [],
               "sectors_deg": {name: [round(lo, 2), round(hi, 2)] for name, (lo, hi) in spans.items()},
               "first_fit_rms_landing_error_mm": first_errors, "slope_limit_deg": limits.max_slope_deg}
    log(f"transport: {len(wall_of)} photons, {start['lit'].sum()} reach a wall's sector through the side")

    report = on_pass or (lambda h: None)
    if coarse != grid:
        heights = surface.refine(cyl, heights, 4)
        report(heights)
        current, fit = fitter.fit(heights, goals, iterations, on_step)
    else:
        current = heights
    budget, kept_error = opt.transport_corrections * iterations, np.inf
    while True:
        report(current)
        goals, landed = landing_goals(fitter.trace(current), wall_of, walls, targets, dump_share)
        figures["passes"].append({**fit, "landed_density_error": landed})
        error = np.mean(list(landed.values()))
        log(f"transport: pass {len(figures['passes']) - 1}: {fit['steps_taken']} steps, "
            f"landed density error {error:.3f}")
        held = fit["steps_taken"] <= 1 and error > (1.0 - MIN_PASS_GAIN) * kept_error
        if error < kept_error:
            heights, kept, kept_error = current, len(figures["passes"]) - 1, error
        if held or budget <= 0:
            break
        current, fit = fitter.fit(current, goals, min(iterations, budget), on_step, MIN_STEP_GAIN)
        budget -= max(fit["steps_taken"], 1)
    figures["kept_pass"] = kept
    bound = limits.max_offset_mm
    heights, max_tilt = limit_shape(cyl, np.clip(heights, -bound, bound), limits.max_slope_deg,
                                    limits.max_overhang_deg, limits.tool_radius_mm)
    clipped = float(np.mean(np.abs(heights) > bound))
    heights = np.clip(heights, -bound, bound)
    figures.update(offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()),
                   clipped_fraction=clipped, grid=list(grid), max_tilt_deg=max_tilt, creased=cyl.creased)
    return heights, figures


def coarse_grid(grid: tuple[int, int]) -> tuple[int, int]:
    """The grid the first fit runs on: four times coarser where that still leaves every
    sector 8 nodes around and the height 5 nodes, else the profile's."""
    nu, nv = grid
    return (nu // 4, (nv - 1) // 4 + 1) if nu % 128 == 0 and (nv - 1) % 16 == 0 else grid


def fit_steps(grid: tuple[int, int], iterations: int, corrections: int) -> int:
    """How many fitting steps ``design`` takes at most (its progress bar's length)."""
    return (2 * iterations if coarse_grid(grid) != grid else 0) + iterations * (1 + corrections)


def sector_spans(walls: list[Wall], targets: list[np.ndarray], light_mm: np.ndarray) -> dict[str, tuple[float, float]]:
    """The span of u (degrees, lo < hi) whose light each wall receives.

    A sector centred on its wall must shift its light sideways on average when the
    image's light is off-centre (a portrait lit from one side): every sector then winds
    the radius the same way round the lamp, which a closed surface cannot do within its
    offset bound.  So each sector is centred on the angle of its image's light centroid
    instead (its light then needs no net sideways shift) when its centroid lies more than
    ``MIN_SECTOR_SHIFT_DEG`` off centre; neighbouring sectors meet half way between their
    centres.  A side without a neighbouring wall reaches at least as far as the centred
    sector would.
    """
    centre = {}
    for wall, target in zip(walls, targets):
        rows, cols = target.shape
        across, _ = _pixel_angles(wall, light_mm, cols, rows, 0)
        column_mass = target.sum(axis=0)
        shift = float(np.clip(np.degrees(column_mass @ across / column_mass.sum()),
                              -MAX_SECTOR_SHIFT_DEG, MAX_SECTOR_SHIFT_DEG))
        shift = shift if abs(shift) >= MIN_SECTOR_SHIFT_DEG else 0.0
        # The image's right axis runs against u seen from the lamp (room.py's layout).
        sign = -1.0 if float(wall.right @ _tangent(np.mean(wall.sector_deg()))) < 0 else 1.0
        centre[wall.name] = float(np.mean(wall.sector_deg())) + sign * shift
    half = SECTOR_WIDTH_DEG / 2
    out = {}
    for wall in walls:
        c, nominal = centre[wall.name], float(np.mean(wall.sector_deg()))
        lo, hi = min(c, nominal) - half, max(c, nominal) + half
        for other in walls:
            c2 = centre[other.name]
            gap = (np.mean(other.sector_deg()) - nominal) % 360
            if gap == SECTOR_WIDTH_DEG:  # the neighbour on the high-u side
                hi = 0.5 * (c + c2 + (360 if c2 < c else 0))
            elif gap == 360 - SECTOR_WIDTH_DEG:  # the neighbour on the low-u side
                lo = 0.5 * (c + c2 - (360 if c2 > c else 0))
        out[wall.name] = (lo, hi)
    return out


def _tangent(u_deg: float) -> np.ndarray:
    u = np.radians(u_deg)
    return np.array([-np.sin(u), np.cos(u), 0.0])


def sector_of(emitted: np.ndarray, walls: list[Wall], spans: dict[str, tuple[float, float]], light_mm: np.ndarray,
              ior: float, max_tilt_deg: float, exit_deg: np.ndarray | None = None) -> np.ndarray:
    """(n,) int: the wall whose sector (``spans``) each photon leaves through (by emission
    azimuth), or -1 where no wall's sector holds it, the photon cannot reach its wall with
    a makeable slope, or (given ``exit_azimuth_deg``) it meets the outer surface in another."""
    reach = np.radians(REACH_MARGIN * max_deflection_deg(ior, max_tilt_deg))
    out = span_of(np.degrees(np.arctan2(emitted[:, 1], emitted[:, 0])), walls, spans)
    if exit_deg is not None:
        # A post's light leaves its faces off the axis: past an off-centre sector's edge some meets
        # the outer surface in the next sector; with goals, it asked the crease to light two walls.
        out[span_of(exit_deg, walls, spans) != out] = -1
    for k, wall in enumerate(walls):
        out[(out == k) & (_angle_to_rectangle(wall, light_mm, emitted) > reach)] = -1
    return out


def span_of(azimuth_deg: np.ndarray, walls: list[Wall], spans: dict[str, tuple[float, float]]) -> np.ndarray:
    """(n,) int: the wall whose span of u (``spans``) holds each azimuth (degrees), -1 for none."""
    out = np.full(len(azimuth_deg), -1)
    for k, wall in enumerate(walls):
        lo, hi = spans[wall.name]
        out[np.mod(azimuth_deg - lo, 360.0) < hi - lo] = k
    return out


def exit_azimuth_deg(ph: raymap.Photons, radius_mm: float) -> np.ndarray:
    """(n,) degrees: the azimuth at which each photon's ray in the glass meets the plain
    outer cylinder of ``radius_mm`` about the lamp's axis."""
    o, d = ph.origin[:, :2], ph.direction[:, :2]
    a, b = np.maximum(np.sum(d * d, axis=1), 1e-300), np.sum(o * d, axis=1)  # a photon going straight up stays
    t = (-b + np.sqrt(np.maximum(b * b - a * (np.sum(o * o, axis=1) - radius_mm**2), 0.0))) / a
    return np.degrees(np.arctan2(o[:, 1] + t * d[:, 1], o[:, 0] + t * d[:, 0]))


def max_deflection_deg(ior: float, max_tilt_deg: float) -> float:
    """How far a surface tilted at most ``max_tilt_deg`` bends light leaving glass along
    its radial direction."""
    tilt = np.radians(max_tilt_deg)
    return float(np.degrees(np.arcsin(min(ior * np.sin(tilt), 1.0)) - tilt))


def _angle_to_rectangle(wall: Wall, light_mm: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(n,) rad between each direction from the light and the nearest point of the wall's
    image (0 inside it; pi for directions away from the wall's plane)."""
    normal = wall.normal
    denom = directions @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((wall.origin - light_mm) @ normal) / denom
    hit = light_mm + np.where(denom < 0, t, 1e9)[:, None] * directions
    rel = hit - wall.origin
    a = np.clip(rel @ wall.right / wall.width_mm**2, 0, 1)
    b = np.clip(rel @ wall.down / wall.height_mm**2, 0, 1)
    nearest = _unit(wall.origin + a[:, None] * wall.right + b[:, None] * wall.down - light_mm)
    angle = np.arccos(np.clip(np.sum(nearest * directions, axis=1), -1, 1))
    return np.where(denom < 0, angle, np.pi)


def source_goals(ph: raymap.Photons, wall_of: np.ndarray, lit: np.ndarray, walls: list[Wall],
                 spans: dict[str, tuple[float, float]], targets: list[np.ndarray], light_mm: np.ndarray,
                 dump_share: float) -> tuple[np.ndarray, dict]:
    """Each photon's goal (n, 2) mm on its wall (NaN: none), from the OT of its sector's
    light, laid out by emission angle, onto the target image with its bands.

    ``lit``: photons whose light reaches the wall side of the lens through its side (the
    transported mass).  Source and target are both in angles as seen from the light, so
    the quadratic cost is isotropic.  Returns (goals, {wall: OT marginal error})."""
    goals = np.full((len(wall_of), 2), np.nan)
    errors = {}
    n2 = ph.n_elevation // CELL_STRATA
    for k, (wall, target) in enumerate(zip(walls, targets)):
        mine = np.flatnonzero(wall_of == k)
        lo, hi = spans[wall.name]
        n1 = max(1, int(round((hi - lo) / 360.0 * ph.n_azimuth / CELL_STRATA)))
        across = np.mod(ph.stratum[mine, 0] - lo / 360.0 * ph.n_azimuth, ph.n_azimuth) / CELL_STRATA
        up = ph.stratum[mine, 1] / CELL_STRATA
        mass = np.zeros((n1, n2))
        np.add.at(mass, (np.minimum(across.astype(int), n1 - 1), np.minimum(up.astype(int), n2 - 1)),
                  np.where(lit[mine], ph.weight[mine], 0.0))
        # Cell centres as emission directions: across the sector on the wall's centre
        # elevation, up the sector's centre azimuth.
        centre_dir = _unit(wall.centre - light_mm)
        azimuth = np.radians(lo) + (np.arange(n1) + 0.5) * np.radians(CELL_STRATA * 360.0 / ph.n_azimuth)
        elevation = np.arcsin(-1.0 + 2.0 * (np.arange(n2) + 0.5) / n2)
        mid_az = np.radians(float(np.mean(wall.sector_deg())))
        mid_el = np.arcsin(np.clip(centre_dir[2], -1, 1))
        x1 = _frame_angles(wall, light_mm, _direction(azimuth, np.full(n1, mid_el)))[0]
        x2 = _frame_angles(wall, light_mm, _direction(np.full(n2, mid_az), elevation))[1]
        cell_a, cell_b, errors[wall.name] = _transport(mass, x1, x2, wall, light_mm, target, dump_share)
        coords = [across - 0.5, up - 0.5]
        goals[mine, 0] = map_coordinates(cell_a, coords, order=1, mode="nearest")
        goals[mine, 1] = map_coordinates(cell_b, coords, order=1, mode="nearest")
    return goals, errors


def landing_goals(land: raymap.Landing, wall_of: np.ndarray, walls: list[Wall], targets: list[np.ndarray],
                  dump_share: float) -> tuple[np.ndarray, dict]:
    """New goals (n, 2) mm from where the photons land now: ``flow`` moves the landed
    photons (on the image's pixel grid, extended by ``BAND_SHARE`` past every edge)
    ``FLOW_GAIN`` of the way towards the target with its bands.  Returns (goals, {wall:
    how far the landed light's density is from that target, L1 of unit masses, 0-2})."""
    goals = np.full((len(wall_of), 2), np.nan)
    landed_error = {}
    for k, (wall, target) in enumerate(zip(walls, targets)):
        rows, cols = target.shape
        pad_r, pad_c = max(1, int(rows * BAND_SHARE)), max(1, int(cols * BAND_SHARE))
        pick = land.ok & (wall_of[land.index] == k)
        x = land.xy[pick, 0] / wall.width_mm * cols + pad_c
        y = land.xy[pick, 1] / wall.height_mm * rows + pad_r
        width, height = cols + 2 * pad_c, rows + 2 * pad_r
        padded = np.zeros((height, width))
        padded[:, pad_c:pad_c + cols] = _banded(target, pad_r, dump_share)
        # Light landing past the margin moves as if from its edge: on by the same step.
        xc, yc = np.clip(x, 0, width - 1e-9), np.clip(y, 0, height - 1e-9)
        landed, _, _ = np.histogram2d(xc, yc, bins=[width, height], range=[[0, width], [0, height]])
        landed_error[wall.name] = float(np.abs(landed / max(landed.sum(), 1.0) - padded.T).sum())
        to_x, to_y = flow.flow(xc, yc, padded.T, FLOW_GAIN, FLOW_SUBSTEPS)
        index = land.index[pick]
        goals[index, 0] = land.xy[pick, 0] + (to_x - xc) / cols * wall.width_mm
        goals[index, 1] = land.xy[pick, 1] + (to_y - yc) / rows * wall.height_mm
    return goals, landed_error


def _banded(target: np.ndarray, pad_rows: int, dump_share: float) -> np.ndarray:
    """(rows + 2 pad_rows, cols) mass: the target with 1 - dump_share of the light and
    uniform bands above and below holding dump_share."""
    rows, cols = target.shape
    out = np.pad(target / target.sum() * (1.0 - dump_share), ((pad_rows, pad_rows), (0, 0)))
    if dump_share > 0:
        out[:pad_rows] = out[-pad_rows:] = dump_share / (2 * pad_rows * cols)
    return out


def _transport(mass: np.ndarray, x1: np.ndarray, x2: np.ndarray, wall: Wall, light_mm: np.ndarray,
               target: np.ndarray, dump_share: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Goal of every source cell (mm along the image's right and down axes) from the OT of
    ``mass`` (n1, n2) at angles (x1, x2) onto the banded target."""
    rows, cols = target.shape
    pad = max(1, int(rows * BAND_SHARE)) if dump_share > 0 else 0
    banded = _banded(target, pad, dump_share)
    y1, y2 = _pixel_angles(wall, light_mm, cols, rows, pad)
    shift = min(x1.min(), x2.min(), y1.min(), y2.min()) - 1.0  # positive coordinates for the log-domain maps
    blur = (BLUR_PX * (y1[-1] - y1[0]) / (cols - 1)) ** 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # log(0) for black cells is meant
        a1, a2, err = ot.barycentric_map(mass + 1e-9 * mass.max(), banded.T, x1 - shift, x2 - shift,
                                            y1 - shift, y2 - shift, blur)
    across = np.interp(a1 + shift, y1, (np.arange(cols) + 0.5) / cols) * wall.width_mm
    down = np.interp(a2 + shift, y2, (np.arange(-pad, rows + pad) + 0.5) / rows) * wall.height_mm
    return across, down, err


def _pixel_angles(wall: Wall, light_mm: np.ndarray, cols: int, rows: int, pad_rows: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Angles (rad) under which the light sees the wall's pixel column centres (on the
    image's middle row) and row centres (on its middle column, ``pad_rows`` more rows
    past each edge), each increasing along the image's axis."""
    a = (np.arange(cols) + 0.5) / cols
    b = (np.arange(-pad_rows, rows + pad_rows) + 0.5) / rows
    across = wall.centre + (a[:, None] - 0.5) * wall.right - light_mm
    down = wall.centre + (b[:, None] - 0.5) * wall.down - light_mm
    return _frame_angles(wall, light_mm, across)[0], _frame_angles(wall, light_mm, down)[1]


def _frame_angles(wall: Wall, light_mm: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n,) rad each: the directions' angles from the light's line to the wall's centre,
    along the image's right axis and along its down axis."""
    centre = _unit(wall.centre - light_mm)
    right = _unit(wall.right - (wall.right @ centre) * centre)
    down = _unit(wall.down - (wall.down @ centre) * centre)
    forward = directions @ centre
    return np.arctan2(directions @ right, forward), np.arctan2(directions @ down, forward)


def _direction(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)


def snell_normals(d_in: np.ndarray, d_out: np.ndarray, ior: float) -> np.ndarray:
    """Outward unit normals that refract d_in (in glass) into d_out (in air).

    n_glass d_in - n_air d_out is parallel to the outward normal (and never zero
    for n_glass > n_air).  (..., 3) in, (..., 3) out.
    """
    n = ior * d_in - d_out
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)
