"""A first lens from optimal transport: each photon's goal on its wall, then the surface
that lands it there.

1. Photons leave the LED's point light (a post's: each face's centre) on a stratified grid
   of directions, traced through the actual inner layer (``raymap.stratified_photons``).
   Each 90° sector of the lens sends its light to the wall it faces (the source's 5.2;
   ``sectors``).
2. For each wall, entropic optimal transport (``ot``) from the sector's light, laid out by
   emission angle, to the wall's target image gives every photon a goal (none to light
   that meets the outer surface in another sector).  A band above and below the image
   takes ``dump_share`` of the light, which the lens's top and bottom cannot squeeze in
   under the profile's slopes; where the picture's light sits so high in its frame that
   the lens would have to lift light farther than it can, the band below takes more
   (``band_shares``).
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
from .room import Wall
from .sectors import direction, exit_azimuth_deg, frame_angles, pixel_angles, sector_of, sector_spans, unit
from .source import Source

# Photon strata around the lens per heightmap node: four photons cross each node column.
AZIMUTH_STRATA_PER_NODE = 4

# Optimal transport runs on cells of 2 x 2 photon strata: enough light per cell for a
# smooth density, twice the node resolution around.
CELL_STRATA = 2

# The band above and below the image that takes the dumped light is this share of the
# image's height; a correction pass sees landings this far (as a share of width and
# height) past the image's edges.
BAND_SHARE = 0.25

# The light a sector sends up its wall, quantile by quantile, should land on the same
# quantile of the picture's rows (the monotone map).  Lifting the lens's lower light,
# which leaves the LED downwards, takes flanks facing down: a print keeps them within its
# overhang rule (``limits.OVERHANG_DEG`` past vertical), a mill within its slope limit,
# and they lift light crossing the glass 30° downwards by 8° (a print, a 3-axis mill) or
# 18° (a 4-axis mill's 60°) at most.  Where the map asks to lift light farther than
# LIFT_REACH_DEG, the light lands short, on the picture's black: an umbrella drawn for a
# test, its canopy in the upper half, asked 37° and hazed its black lower half (LED SSIM
# 0.46-0.49, 14-16 % of the light on black), a sunset over dark ground asked 43° (0.51);
# the bundled pictures and scikit-image's photographs ask 7-17°, the umbrella drawn
# centred 24°.  So the band below takes more of the light, in steps of BAND_STEP, until
# the map stays within reach or the band holds MAX_BAND: that light glows below the
# picture instead of in it (the umbrella 0.69-0.72, the sunset 0.86-0.90; milled, the
# umbrella 0.31-0.34 -> 0.43-0.47; bench/RESULTS.md).  Bending light down takes
# flanks facing up, which a print makes steeper: the panorama (hills under a dark sky,
# 31-38° down) and a flat LED facing up (48° down) lost SSIM or light with a larger band
# above, so that band stays as it is.  The quantiles' tails (TAIL_SHARE at each end) hold
# too little light to count.
LIFT_REACH_DEG = 24.0
BAND_STEP = 0.025
MAX_BAND = 0.4
TAIL_SHARE = 0.005

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
    ``dump_share`` of the light in the bands beside each image, more below where the
    picture's light sits higher than the lens can lift it (``band_shares``; figures'
    ``bands``).
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
        goals, marginal, bands = source_goals(ph, wall_of, lit, walls, spans, targets, light_mm, dump_share,
                                              LIFT_REACH_DEG)
        heights, fit = fitter.fit(np.zeros(coarse), goals, first_steps, on_step)
        return dict(limits=limits, wall_of=wall_of, fitter=fitter, lit=lit, goals=goals, marginal=marginal,
                    bands=bands, heights=heights, fit=fit)

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
    limits, wall_of, fitter, goals, bands, heights, fit = (start[k] for k in ("limits", "wall_of", "fitter", "goals",
                                                                                "bands", "heights", "fit"))
    figures = {"photons": int(len(wall_of)), "ot_marginal_error": start["marginal"], "passes": [], "bands": bands,
               "sectors_deg": {name: [round(lo, 2), round(hi, 2)] for name, (lo, hi) in spans.items()},
               "first_fit_rms_landing_error_mm": first_errors, "slope_limit_deg": limits.max_slope_deg}
    log(f"transport: {len(wall_of)} photons, {start['lit'].sum()} reach a wall's sector through the side")
    for name, b in bands.items():
        if b["lifted"]:
            log(f"transport: {name}: the picture's light sits higher than the lens can lift its lower light; "
                f"the band below it takes {b['below']:.1%} of the light")

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
        goals, landed = landing_goals(fitter.trace(current), wall_of, walls, targets, bands)
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


def source_goals(ph: raymap.Photons, wall_of: np.ndarray, lit: np.ndarray, walls: list[Wall],
                 spans: dict[str, tuple[float, float]], targets: list[np.ndarray], light_mm: np.ndarray,
                 dump_share: float, reach_deg: float) -> tuple[np.ndarray, dict, dict]:
    """Each photon's goal (n, 2) mm on its wall (NaN: none), from the OT of its sector's
    light, laid out by emission angle, onto the target image with its bands
    (``band_shares`` of ``dump_share``, within the lens's reach up ``reach_deg``).

    ``lit``: photons whose light reaches the wall side of the lens through its side (the
    transported mass).  Source and target are both in angles as seen from the light, so
    the quadratic cost is isotropic.  Returns (goals, {wall: OT marginal error}, {wall:
    ``band_shares``' figures})."""
    goals = np.full((len(wall_of), 2), np.nan)
    errors, bands = {}, {}
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
        centre_dir = unit(wall.centre - light_mm)
        azimuth = np.radians(lo) + (np.arange(n1) + 0.5) * np.radians(CELL_STRATA * 360.0 / ph.n_azimuth)
        elevation = np.arcsin(-1.0 + 2.0 * (np.arange(n2) + 0.5) / n2)
        mid_az = np.radians(float(np.mean(wall.sector_deg())))
        mid_el = np.arcsin(np.clip(centre_dir[2], -1, 1))
        x1 = frame_angles(wall, light_mm, direction(azimuth, np.full(n1, mid_el)))[0]
        x2 = frame_angles(wall, light_mm, direction(np.full(n2, mid_az), elevation))[1]
        bands[wall.name] = band_shares(mass.sum(axis=0), x2, wall, light_mm, target, dump_share, reach_deg)
        shares = (bands[wall.name]["above"], bands[wall.name]["below"])
        cell_a, cell_b, errors[wall.name] = _transport(mass, x1, x2, wall, light_mm, target, shares)
        coords = [across - 0.5, up - 0.5]
        goals[mine, 0] = map_coordinates(cell_a, coords, order=1, mode="nearest")
        goals[mine, 1] = map_coordinates(cell_b, coords, order=1, mode="nearest")
    return goals, errors, bands


def band_shares(elevation_mass: np.ndarray, x2: np.ndarray, wall: Wall, light_mm: np.ndarray, target: np.ndarray,
                dump_share: float, reach_deg: float | None) -> dict:
    """The shares of a sector's light the bands above and below ``target`` take: half of
    ``dump_share`` each, and more below where the monotone map of the light up the wall
    onto the picture's rows would lift it farther than ``reach_deg`` (None: never), until
    it does not (``BAND_STEP``, ``MAX_BAND``).

    ``elevation_mass``: (n2,) the sector's light by emission elevation, at ``x2`` (n2,)
    rad, its angle along the image's down axis.  Returns {"above", "below": shares,
    "bend_deg": [most up (negative), most down] of the map with those bands, "reach_deg",
    "lifted": whether the band below grew}."""
    above = below = dump_share / 2
    lifted = False
    while True:
        bend = vertical_bend_deg(elevation_mass, x2, wall, light_mm, target, (above, below))
        if reach_deg is None or -bend[0] <= reach_deg or below >= MAX_BAND - 1e-9:  # float steps
            return {"above": above, "below": below, "bend_deg": bend, "reach_deg": reach_deg, "lifted": lifted}
        below, lifted = below + BAND_STEP, True


def vertical_bend_deg(elevation_mass: np.ndarray, x2: np.ndarray, wall: Wall, light_mm: np.ndarray,
                      target: np.ndarray, shares: tuple[float, float]) -> list[float]:
    """[most up (negative), most down] degrees: how far the monotone map from the light
    (``elevation_mass`` (n2,) at angles ``x2`` (n2,) rad down the image's axis) onto the
    rows of ``target`` with bands holding ``shares`` (above, below) bends it, over the
    light's quantiles but their tails (``TAIL_SHARE``)."""
    rows, cols = target.shape
    pad = max(1, int(rows * BAND_SHARE))
    _, y2 = pixel_angles(wall, light_mm, cols, rows, pad)
    order = np.argsort(x2)
    # A hair of mass in every cell and row keeps the cumulative sums increasing for interp.
    source = np.cumsum(elevation_mass[order] + (1e-12 * elevation_mass.sum() or 1.0))
    image = np.cumsum(_banded(target, pad, shares).sum(axis=1) + 1e-12)
    q = np.linspace(TAIL_SHARE, 1.0 - TAIL_SHARE, 199)
    bend = np.degrees(np.interp(q, image / image[-1], y2) - np.interp(q, source / source[-1], x2[order]))
    return [float(bend.min()), float(bend.max())]


def landing_goals(land: raymap.Landing, wall_of: np.ndarray, walls: list[Wall], targets: list[np.ndarray],
                  bands: dict) -> tuple[np.ndarray, dict]:
    """New goals (n, 2) mm from where the photons land now: ``flow`` moves the landed
    photons (on the image's pixel grid, extended by ``BAND_SHARE`` past every edge)
    ``FLOW_GAIN`` of the way towards the target with its bands (``bands``: {wall:
    ``band_shares``' figures}).  Returns (goals, {wall:
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
        padded[:, pad_c:pad_c + cols] = _banded(target, pad_r, (bands[wall.name]["above"], bands[wall.name]["below"]))
        # Light landing past the margin moves as if from its edge: on by the same step.
        xc, yc = np.clip(x, 0, width - 1e-9), np.clip(y, 0, height - 1e-9)
        landed, _, _ = np.histogram2d(xc, yc, bins=[width, height], range=[[0, width], [0, height]])
        landed_error[wall.name] = float(np.abs(landed / max(landed.sum(), 1.0) - padded.T).sum())
        to_x, to_y = flow.flow(xc, yc, padded.T, FLOW_GAIN, FLOW_SUBSTEPS)
        index = land.index[pick]
        goals[index, 0] = land.xy[pick, 0] + (to_x - xc) / cols * wall.width_mm
        goals[index, 1] = land.xy[pick, 1] + (to_y - yc) / rows * wall.height_mm
    return goals, landed_error


def _banded(target: np.ndarray, pad_rows: int, shares: tuple[float, float]) -> np.ndarray:
    """(rows + 2 pad_rows, cols) mass: the target with the light the bands leave, and
    uniform bands above and below holding ``shares`` (above, below) of it."""
    rows, cols = target.shape
    above, below = shares
    out = np.pad(target / target.sum() * (1.0 - (above + below)), ((pad_rows, pad_rows), (0, 0)))
    if pad_rows:
        out[:pad_rows] = above / (pad_rows * cols)
        out[rows + pad_rows:] = below / (pad_rows * cols)
    return out


def _transport(mass: np.ndarray, x1: np.ndarray, x2: np.ndarray, wall: Wall, light_mm: np.ndarray,
               target: np.ndarray, shares: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, float]:
    """Goal of every source cell (mm along the image's right and down axes) from the OT of
    ``mass`` (n1, n2) at angles (x1, x2) onto the target with bands holding ``shares``
    (above, below) of the light."""
    rows, cols = target.shape
    pad = max(1, int(rows * BAND_SHARE)) if sum(shares) > 0 else 0
    banded = _banded(target, pad, shares)
    y1, y2 = pixel_angles(wall, light_mm, cols, rows, pad)
    shift = min(x1.min(), x2.min(), y1.min(), y2.min()) - 1.0  # positive coordinates for the log-domain maps
    blur = (BLUR_PX * (y1[-1] - y1[0]) / (cols - 1)) ** 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # log(0) for black cells is meant
        a1, a2, err = ot.barycentric_map(mass + 1e-9 * mass.max(), banded.T, x1 - shift, x2 - shift,
                                            y1 - shift, y2 - shift, blur)
    across = np.interp(a1 + shift, y1, (np.arange(cols) + 0.5) / cols) * wall.width_mm
    down = np.interp(a2 + shift, y2, (np.arange(-pad, rows + pad) + 0.5) / rows) * wall.height_mm
    return across, down, err


def snell_normals(d_in: np.ndarray, d_out: np.ndarray, ior: float) -> np.ndarray:
    """Outward unit normals that refract d_in (in glass) into d_out (in air).

    n_glass d_in - n_air d_out is parallel to the outward normal (and never zero
    for n_glass > n_air).  (..., 3) in, (..., 3) out.
    """
    n = ior * d_in - d_out
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
