"""Which wall each part of the lens serves, and how the light sees each wall's picture.

Each 90° sector of the lens sends its light to the wall it faces (the source's 5.2),
turned towards its picture's light where that sits off centre (``sector_spans``); a
photon belongs to the sector it leaves the light in, unless no makeable slope brings it
to its wall or it meets the outer surface in another sector (``sector_of``).  Angles are
as seen from the light: across and down a wall's picture (``frame_angles``).
"""

from __future__ import annotations

import numpy as np

from . import raymap
from .room import SECTOR_WIDTH_DEG, Wall

# Share of the deflection a slope at the profile's limit can make that a photon may need
# to reach its wall at all; beyond it the photon gets no goal (the floor's sector sends
# its upper half to the ceiling).
REACH_MARGIN = 0.8

# A wall's sector follows its image's light centroid at most this far (degrees): beyond
# it the sector would face the next wall more than its own.
MAX_SECTOR_SHIFT_DEG = 30.0
# Below this shift (degrees) a sector stays on its nominal span, whose ends are the
# creases of a creased lens: a slight net tilt of the sector costs less than light
# crossing to the next wall away from a crease.
MIN_SECTOR_SHIFT_DEG = 3.0


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
        across, _ = pixel_angles(wall, light_mm, cols, rows, 0)
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
    nearest = unit(wall.origin + a[:, None] * wall.right + b[:, None] * wall.down - light_mm)
    angle = np.arccos(np.clip(np.sum(nearest * directions, axis=1), -1, 1))
    return np.where(denom < 0, angle, np.pi)



def pixel_angles(wall: Wall, light_mm: np.ndarray, cols: int, rows: int, pad_rows: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Angles (rad) under which the light sees the wall's pixel column centres (on the
    image's middle row) and row centres (on its middle column, ``pad_rows`` more rows
    past each edge), each increasing along the image's axis."""
    a = (np.arange(cols) + 0.5) / cols
    b = (np.arange(-pad_rows, rows + pad_rows) + 0.5) / rows
    across = wall.centre + (a[:, None] - 0.5) * wall.right - light_mm
    down = wall.centre + (b[:, None] - 0.5) * wall.down - light_mm
    return frame_angles(wall, light_mm, across)[0], frame_angles(wall, light_mm, down)[1]


def frame_angles(wall: Wall, light_mm: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n,) rad each: the directions' angles from the light's line to the wall's centre,
    along the image's right axis and along its down axis."""
    centre = unit(wall.centre - light_mm)
    right = unit(wall.right - (wall.right @ centre) * centre)
    down = unit(wall.down - (wall.down @ centre) * centre)
    forward = directions @ centre
    return np.arctan2(directions @ right, forward), np.arctan2(directions @ down, forward)


def direction(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)



def unit(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)
