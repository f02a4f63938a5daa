"""The LED as the optics see it: where it is, what glows, and which way it shines.

Three shapes (``profile.LED_SHAPES``):

- ``sphere``: a ball glowing the same in every direction (an LED inside a small opal
  ball).
- ``cylinder``: a filament standing on the lamp axis, its ends dark: light all round.
- ``disc``: a flat emitter facing up (+z), Lambertian: an LED package on its board, the
  board passing up through the bore.  Its intensity falls as the cosine of the angle
  from straight up, and nothing goes below the horizon.

A point (``radius_mm`` 0) keeps its shape's beam: a ball's or a filament's shines
evenly every way, a disc's as the cosine from straight up.  So a design's "point light"
is always the same beam from one point: what a perfect lens would show with an
infinitely small emitter of that kind.  (A filament's own light is brightest side-on;
its point keeps the ball's even beam, which its length's blur dwarfs.)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

SHAPES = ("sphere", "cylinder", "disc")


@dataclass(frozen=True)
class Source:
    """An LED: ``position_mm`` (x, y, z) mm its centre (a disc's emitting face);
    ``shape`` one of ``SHAPES``; ``radius_mm`` the ball's, the filament's or the disc's
    (0: a point with the shape's beam); ``length_mm`` a filament's emitting length."""
    position_mm: tuple[float, float, float]
    shape: str = "sphere"
    radius_mm: float = 0.0
    length_mm: float = 0.0

    def __post_init__(self):
        if self.shape not in SHAPES:
            raise ValueError(f"shape {self.shape!r}: one of {', '.join(SHAPES)}")
        object.__setattr__(self, "position_mm", tuple(float(c) for c in self.position_mm))

    @staticmethod
    def of_led(position_mm: np.ndarray, led) -> "Source":
        """A ``profile.Led`` at ``position_mm`` (3,) mm."""
        return Source(tuple(position_mm), led.shape, led.radius_mm, led.length_mm)

    @staticmethod
    def from_json(light: dict) -> "Source":
        """design.json's ``light`` (``kind.light_json``); one written before it named
        its shape is a filament when it has a length, else a ball."""
        length = light.get("length", 0.0)
        shape = light.get("shape") or ("cylinder" if length > 0 else "sphere")
        return Source(tuple(light["position"]), shape, light["radius"], length)

    @property
    def position(self) -> np.ndarray:
        """(3,) float64 mm."""
        return np.asarray(self.position_mm, np.float64)

    @property
    def facing_up(self) -> bool:
        """True when no light leaves below the horizon."""
        return self.shape == "disc"

    def point(self) -> "Source":
        """The same beam from a point at the centre."""
        return dataclasses.replace(self, radius_mm=0.0, length_mm=0.0)

    def intensity(self, directions: np.ndarray) -> np.ndarray:
        """Relative radiant intensity towards unit ``directions`` (n, 3): (n,) float64
        whose mean over the whole sphere of directions is 1 (a disc: 4 cos from up,
        0 below the horizon; the others: 1)."""
        directions = np.asarray(directions, np.float64)
        if self.facing_up:
            return 4.0 * np.maximum(directions[:, 2], 0.0)
        return np.ones(len(directions))

    def describe(self) -> str:
        """The light in a few words, for reports."""
        if self.shape == "cylinder" and self.length_mm > 0:
            return f"{self.length_mm:g} mm filament"
        if self.shape == "disc":
            return f"flat LED {self.radius_mm:g} mm facing up"
        return f"LED {self.radius_mm:g} mm"
