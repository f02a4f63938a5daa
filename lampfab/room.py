"""The room: where each projection surface is, in the lamp (STL) frame, mm.

The lamp stands with its axis on z; the viewer stands at the open back (-y) and faces
the front wall (+y).  Left wall at x = -D, right wall at x = +D, the floor image lies
behind the lamp (-y) where the viewer looks down at it.  Each lens sector of 90° in u
sends its light to the surface it faces (front: u = 90°, left: 180°, right: 0°,
floor: 270°).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .profile import Design

SECTOR_CENTRE_DEG = {"right": 0.0, "front": 90.0, "left": 180.0, "floor": 270.0}
SECTOR_WIDTH_DEG = 90.0


@dataclass(frozen=True)
class Wall:
    """A target rectangle: ``origin`` is the image's top-left corner; ``right`` and
    ``down`` span its full width and height.  (3,) float64 mm each."""
    name: str
    origin: np.ndarray
    right: np.ndarray
    down: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        """Unit normal facing the lamp side."""
        n = np.cross(self.down, self.right)
        return n / np.linalg.norm(n)

    @property
    def width_mm(self) -> float:
        return float(np.linalg.norm(self.right))

    @property
    def height_mm(self) -> float:
        return float(np.linalg.norm(self.down))

    @property
    def centre(self) -> np.ndarray:
        """(3,) float64 mm: the middle of the image."""
        return self.origin + 0.5 * (self.right + self.down)

    def sector_deg(self) -> tuple[float, float]:
        c = SECTOR_CENTRE_DEG[self.name]
        return c - SECTOR_WIDTH_DEG / 2, c + SECTOR_WIDTH_DEG / 2

    def to_json(self, target: str) -> dict:
        return {"name": self.name, "origin": self.origin.tolist(), "right": self.right.tolist(),
                "down": self.down.tolist(), "target": target}

    @staticmethod
    def from_json(d: dict) -> "Wall":
        return Wall(d["name"], np.asarray(d["origin"], float), np.asarray(d["right"], float),
                    np.asarray(d["down"], float))


def light_position(design: Design) -> np.ndarray:
    """(3,) float64 mm: the LED centre on the lamp axis (a panel: the centre of its
    flat back face, where the collimated beam enters)."""
    if design.lens.kind == "panel":
        return np.array([0.0, 0.0, design.panel.height_mm / 2])
    return np.array([0.0, 0.0, design.lens.light_height_mm])


def walls(design: Design) -> list[Wall]:
    """The projection surfaces named in the profile, in profile order."""
    room = design.room
    light = light_position(design)
    d = room.wall_distance_mm
    w, h = room.target_width_mm, room.target_height_mm
    zc = light[2] + room.target_center_z_mm
    down = np.array([0.0, 0.0, -h])
    frames = {
        # name: (centre of the image, right vector)
        "front": (np.array([0.0, d, zc]), np.array([w, 0.0, 0.0])),
        "left": (np.array([-d, 0.0, zc]), np.array([0.0, w, 0.0])),
        "right": (np.array([d, 0.0, zc]), np.array([0.0, -w, 0.0])),
    }
    out = []
    for name in room.walls:
        if name == "floor":
            centre = np.array([0.0, -room.floor_center_mm, light[2] - room.floor_depth_mm])
            right = np.array([w, 0.0, 0.0])
            fdown = np.array([0.0, -h, 0.0])  # away from the lamp, towards the viewer
            out.append(Wall("floor", centre - 0.5 * (right + fdown), right, fdown))
        else:
            centre, right = frames[name]
            out.append(Wall(name, centre - 0.5 * (right + down), right, down))
    return out


def image_shape(wall: Wall, width_px: int) -> tuple[int, int]:
    """(rows, cols) of a wall image ``width_px`` wide with the wall's aspect ratio."""
    rows = max(1, int(round(width_px * wall.height_mm / wall.width_mm)))
    return rows, width_px
