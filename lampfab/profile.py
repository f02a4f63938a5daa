"""Profiles: TOML files loaded strictly into frozen dataclasses.

A design profile (``profiles/NAME.toml``) sets the lens, the room and the optimizer; a
fabrication profile (``profiles/fab/NAME.toml``) sets the material and the machine's
limits.  An unknown key, a wrong type or a value out of range is a LampfabError that
names the file, the key and what is allowed.  ``profile_files`` finds and reads the
files (a design profile over its ``base``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import LampfabError
from .profile_files import PROFILE_DIR, design_tables, read_toml, resolve
from .source import SHAPES

DEFAULT_LED = "post3535"
WALL_NAMES = ("front", "left", "right", "floor")
LENS_KINDS = ("cylinder", "panel")
# Per-view losses (lampfab.losses computes them) and view schedules.  The numpy-only ones
# need whole images, so only the splat refinement takes them.
LOSSES = ("si_mse", "si_mse_ssim", "multiscale", "l1_joint", "l1_weighted")
NUMPY_ONLY_LOSSES = ("si_mse_ssim", "multiscale")
SCHEDULES = ("cyclic", "joint")
PAINTS = ("none", "top_and_base", "top_base_and_back")  # lampfab.paint says what each paints


def _spec(default, lo=None, hi=None, choices=None, doc=""):
    return field(default=default, metadata={"lo": lo, "hi": hi, "choices": choices, "doc": doc})


# The bundled inner layer's hollow (``inner.default_inner_mesh``), when no inner_mesh is given:
# 16 mm lets the default post's fins reach 14.5 mm, which keeps more of the next wall's
# LED off each sector's edge; against 12 mm, words gained 0.02-0.04 of SSIM on every wall
# and the horse 0.02-0.035, for about 5 % of the light (bench/log/2026-12-06.md).
DEFAULT_HOLLOW_RADIUS_MM = 16.0


@dataclass(frozen=True)
class Lens:
    kind: str = _spec("cylinder", choices=LENS_KINDS,
                      doc="cylinder: the lamp around its LED; panel: the source's prior-work flat panel ([panel])")
    outer_radius_mm: float = _spec(45.0, 10.0, 300.0, doc="radius of the plain outer cylinder")
    height_mm: float = _spec(90.0, 10.0, 600.0, doc="height of the lens solid, base on z = 0")
    light_height_mm: float = _spec(45.0, 1.0, 599.0, doc="LED centre above the base")
    inner_mesh: str = _spec("", doc="inner layer file (OBJ/PLY/STL/OFF, or GLB read in metres); empty: bundled default")
    hollow_radius_mm: float = _spec(DEFAULT_HOLLOW_RADIUS_MM, 4.0, 40.0,
                                    doc="radius of the bundled inner layer's hollow (a cylinder from z 10 mm, "
                                        "a 45 degree cone roof to z 86 mm); with inner_mesh empty")
    inner_scale: float = _spec(1.0, 1e-4, 1e4, doc="scale applied to the inner mesh (Blender metres -> 1000)")
    max_offset_mm: float = _spec(20.0, 0.1, 100.0, doc="bound on the radial heightmap, both ways")
    black_paint: str = _spec("top_base_and_back", choices=PAINTS,
                             doc="matt black paint on faces that light no wall, where it swallows light reflected "
                                 "inside the lens: none, the flat top and base, or those and the outer surface "
                                 "where no wall's sector lies (none with a floor image)")
    slot_width_mm: float = _spec(0.0, 0.0, 3.0,
                                 doc="a print's blind slots, this wide, at the edges between the walls' sectors, "
                                     "open through the base, that the maker fills with black epoxy: they stop the "
                                     "light reflected inside the glass from crossing to another wall; 0: none "
                                     "(at least 0.5 when set, for the resin to drain and the epoxy to flow)")


@dataclass(frozen=True)
class Panel:
    """The flat panel of the source's prior work (``[lens] kind = "panel"``): a collimated
    beam enters its flat back face and leaves through the relief facing the front wall."""
    width_mm: float = _spec(100.0, 5.0, 2000.0, doc="panel width (x)")
    height_mm: float = _spec(100.0, 5.0, 2000.0, doc="panel height (z), standing on its lower edge")
    thickness_mm: float = _spec(10.0, 1.0, 200.0, doc="flat back face to the relief's middle plane")
    max_relief_mm: float = _spec(4.0, 0.05, 100.0, doc="bound on the relief's offsets, both ways")
    divergence_deg: float = _spec(0.5, 0.0, 10.0, doc="half-angle of the real beam's spread (verify's second render)")


@dataclass(frozen=True)
class Room:
    walls: tuple = _spec(("front", "left", "right"), choices=WALL_NAMES, doc="projection surfaces")
    wall_distance_mm: float = _spec(1000.0, 100.0, 20000.0, doc="light to front/left/right walls")
    target_width_mm: float = _spec(1800.0, 10.0, 20000.0, doc="width of the image on each wall")
    target_height_mm: float = _spec(1350.0, 10.0, 20000.0, doc="height of the image on each wall")
    target_center_z_mm: float = _spec(0.0, -5000.0, 5000.0, doc="image centre height relative to the light")
    floor_depth_mm: float = _spec(800.0, 50.0, 10000.0, doc="light height above the floor")
    floor_center_mm: float = _spec(1200.0, 0.0, 20000.0, doc="floor image centre, behind the lamp")


@dataclass(frozen=True)
class Optimize:
    init: str = _spec("transport", choices=("transport", "cylinder"), doc="first design")
    method: str = _spec("splat", choices=("splat", "ptracer"),
                        doc="refinement: photon splatting (fast) or the source's ptracer")
    grid_u: int = _spec(256, 8, 8192, doc="heightmap nodes around (final level)")
    grid_v: int = _spec(64, 4, 4096, doc="heightmap nodes up (final level)")
    levels: int = _spec(2, 1, 4, doc="coarse-to-fine levels, x4 in u and v between levels")
    iterations: int = _spec(0, 0, 1_000_000, doc="gradient steps in all, split over levels")
    loss: str = _spec("si_mse", choices=LOSSES,
                      doc="per-view loss (si_mse_ssim, multiscale: splat only)")
    loss_weights: tuple = _spec((), doc="weights for l1_weighted, one per wall")
    schedule: str = _spec("cyclic", choices=SCHEDULES, doc="one view per step or all")
    update_rule: str = _spec("adam", choices=("adam", "gd"), doc="Adam or plain gradient descent")
    backtrack: bool = _spec(False, doc="a step after which the loss rises is taken again from where it "
                                       "started, half as long (joint schedule)")
    learning_rate: float = _spec(0.02, 1e-8, 100.0, doc="mm per step scale")
    fine_level_rate: float = _spec(1.0, 0.01, 4.0, doc="tilt per step of the finer levels against the coarsest's")
    fine_level_anneal: bool = _spec(False, doc="the finest level's second half shrinks its step linearly "
                                                "towards zero: its last steps average the photon noise out")
    sensor_px: int = _spec(64, 8, 2048, doc="sensor width in pixels (height from the aspect)")
    spp: int = _spec(16, 1, 65536, doc="samples per pixel per step (ptracer)")
    design_light: str = _spec("point", choices=("point", "led"),
                              doc="the light the refinement designs for: the ideal point, or the LED profile's "
                                  "emitter, whose blurred pictures the walls really get (splat only)")
    splat_photons: int = _spec(1_000_000, 1000, 100_000_000, doc="photons per step (splat), one per cell of an "
                                                                     "even grid of directions: rounded down to fill it")
    fine_level_photons: float = _spec(1.0, 0.1, 16.0, doc="photons per step of the finer levels, times "
                                                           "splat_photons (splat)")
    tessellation: int = _spec(4, 1, 16, doc="mesh vertices per heightmap cell edge (the STL uses the same)")
    transport_rounds: int = _spec(4, 1, 20, doc="fitting steps per transport pass (a panel: position/normal rounds)")
    transport_photons: int = _spec(500_000, 10_000, 100_000_000, doc="photons the transport design traces")
    transport_corrections: int = _spec(3, 0, 20, doc="trace-and-refit passes after the first transport: a lens "
                                                        "spends their steps in passes that end when a step stops paying")
    dump_share: float = _spec(0.1, 0.0, 0.9, doc="light the transport sends above and below the image "
                                                 "(the lens's top and bottom need the steepest slopes)")
    smoothness: float = _spec(1e-2, 0.0, 10.0, doc="curvature penalty of the transport's surface fit")
    slope_weight: float = _spec(200.0, 0.0, 1e6, doc="weight of the slope and overhang penalty in the loss")
    hollow_weight: float = _spec(2000.0, 0.0, 1e6, doc="weight of the hollow penalty in the loss (milled "
                                                       "lenses: hollows the ball-end tool reaches)")
    preview_every: int = _spec(50, 1, 1_000_000, doc="preview images every N steps")
    checkpoint_every: int = _spec(20, 1, 1_000_000, doc="checkpoint every N steps")
    seed: int = _spec(0, 0, 2**31 - 1, doc="random seed")


@dataclass(frozen=True)
class Verify:
    image_px: int = _spec(64, 8, 4096, doc="verify image width in pixels")
    photons: int = _spec(16_000_000, 10_000, 2_000_000_000, doc="photons per verify render (a quarter of them for "
                                                                        "plan's plain lens and the room picture's walls)")
    led_photons: int = _spec(0, 0, 2_000_000_000,
                             doc="photons of the render with the design's own light (its LED, a panel's beam with "
                                 "its spread), whose figures are held against the LED reference (0: as many as "
                                 "photons)")
    study_photons: int = _spec(1_000_000, 10_000, 2_000_000_000,
                               doc="photons per render of the tolerance study (eight or nine renders; the same photons "
                                   "in each, so their differences are not noise)")
    max_bounces: int = _spec(8, 2, 64, doc="interface crossings followed per photon")
    mitsuba_photons: int = _spec(0, 0, 2_000_000_000, doc="light paths per wall and light of Mitsuba's own light "
                                                          "tracer, the second opinion on verify's walls (0: none)")
    scene_px: int = _spec(1280, 16, 4096, doc="width of the report's picture of the lamp in its room (16:9; the close view of "
                                              "the lens is 5/8 as wide, 4:3)")
    scene_spp: int = _spec(8, 1, 65536, doc="path-traced samples per pixel of those pictures (denoised)")


@dataclass(frozen=True)
class Export:
    step_samples_u: int = _spec(256, 16, 4096, doc="most B-spline interpolation samples around (export "
                                                   "takes the fewest within the deviation target)")
    step_samples_v: int = _spec(64, 4, 4096, doc="most B-spline interpolation samples up")


@dataclass(frozen=True)
class Design:
    """A design profile: what to make and how hard to try."""
    name: str
    lens: Lens
    room: Room
    optimize: Optimize
    verify: Verify
    export: Export
    panel: Panel = field(default_factory=Panel)
    path: str = ""


@dataclass(frozen=True)
class Fabrication:
    """A fabrication profile: the material and the machine's limits (sourced numbers)."""
    name: str = _spec("", doc="profile name")
    process: str = _spec("sla", choices=("sla", "cnc3", "cnc4", "glass"), doc="how it is made")
    material: str = _spec("", doc="material name")
    ior: float = _spec(1.49, 1.0, 3.0, doc="refractive index at ~589 nm")
    min_wall_mm: float = _spec(1.5, 0.1, 50.0, doc="thinnest wall between inner and outer surface")
    max_slope_deg: float = _spec(60.0, 1.0, 90.0, doc="steepest outer slope against the radial direction")
    preferred_slope_deg: float = _spec(90.0, 1.0, 90.0, doc="the design keeps its slopes under this (and "
                                       "max_slope_deg) unless its light cannot land otherwise; then it steepens "
                                       "them up to max_slope_deg")
    tool_radius_mm: float = _spec(0.0, 0.0, 50.0, doc="ball-end radius (0: not milled)")
    setups: int = _spec(0, 0, 12, doc="3-axis milling: indexed setups about the lamp axis (0: not indexed)")
    max_tool_angle_deg: float = _spec(90.0, 1.0, 90.0, doc="3-axis: steepest surface against the tool axis")
    build_x_mm: float = _spec(145.0, 1.0, 5000.0, doc="build volume x")
    build_y_mm: float = _spec(145.0, 1.0, 5000.0, doc="build volume y")
    build_z_mm: float = _spec(185.0, 1.0, 5000.0, doc="build volume z")
    mount_radius_mm: float = _spec(6.0, 0.5, 100.0, doc="the smallest bore through the base the process needs "
                                                       "(the LED's board may need a wider one)")
    sector_creases: bool = _spec(False, doc="the outer surface may bend sharply where two walls' sectors meet "
                                           "(a printer makes such an edge, a ball-end tool cannot cut it)")
    surface_error_mm: float = _spec(0.01, 0.0, 5.0, doc="surface error after finishing")
    path: str = ""


