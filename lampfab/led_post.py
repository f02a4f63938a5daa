"""The fins of a post (``source.Source`` shape "post") as a part to print in black.

The post is a square rod a maker buys (aluminium: it also carries the LEDs' heat away),
standing on the lamp's axis, with one LED board glued to each face that looks at a
wall.  The fins stand at the rod's corners, 45° from the LEDs, where the optics put
them (``fins.stops``).  This part holds them: two collars that slide over the rod at
the fins' top and bottom, joined by the fins, each a plate from the rod's corner out to
``fin_radius_mm``, notched where the LED boards sit.  The collars' holes are round, so
the rod's corners locate the part and the LEDs' wires run up the faces beside them.

The optics trace the fins as thin half-planes from the axis; the printed ones are
``FIN_THICKNESS_MM`` thick and start just clear of the rod's corner, which stops a
little more light close to their edges.  Units: mm, the lamp's frame (z up, the lens's base on
z = 0).
"""

from __future__ import annotations

import math

import numpy as np

from .errors import GeometryError

# Chosen: 1 mm of black PLA, PETG or resin passes no light to speak of, and is two
# perimeters of a 0.4 mm nozzle.
FIN_THICKNESS_MM = 1.0
# Chosen: a printed hole this much wider than the rod (all round) slides on it.
CLEARANCE_MM = 0.2
# Chosen: collars stiff enough to hold the fins square, low enough to stay clear of the
# LEDs (they sit at the fins' ends, 25 mm from the LEDs for the bundled profiles).
COLLAR_WALL_MM = 1.2
COLLAR_HEIGHT_MM = 3.0
# Chosen: room in front of each LED board for its package's edge and solder.
BOARD_ROOM_MM = 0.5


def fin_part(led, light_height_mm: float, fin_azimuths_deg) -> tuple[np.ndarray, np.ndarray]:
    """The fins' part for ``led`` (a ``profile.Led`` of shape "post" with fins and a
    rod) whose LEDs' centres are ``light_height_mm`` above the base and whose fins stand
    at ``fin_azimuths_deg`` (degrees from +x, each once: ``Source.fin_azimuths_deg``).
    Returns ((n, 3) float64 mm vertices, (m, 3) int64 faces): one closed solid."""
    import manifold3d

    from .solid import _arrays, _check

    half = 0.5 * led.rod_width_mm
    hole = half * math.sqrt(2.0) + CLEARANCE_MM  # round: the rod's corners touch it
    bottom = light_height_mm - 0.5 * led.fin_height_mm
    top = light_height_mm + 0.5 * led.fin_height_mm
    collar = (manifold3d.Manifold.cylinder(COLLAR_HEIGHT_MM, hole + COLLAR_WALL_MM, -1.0, 64)
              - manifold3d.Manifold.cylinder(COLLAR_HEIGHT_MM, hole, -1.0, 64))
    part = _check(collar.translate((0.0, 0.0, bottom)) + collar.translate((0.0, 0.0, top - COLLAR_HEIGHT_MM)),
                  "the fins' collars")
    length = led.fin_radius_mm - hole
    for a in np.asarray(fin_azimuths_deg, np.float64):
        plate = manifold3d.Manifold.cube((length, FIN_THICKNESS_MM, led.fin_height_mm))
        plate = plate.translate((hole, -0.5 * FIN_THICKNESS_MM, bottom)).rotate((0.0, 0.0, float(a)))
        part = _check(part + plate, "a fin")
    # Each LED board (as wide as the rod's face) and its package's edge keep the fins clear.
    room = half + CLEARANCE_MM
    for a in np.asarray(fin_azimuths_deg, np.float64) + 45.0:
        board = manifold3d.Manifold.cube((led.offset_mm + BOARD_ROOM_MM, 2 * room, 2 * room))
        part = _check(part - board.translate((0.0, -room, light_height_mm - room)).rotate((0.0, 0.0, float(a))),
                      "the LED boards' room")
    bodies = len(part.decompose())
    if bodies != 1:
        raise GeometryError(f"manifold3d: the fins' part came out as {bodies} bodies, not one")
    return _arrays(part)
