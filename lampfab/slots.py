"""Blind slots at the edges between the lens's sectors, filled black (a print's option).

About 4 % of the light is reflected back into the glass where it leaves the outer
surface.  Near the edge of a wall's sector part of it runs on through the glass as a
chord that never enters the hollow (where a post's fins stop what crosses), into another
wall's sector, and leaves there as a haze over that wall's picture: on the apple the
right sector's reflections are 0.9 % of the left wall's light
(``bench/light_in_black.py --sectors``).  A thin slot standing radially at every edge
between two sectors, its walls in optical contact with black epoxy, ends those chords.
Behind an air gap it would not: they meet a slot's wall at about 45°, past the critical
angle, and are reflected whole.

Each slot is a box ``width_mm`` wide, centred on its sector edge, from ``from_mm`` to
``to_mm`` out from the axis, open through the base (the maker fills it from below) and
closed ``TOP_MARGIN_MM`` under the top.  It keeps the fabrication profile's thinnest wall
from the cavity and from the outer surface, so the outer surface stays whole: a slot cut
through it left crossing facets where the cut met the surface's creases (bench/log).

The slots also shade the LEDs' light near each edge (a 1 mm slot 17 mm out about 3.4°)
and end the light that crosses an edge inside the glass: a lens designed without them
had steered that light into its pictures, which then showed dark spots (the apple's
front wall −0.03 of SSIM).  So the refinement stops its photons in them (``stops``), and
verify, the reference render and the pictures of the lamp trace their walls black, as
made.  Measured: bench/RESULTS.md, "Black-filled slots, an option".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import LampfabError

# Chosen: the glass left whole above the slots holds the lens's four quarters together
# while it is printed, washed and filled (its walls beside the slots are a print's
# thinnest); measured with slots up to 85 mm in the 90 mm lens (bench/log).
TOP_MARGIN_MM = 5.0

# The boxes start this far below the base, so the cut opens the base cleanly (no face
# of the box coincides with it).
BELOW_BASE_MM = 1.0

# A slot shorter than this (radially, mm) stops too few chords to be worth filling: where
# the outer surface comes this close to the cavity at a sector edge, plan refuses.
MIN_LENGTH_MM = 3.0

# A facet lies on a slot's wall when its centre is within this of the box (mm): the
# booleans put the walls' facets exactly on the box's planes, and every other facet of
# the lens keeps at least the profile's thinnest wall (0.1 mm at the least) away.
ON_WALL_MM = 1e-3


@dataclass(frozen=True)
class Slot:
    """One slot: its sector edge (deg, u = atan2(y, x)) and its reach from the axis (mm)."""
    azimuth_deg: float
    from_mm: float
    to_mm: float


@dataclass(frozen=True)
class Slots:
    """A lens's slots, ``width_mm`` wide and ``top_mm`` high (the lamp's axis at x = y = 0,
    the base on z = 0)."""
    width_mm: float
    top_mm: float
    slots: tuple[Slot, ...]

    def to_json(self) -> dict:
        return {"width_mm": self.width_mm, "top_mm": self.top_mm,
                "slots": [{"azimuth_deg": s.azimuth_deg, "from_mm": s.from_mm, "to_mm": s.to_mm} for s in self.slots]}

    @staticmethod
    def from_json(d: dict | None) -> "Slots | None":
        """The slots design.json's or solid.json's record describes; None for none."""
        if not d:
            return None
        return Slots(float(d["width_mm"]), float(d["top_mm"]),
                     tuple(Slot(float(s["azimuth_deg"]), float(s["from_mm"]), float(s["to_mm"])) for s in d["slots"]))

    @property
    def glass_mm3(self) -> float:
        """The glass the slots take out of the lens (mm^3): the boxes above the base."""
        return float(sum((s.to_mm - s.from_mm) * self.width_mm * self.top_mm for s in self.slots))

    def outlines(self) -> list[np.ndarray]:
        """Each slot's cross-section, (4, 2) float64 mm, counter-clockwise."""
        out = []
        for s in self.slots:
            along, across = _axes(s.azimuth_deg)
            half = 0.5 * self.width_mm
            out.append(np.array([s.from_mm * along - half * across, s.to_mm * along - half * across,
                                 s.to_mm * along + half * across, s.from_mm * along + half * across]))
        return out

    def manifold(self):
        """The slots' boxes as one manifold3d solid, for cutting from the lens."""
        import manifold3d

        height = self.top_mm + BELOW_BASE_MM
        out = None
        for outline in self.outlines():
            box = manifold3d.CrossSection([outline]).extrude(height).translate((0.0, 0.0, -BELOW_BASE_MM))
            out = box if out is None else out + box
        return out

    def stops(self, mi, o, d):
        """Dr.Jit Bool per ray: the rays from ``o`` (Point3f, mm) along ``d`` (Vector3f)
        that enter a slot ahead (slab test on each box).  For photons in the glass,
        before they leave it: the boxes lie inside the glass, so a ray meets one before it
        reaches the outer surface."""
        import drjit as dr

        stopped = dr.zeros(mi.Bool, dr.width(d))
        half = 0.5 * self.width_mm
        for s in self.slots:
            along, across = _axes(s.azimuth_deg)
            enter, leave = dr.zeros(mi.Float, dr.width(d)), dr.full(mi.Float, dr.inf, dr.width(d))
            for axis, lo, hi in (((*along, 0.0), s.from_mm, s.to_mm), ((*across, 0.0), -half, half),
                                 ((0.0, 0.0, 1.0), 0.0, self.top_mm)):
                v = mi.Vector3f(*map(float, axis))
                start, rate = dr.dot(o, v), dr.dot(d, v)
                # Parallel to a slab, t1 and t2 are infinite: of opposite signs inside it (no
                # bound), of the same sign outside (never in it).
                t1, t2 = (lo - start) / rate, (hi - start) / rate
                enter = dr.maximum(enter, dr.minimum(t1, t2))
                leave = dr.minimum(leave, dr.maximum(t1, t2))
            stopped |= enter < leave
        return stopped

    def on_walls(self, centres: np.ndarray) -> np.ndarray:
        """(m,) bool: the facets whose centres ((m, 3) float64 mm) lie on a slot's walls
        or roof."""
        out = np.zeros(len(centres), bool)
        within_z = (centres[:, 2] > -ON_WALL_MM) & (centres[:, 2] < self.top_mm + ON_WALL_MM)
        for s in self.slots:
            axes = _axes(s.azimuth_deg)
            along, across = centres[:, :2] @ axes[0], centres[:, :2] @ axes[1]
            out |= (within_z & (along > s.from_mm - ON_WALL_MM) & (along < s.to_mm + ON_WALL_MM)
                    & (np.abs(across) < 0.5 * self.width_mm + ON_WALL_MM))
        return out


