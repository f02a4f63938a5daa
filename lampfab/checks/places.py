"""Where a check points: the ``worst`` place of a ``CheckResult``, in the STL's frame.

On the lamp a place is the point in the lamp frame (mm, Z up, base on z = 0) with its
cylinder coordinates, so ``checks.png`` can ring it on the unrolled surface; on a panel
it is the point with its position across and up the relief.
"""

from __future__ import annotations

import math


def cylinder_place(xyz) -> dict:
    """{"u_deg" in [0, 360), "z_mm", "xyz_mm": [x, y, z]} of a point of the lamp (mm)."""
    x, y, z = (float(c) for c in xyz)
    u = math.degrees(math.atan2(y, x)) % 360.0
    return {"u_deg": round(u, 3), "z_mm": round(z, 4), "xyz_mm": [round(x, 4), round(y, 4), round(z, 4)]}


def panel_place(xyz) -> dict:
    """{"x_mm", "z_mm", "xyz_mm": [x, y, z]} of a point of a panel's relief (mm)."""
    x, y, z = (round(float(c), 4) for c in xyz)
    return {"x_mm": x, "z_mm": z, "xyz_mm": [x, y, z]}
