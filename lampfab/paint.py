"""Matt black paint on the faces of a lens that light no wall.

About 4 % of the light is reflected back into the glass at each glass-air surface.  Part
of it reaches the walls by paths no surface was shaped for, as a haze over the pictures,
and where a picture is black any haze costs SSIM fast.  Much of it travels through the
flat top and base (reflected there, often totally) or through the sector of the outer
surface that faces no wall.  Those faces send no light to the walls themselves, so paint
there swallows the haze and takes nothing from the pictures: on the default lamps, the
top and the base painted took the light reflected inside the lens from 2.0-4.5 % of
each wall's light to 0.6-3.0 %, and the back as well to 0.2-1.9 % (bench/log).

The paint is a finish the maker applies, so the refinement does not trace it: of the
light it steers onto the walls, 0.01-0.1 % leaves through the top or the base and none
through the back (measured on the apple and the cameraman).  verify, the reference render
and the pictures of the lamp trace it, since they show the lamp as made.
"""

from __future__ import annotations

import numpy as np

from . import tolerances
from .profile import PAINTS as CHOICES


def free_span_deg(sectors_deg: dict[str, tuple[float, float]]) -> tuple[float, float] | None:
    """The arc of u (deg, lo < hi, hi - lo < 360) that no wall's sector covers, from the
    design's sectors {wall: (start, end) deg}; None when they leave less than 1 deg.

    The sectors tile the circle in order (right, front, left, then the floor's), each
    starting where the previous one ends."""
    ends = sorted((float(a), float(b)) for a, b in sectors_deg.values())
    covered = sum(b - a for a, b in ends)
    if 360.0 - covered < 1.0:
        return None
    # The gap follows the sector whose end no other sector starts at.
    starts = {round(a % 360.0, 6) for a, _ in ends}
    for _, b in ends:
        if round(b % 360.0, 6) not in starts:
            return b, b + 360.0 - covered
    raise ValueError(f"sectors {sectors_deg} do not follow each other around the lens")


def painted_faces(vertices: np.ndarray, faces: np.ndarray, choice: str, height_mm: float,
                  back_deg: tuple[float, float] | None = None, slots=None) -> np.ndarray:
    """Which facets of a lens solid are painted: (m,) bool.

    vertices (n, 3) float64 mm, z up, the base on z = 0; faces (m, 3) int wound outward;
    ``choice`` one of CHOICES; ``height_mm`` the top's height; ``back_deg`` the arc of u
    (deg, u = atan2(y, x)) that lights no wall, painted on the outer surface with
    "top_base_and_back".  The top and the base are the flat facets at those heights (the
    bore's and the hollow's walls and roof are inside, not painted); the outer surface's
    facets are those facing away from the axis.  The walls of ``slots`` (``slots.Slots``,
    or None) are black whatever the choice: the maker fills them with black epoxy."""
    if choice not in CHOICES:
        raise ValueError(f"black paint {choice!r}: one of {', '.join(CHOICES)}")
    tri = vertices[faces]
    centre = tri.mean(axis=1)
    painted = np.zeros(len(faces), bool) if slots is None else slots.on_walls(centre)
    if choice == "none":
        return painted
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    flat = np.abs(normal[:, 2]) > np.cos(np.radians(tolerances.FLAT_FACE_DEG))
    at_end = (np.abs(centre[:, 2]) < tolerances.FLAT_FACE_HEIGHT_MM) | (
        np.abs(centre[:, 2] - height_mm) < tolerances.FLAT_FACE_HEIGHT_MM)
    painted |= flat & at_end
    if choice == "top_base_and_back" and back_deg is not None:
        lo, hi = back_deg
        u = np.degrees(np.arctan2(centre[:, 1], centre[:, 0]))
        inside = (u - lo) % 360.0 < hi - lo
        outward = normal[:, 0] * centre[:, 0] + normal[:, 1] * centre[:, 1] > 0
        painted |= inside & outward & ~flat
    return painted


def painted_from_json(vertices: np.ndarray, faces: np.ndarray, lens: dict, slots_filled: bool = True) -> np.ndarray:
    """``painted_faces`` of a lens solid (vertices (n, 3) float64 mm, the base on z = 0,
    faces (m, 3) int) as design.json's ``lens`` says (``black_paint``, ``painted_u_deg``,
    ``slots``; a design without them is unpainted and has none): (m,) bool.  With
    ``slots_filled`` False the slots' walls stay clear, as a maker who leaves them empty
    gets them."""
    from .slots import Slots

    return painted_faces(vertices, faces, lens.get("black_paint", "none"), float(vertices[:, 2].max()),
                         lens.get("painted_u_deg"), Slots.from_json(lens.get("slots")) if slots_filled else None)