def _axes(azimuth_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """A slot's frame in the xy plane: (along it, out from the axis; across it, a quarter
    turn counter-clockwise), unit (2,) float64."""
    a = np.radians(azimuth_deg)
    return np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])


def sector_edges_deg(sectors_deg: dict[str, tuple[float, float]]) -> tuple[float, ...]:
    """The azimuths (deg in [0, 360), ascending) where a wall's sector ends, from the
    design's sectors {wall: (start, end) deg}: each sector's two ends, once each."""
    edges: list[float] = []
    for lo, hi in sectors_deg.values():
        for a in (lo % 360.0, hi % 360.0):
            if all(min(abs(a - e), 360.0 - abs(a - e)) > 1e-6 for e in edges):
                edges.append(a)
    return tuple(sorted(edges))


def plan(width_mm: float, sectors_deg: dict[str, tuple[float, float]], cavity_reach_mm: float,
         outer_vertices: np.ndarray, height_mm: float, min_wall_mm: float) -> Slots | None:
    """The slots, ``width_mm`` wide (0: none), at the design's sector edges.

    cavity_reach_mm: the farthest the cavity (inner layer and bore) reaches from the axis;
    outer_vertices (n, 3) float64 mm: the outer surface's vertices (a fine mesh: the
    facets between them bulge by well under a micron); min_wall_mm: the glass every slot
    keeps from the cavity and from the outer surface (3D distance).  Raises
    LampfabError when the outer surface comes so close to the cavity at an edge that a
    slot there would be under ``MIN_LENGTH_MM`` long, or the lens is too short."""
    if width_mm <= 0:
        return None
    top = height_mm - TOP_MARGIN_MM
    if top <= min_wall_mm:
        raise LampfabError(f"slots: the lens ({height_mm:g} mm tall) is too short for slots closed "
                           f"{TOP_MARGIN_MM:g} mm under its top")
    start = cavity_reach_mm + min_wall_mm
    half = 0.5 * width_mm
    slots = []
    for edge in sector_edges_deg(sectors_deg):
        axes = _axes(edge)
        along = outer_vertices[:, :2] @ axes[0]
        beside = np.maximum(np.abs(outer_vertices[:, :2] @ axes[1]) - half, 0.0)
        above = np.maximum(outer_vertices[:, 2] - top, 0.0)
        near = beside ** 2 + above ** 2
        close = (along > 0) & (near < min_wall_mm ** 2)
        # The box's outer face keeps min_wall_mm from every surface point beside or above it.
        if not close.any():
            raise LampfabError(f"slots: no outer surface found at the sector edge u = {edge:.1f} deg")
        end = float(np.min(along[close] - np.sqrt(min_wall_mm ** 2 - near[close])))
        if not end - start >= MIN_LENGTH_MM:
            raise LampfabError(
                f"slots: at the sector edge u = {edge:.1f} deg the outer surface comes in to "
                f"{end + min_wall_mm:.1f} mm from the axis, leaving a slot from {start:.1f} to {end:.1f} mm "
                f"(under {MIN_LENGTH_MM:g} mm with {min_wall_mm:g} mm walls); set [lens] slot_width_mm = 0")
        # To the micron, inwards: what solid.json records is what was cut, to the digit.
        slots.append(Slot(float(edge), math.ceil(start * 1e6) / 1e6, math.floor(end * 1e6) / 1e6))
    return Slots(float(width_mm), top, tuple(slots))
