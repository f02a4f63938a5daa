"""The LED as the optics see it: where it is, what glows, and which way it shines.

Four shapes (``profile.LED_SHAPES``):

- ``sphere``: a ball glowing the same in every direction (an LED inside a small opal
  ball).
- ``cylinder``: a filament standing on the lamp axis, its ends dark: light all round.
- ``disc``: a flat emitter facing up (+z), Lambertian: an LED package on its board, the
  board passing up through the bore.  Its intensity falls as the cosine of the angle
  from straight up, and nothing goes below the horizon.
- ``post``: one such flat LED per wall, on the faces of a small post standing on the
  axis, each ``offset_mm`` out from the axis and facing its wall's sector of the lens
  level (``facing_deg``, the sectors' centres): light goes out level, where the walls
  are, as the ball's does, from parts a maker can buy.  Black fins between the LEDs
  (``fin_radius_mm`` out from the axis, ``fin_height_mm`` tall, at the sectors' edges)
  keep each LED's light to its own sector: a lens patch near a sector's edge then sees
  one LED, not two a few millimetres apart (a double image).

A point (``radius_mm`` 0) keeps its shape's beam: a ball's or a filament's shines
evenly every way, a disc's as the cosine from straight up, a post's as its LEDs' cosines,
each from the centre of its face.  So a design's "point light" is always the same beam
from a point (a post's: one per face): what a perfect lens would show with an
infinitely small emitter of that kind.  (A filament's own light is brightest side-on;
its point keeps the ball's even beam, which its length's blur dwarfs.)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

SHAPES = ("sphere", "cylinder", "disc", "post")
FLAT = ("disc", "post")  # Lambertian faces: light only in front of each
SECTOR_HALF_DEG = 45.0  # a wall's sector of the lens spans 90° (room.SECTOR_CENTRE_DEG)


@dataclass(frozen=True)
class Source:
    """An LED: ``position_mm`` (x, y, z) mm its centre (a disc's emitting face);
    ``shape`` one of ``SHAPES``; ``radius_mm`` the ball's, the filament's or the disc's
    (0: a point with the shape's beam); ``length_mm`` a filament's emitting length;
    ``facing_deg`` the azimuths (degrees from +x) a post's LEDs face, ``offset_mm`` how
    far out from the axis their faces are; ``fin_radius_mm`` and ``fin_height_mm`` its
    fins' size (0: none)."""
    position_mm: tuple[float, float, float]
    shape: str = "sphere"
    radius_mm: float = 0.0
    length_mm: float = 0.0
    facing_deg: tuple[float, ...] = ()
    offset_mm: float = 0.0
    fin_radius_mm: float = 0.0
    fin_height_mm: float = 0.0

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f"shape {self.shape!r}: one of {', '.join(SHAPES)}")
        if (self.shape == "post") != bool(self.facing_deg):
            raise ValueError("a post, and only a post, faces azimuths (facing_deg)")
        if self.fins and self.shape != "post":
            raise ValueError("only a post has fins")
        object.__setattr__(self, "position_mm", tuple(float(c) for c in self.position_mm))
        object.__setattr__(self, "facing_deg", tuple(float(a) for a in self.facing_deg))

    @staticmethod
    def of_led(position_mm: np.ndarray, led, facing_deg=()) -> "Source":
        """A ``profile.Led`` at ``position_mm`` (3,) mm; a post's LEDs face the azimuths
        ``facing_deg`` (degrees, the walls' sectors)."""
        facing = tuple(facing_deg) if led.shape == "post" else ()
        return Source(tuple(position_mm), led.shape, led.radius_mm, led.length_mm, facing, led.offset_mm,
                      led.fin_radius_mm, led.fin_height_mm)

    @staticmethod
    def from_json(light: dict) -> "Source":
        """design.json's ``light`` (``kind.light_json``); one written before it named
        its shape is a filament when it has a length, else a ball."""
        length = light.get("length", 0.0)
        shape = light.get("shape") or ("cylinder" if length > 0 else "sphere")
        return Source(tuple(light["position"]), shape, light["radius"], length, tuple(light.get("facing_deg", ())),
                      light.get("offset_mm", 0.0), light.get("fin_radius_mm", 0.0), light.get("fin_height_mm", 0.0))

    @property
    def position(self) -> np.ndarray:
        """(3,) float64 mm."""
        return np.asarray(self.position_mm, np.float64)

    @property
    def facing_up(self) -> bool:
        """True when no light leaves below the horizon."""
        return self.shape == "disc"

    @property
    def fins(self) -> bool:
        """True when black fins keep each of a post's LEDs to its own sector."""
        return self.fin_radius_mm > 0 and self.fin_height_mm > 0

    def fin_azimuths_deg(self) -> np.ndarray:
        """(f,) float64 degrees in [0, 360), ascending: each fin once, the fins standing
        either side of each LED, ``SECTOR_HALF_DEG`` from the way it faces."""
        both = np.asarray(self.facing_deg)[:, None] + np.array([-SECTOR_HALF_DEG, SECTOR_HALF_DEG])
        return np.unique(both % 360.0)

    @property
    def normals(self) -> np.ndarray:
        """(k, 3) float64: the unit normals of a disc's or a post's flat emitters."""
        if self.shape == "disc":
            return np.array([[0.0, 0.0, 1.0]])
        a = np.radians(np.asarray(self.facing_deg))
        return np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)

    @property
    def face_centres(self) -> np.ndarray:
        """(k, 3) float64 mm: the centre of each of a post's LEDs, or the centre alone."""
        if self.shape == "post":
            return self.position + self.offset_mm * self.normals
        return self.position[None, :]

    def point(self) -> "Source":
        """The same beam from a point: the centre, or each of a post's faces' centres
        (the design places its light by where they are)."""
        return dataclasses.replace(self, radius_mm=0.0, length_mm=0.0)

    def intensity(self, directions: np.ndarray) -> np.ndarray:
        """Relative radiant intensity towards unit ``directions`` (n, 3): (n,) float64
        whose mean over the whole sphere of directions is 1 (a disc: 4 cos from up,
        0 below the horizon; a post: the mean of its LEDs' 4 cos; the others: 1).  A post's
        fins leave each LED the azimuths up to its fins' tips, as seen from its face, and
        take the rest: the mean is then under 1."""
        directions = np.asarray(directions, np.float64)
        if self.shape in FLAT:
            return 4.0 / len(self.normals) * self._face_cosines(directions).sum(axis=1)
        return np.ones(len(directions))

    def origins(self, directions: np.ndarray) -> np.ndarray:
        """Where the light of ``point()`` leaving in each of the unit ``directions`` (n, 3)
        starts: (n, 3) float64 mm, the centre, or for a post the centre of the face that
        sends it (the one it leaves most squarely, within the fins).  Directions no face
        sends start at the centre."""
        directions = np.asarray(directions, np.float64)
        start = np.broadcast_to(self.position, directions.shape).copy()
        if self.shape == "post":
            cosines = self._face_cosines(directions)
            face = np.argmax(cosines, axis=1)
            lit = cosines.max(axis=1) > 0.0
            start[lit] = self.face_centres[face[lit]]
        return start

    def _face_cosines(self, directions: np.ndarray) -> np.ndarray:
        """(n, k) float64: the cosine of each of the unit ``directions`` (n, 3) from each
        flat face's normal, 0 behind it and, for a post with fins, outside the azimuths
        its fins leave it (up to their tips, as seen from its face)."""
        cosines = np.maximum(directions @ self.normals.T, 0.0)
        if self.fins:
            azimuth = np.degrees(np.arctan2(directions[:, 1], directions[:, 0]))
            off = (azimuth[:, None] - np.asarray(self.facing_deg)[None, :] + 180.0) % 360.0 - 180.0
            half = np.radians(SECTOR_HALF_DEG)
            window = np.degrees(np.arctan2(self.fin_radius_mm * np.sin(half),
                                           self.fin_radius_mm * np.cos(half) - self.offset_mm))
            cosines = np.where(np.abs(off) <= window, cosines, 0.0)
        return cosines

    def describe(self) -> str:
        """The light in a few words, for reports."""
        if self.shape == "cylinder" and self.length_mm > 0:
            return f"{self.length_mm:g} mm filament"
        if self.shape == "disc":
            return f"flat LED {self.radius_mm:g} mm facing up"
        if self.shape == "post":
            return f"{len(self.facing_deg)} flat LEDs {self.radius_mm:g} mm " + ("between fins" if self.fins else "facing out")
        return f"LED {self.radius_mm:g} mm"