LED_SHAPES = SHAPES  # what trace and the design know how to shine


@dataclass(frozen=True)
class Led:
    """An LED profile (``profiles/led/NAME.toml``): the part a maker buys, as the optics see
    it.  Its emitting surface blurs every picture; its board must pass through the bore."""
    name: str = _spec("", doc="profile name")
    part: str = _spec("", doc="what to buy, in words")
    shape: str = _spec("sphere", choices=LED_SHAPES,
                       doc="sphere: a ball glowing every way; cylinder: a filament standing on the lamp axis; "
                           "disc: a flat emitter facing up (a package on its board), nothing below the horizon; "
                           "post: one flat emitter per wall on a post on the axis, each facing its wall")
    radius_mm: float = _spec(1.5, 0.0, 20.0, doc="emitting radius (the ball's, the filament's or the disc's, "
                                                   "a post's LEDs' each); 0: a point")
    length_mm: float = _spec(0.0, 0.0, 100.0, doc="emitting length of a filament (cylinder only)")
    offset_mm: float = _spec(0.0, 0.0, 20.0, doc="how far out from the axis a post's emitting faces are (post only)")
    fin_radius_mm: float = _spec(0.0, 0.0, 50.0, doc="black fins between a post's LEDs reach this far from the axis "
                                                     "(post only; 0: no fins)")
    fin_height_mm: float = _spec(0.0, 0.0, 200.0, doc="the fins' height, centred on the LEDs (post only; 0: no fins)")
    rod_width_mm: float = _spec(0.0, 0.0, 20.0, doc="the square rod a post's LED boards sit on, and the fins' part "
                                                    "slides over (post with fins only)")
    board_diameter_mm: float = _spec(20.0, 1.0, 200.0, doc="the board or holder that must pass through the bore")
    flux_lm: float = _spec(100.0, 0.1, 100_000.0, doc="typical luminous flux (lumen) at its usual current")
    path: str = ""


SECTIONS = {"lens": Lens, "room": Room, "optimize": Optimize, "verify": Verify, "export": Export, "panel": Panel}


def _check_value(cls, f: dataclasses.Field, value: Any, where: str) -> Any:
    default = f.default
    meta = f.metadata
    if isinstance(default, bool):
        ok = isinstance(value, bool)
        allowed = "true or false"
    elif isinstance(default, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
        allowed = "an integer"
    elif isinstance(default, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        value = float(value) if ok else value
        allowed = "a number"
    elif isinstance(default, tuple):
        ok = isinstance(value, list)
        value = tuple(value) if ok else value
        allowed = "a list"
    else:
        ok = isinstance(value, str)
        allowed = "a string"
    if not ok:
        raise LampfabError(f"{where}: expected {allowed}, got {value!r}")
    lo, hi, choices = meta.get("lo"), meta.get("hi"), meta.get("choices")
    if lo is not None and not (lo <= value <= hi):
        raise LampfabError(f"{where}: {value!r} is out of range; allowed {lo} to {hi}")
    if choices is not None:
        items = value if isinstance(value, tuple) else (value,)
        bad = [v for v in items if v not in choices]
        if bad:
            raise LampfabError(f"{where}: {bad[0]!r} is not allowed; choose from {', '.join(choices)}")
    return value


def _build(cls, table: dict, path: Path, section: str, origins: dict | None = None):
    """``cls`` from a profile's ``table``; errors name the file that set the key
    (``origins`` {(section, key): path}, else ``path``)."""
    known = {f.name: f for f in dataclasses.fields(cls) if f.name != "path"}
    values = {}
    for key, value in table.items():
        source = (origins or {}).get((section, key), path)
        where = f"{source}: [{section}] {key}" if section else f"{source}: {key}"
        if key not in known:
            raise LampfabError(f"{where}: unknown key; allowed: {', '.join(sorted(known))}")
        values[key] = _check_value(cls, known[key], value, where)
    return cls(**values)


def load_design(name_or_path: str) -> Design:
    path = resolve(name_or_path, PROFILE_DIR)
    data, origins = design_tables(path, SECTIONS)
    parts = {}
    for section, cls in SECTIONS.items():
        parts[section] = _build(cls, data.get(section, {}), path, section, origins)
    design = Design(name=path.stem, path=str(path), **parts)
    if design.lens.inner_mesh and "hollow_radius_mm" in data.get("lens", {}):
        raise LampfabError(f"{path}: [lens] hollow_radius_mm sizes the bundled inner layer, and inner_mesh "
                           f"replaces it with {design.lens.inner_mesh}: set one of them")
    if design.lens.kind == "panel":
        _check_panel(design, data, path)
    else:
        if "panel" in data:
            raise LampfabError(f"{path}: [panel] applies only to [lens] kind = \"panel\"")
        _check_design(design, path)
    return design


def load_fabrication(name_or_path: str) -> Fabrication:
    path = resolve(name_or_path, PROFILE_DIR / "fab")
    data = read_toml(path)
    fab = _build(Fabrication, data, path, "")
    if not fab.name:
        fab = dataclasses.replace(fab, name=path.stem)
    if fab.process == "cnc3" and fab.setups < 2:
        raise LampfabError(f"{path}: setups {fab.setups}: 3-axis milling (process cnc3) needs at least 2 setups "
                           f"(the part is turned about the lamp axis between them)")
    if "preferred_slope_deg" in data and fab.preferred_slope_deg > fab.max_slope_deg:
        raise LampfabError(f"{path}: preferred_slope_deg {fab.preferred_slope_deg:g} is steeper than max_slope_deg "
                           f"{fab.max_slope_deg:g}; allowed: 1 to max_slope_deg")
    return dataclasses.replace(fab, path=str(path))


def load_led(name_or_path: str) -> Led:
    path = resolve(name_or_path, PROFILE_DIR / "led")
    led = _build(Led, read_toml(path), path, "")
    if led.shape == "cylinder" and not led.length_mm > 0:
        raise LampfabError(f"{path}: length_mm {led.length_mm}: a filament (shape cylinder) needs a length above 0")
    if led.shape != "cylinder" and led.length_mm:
        raise LampfabError(f"{path}: length_mm applies only to shape = \"cylinder\" (a filament)")
    for key in ("offset_mm", "fin_radius_mm", "fin_height_mm", "rod_width_mm"):
        if led.shape != "post" and getattr(led, key):
            raise LampfabError(f"{path}: {key} applies only to shape = \"post\" (LEDs on a post's faces)")
    if (led.fin_radius_mm > 0) != (led.fin_height_mm > 0):
        raise LampfabError(f"{path}: fin_radius_mm and fin_height_mm go together: set both above 0, or neither")
    if 0 < led.fin_radius_mm <= led.offset_mm + led.radius_mm:
        raise LampfabError(f"{path}: fin_radius_mm {led.fin_radius_mm:g}: the fins must reach past the LEDs "
                           f"(offset_mm + radius_mm = {led.offset_mm + led.radius_mm:g}); allowed: above that, to 50")
    if 2 * led.fin_radius_mm >= led.board_diameter_mm:
        raise LampfabError(f"{path}: fin_radius_mm {led.fin_radius_mm:g}: the fins ({2 * led.fin_radius_mm:g} mm across) "
                           f"must slide through the bore made for board_diameter_mm {led.board_diameter_mm:g}; "
                           f"allowed: under {led.board_diameter_mm / 2:g}")
    if led.fin_radius_mm and not 0 < led.rod_width_mm / 2 < led.offset_mm:
        raise LampfabError(f"{path}: rod_width_mm {led.rod_width_mm:g}: a post with fins needs the square rod its "
                           f"boards sit on and its fins slide over; allowed: above 0, under 2 x offset_mm "
                           f"({2 * led.offset_mm:g})")
    return dataclasses.replace(led, name=led.name or path.stem, path=str(path))


def check_led_for(design: Design, led: Led) -> None:
    """Refuse an LED that cannot light the design's walls: a flat one facing up sends no
    light below the horizon, where the floor's picture must come from (the lens's back
    sector bends the downward light onto it; the upward light is the other walls')."""
    if led.shape == "disc" and "floor" in design.room.walls:
        raise LampfabError(f"{led.path}: a flat LED facing up (shape disc) sends no light below the horizon, and "
                           f"{design.path} has a floor picture ([room] walls): choose LEDs that face the walls "
                           f"(LED=post3535, one faces the floor's part of the lens) or leave out the floor")


def check_fab_for(design: Design, fab: Fabrication) -> None:
    """Refuse slots on a lens that is not printed: no tool cuts a slot a millimetre wide
    and several centimetres deep."""
    if design.lens.slot_width_mm and fab.process != "sla":
        raise LampfabError(f"{design.path}: [lens] slot_width_mm {design.lens.slot_width_mm:g}: slots are for a "
                           f"printed lens, and {fab.path} is made by {fab.process} (no tool cuts them); set it to 0 "
                           f"or print the lens (FAB=sla_resin)")


def with_bore_for(fab: Fabrication, led: Led) -> Fabrication:
    """``fab`` with its bore widened, where needed, so that ``led``'s board passes through."""
    return dataclasses.replace(fab, mount_radius_mm=max(fab.mount_radius_mm, led.board_diameter_mm / 2))


def _check_design(d: Design, path: Path) -> None:
    """Relations between keys that single ranges cannot express."""
    lens, room, opt = d.lens, d.room, d.optimize
    if not 0 < lens.light_height_mm < lens.height_mm:
        raise LampfabError(f"{path}: [lens] light_height_mm {lens.light_height_mm} must lie inside the lens "
                           f"(0 to height_mm {lens.height_mm})")
    if lens.max_offset_mm >= lens.outer_radius_mm:
        raise LampfabError(f"{path}: [lens] max_offset_mm must be below outer_radius_mm")
    if 0 < lens.slot_width_mm < 0.5:
        raise LampfabError(f"{path}: [lens] slot_width_mm {lens.slot_width_mm:g}: allowed 0 (no slots) or 0.5 to 3 "
                           f"(narrower, the resin does not drain nor the epoxy flow)")
    if room.wall_distance_mm <= 2 * lens.outer_radius_mm:
        raise LampfabError(f"{path}: [room] wall_distance_mm must exceed the lens diameter (walls behind or inside the lamp)")
    if not room.walls:
        raise LampfabError(f"{path}: [room] walls must name at least one of {', '.join(WALL_NAMES)}")
    if len(set(room.walls)) != len(room.walls):
        raise LampfabError(f"{path}: [room] walls lists a wall twice")
    if "floor" in room.walls and room.floor_depth_mm <= lens.light_height_mm:
        raise LampfabError(f"{path}: [room] floor_depth_mm must exceed light_height_mm (the floor is below the lamp)")
    if opt.loss in NUMPY_ONLY_LOSSES and opt.method != "splat":
        raise LampfabError(f"{path}: [optimize] loss \"{opt.loss}\" needs method \"splat\" (the {opt.method} "
                           f"method takes {', '.join(n for n in LOSSES if n not in NUMPY_ONLY_LOSSES)})")
    if opt.loss == "l1_weighted" and len(opt.loss_weights) != len(room.walls):
        raise LampfabError(f"{path}: [optimize] loss_weights needs one weight per wall ({len(room.walls)})")
    if opt.design_light == "led" and opt.method != "splat":
        raise LampfabError(f"{path}: [optimize] design_light \"led\" needs method \"splat\" (the {opt.method} "
                           f"method designs for the point light)")
    if opt.fine_level_photons != 1.0 and opt.method != "splat":
        raise LampfabError(f"{path}: [optimize] fine_level_photons needs method \"splat\" (the {opt.method} "
                           f"method renders spp samples per pixel on every level)")
    if opt.backtrack and opt.schedule != "joint":
        raise LampfabError(f"{path}: [optimize] backtrack needs schedule \"joint\" (with one view per step, "
                           f"one step's loss does not compare with the next)")
    coarse = 4 ** (opt.levels - 1)
    if opt.grid_u % (8 * coarse):
        raise LampfabError(f"{path}: [optimize] grid_u must be divisible by 8 x 4^(levels-1) = {8 * coarse} "
                           f"(the sector boundaries fall on nodes at every level)")
    if opt.grid_u // coarse < 16 or opt.grid_v // coarse < 4:
        raise LampfabError(f"{path}: [optimize] the coarsest level would be below 16 x 4 nodes; lower levels")


def _check_panel(d: Design, data: dict, path: Path) -> None:
    """A panel profile: only the keys that mean something for a panel, and sizes that fit."""
    cylinder_only = sorted(set(data.get("lens", {})) - {"kind"})
    if cylinder_only:
        raise LampfabError(f"{path}: [lens] {cylinder_only[0]} applies only to kind = \"cylinder\"; a panel's "
                           f"sizes go in [panel]")
    p, room, opt = d.panel, d.room, d.optimize
    if tuple(room.walls) != ("front",):
        raise LampfabError(f"{path}: [room] walls must be [\"front\"] for a panel (it lights the wall it faces)")
    if p.max_relief_mm >= p.thickness_mm:
        raise LampfabError(f"{path}: [panel] max_relief_mm {p.max_relief_mm} must be below thickness_mm "
                           f"{p.thickness_mm} (the relief would cut through the back face)")
    if room.wall_distance_mm <= p.thickness_mm + p.max_relief_mm:
        raise LampfabError(f"{path}: [room] wall_distance_mm must exceed the panel's thickness plus its relief")
    if opt.init != "transport" or opt.iterations:
        raise LampfabError(f"{path}: [optimize] a panel is designed by transport alone: init must be "
                           f"\"transport\" and iterations 0")


def as_dict(obj) -> dict:
    """A profile as plain JSON-able data (for reports)."""
    return dataclasses.asdict(obj)
