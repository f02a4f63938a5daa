"""Machining access: can a mill's tool reach every surface of the lens (see ``lamp``)?

Two checks, for milled profiles (``process`` cnc3 / cnc4; cavity_access also for glass):

  tool_axis      3-axis milling: the part lies on its side and is turned about the lamp
                 axis between ``fab.setups`` indexed setups; each point of the outer
                 surface is cut in the setup whose (vertical) tool axis is closest to its
                 normal.  The angle between the two is the "slope against the tool
                 axis": near 90 deg the ball cuts with its flank, past 90 the point is an
                 undercut.  Limit ``fab.max_tool_angle_deg``.  Sideways tilt only turns
                 the normal about the axis (every direction is within 180/setups deg of a
                 tool axis); tilt along the axis adds: the worst is about
                 acos(cos(180/setups) cos(slope along z)).  On a rotary (4th) axis the
                 tool axis is radial, so the outer slope (max_slope) already is that
                 angle: tool_axis does not apply there.
  cavity_access  the cavity is made from below, through the bore: a straight tool moving
                 along the lamp axis reaches every cavity surface that faces down or
                 sideways, but no glass surface that faces up into the cavity (a floor
                 ledge left around a narrower bore, or a cavity that widens upward).
                 Value: the area of such hidden surface (mm^2), limit 0.  A counterbore
                 (``solid.plan_bore``) removes the whole floor.

Units: mm, degrees where a name says ``deg``.
"""

from __future__ import annotations

import math

import numpy as np

from .. import tolerances
from ..profile import Fabrication
from .fields import Fields, faces_on_grid
from .mesh import face_area_nz
from .places import cylinder_place
from .result import CheckResult, not_applicable

# A cavity face is "up-facing" (hidden from a tool below) when its normal into the glass
# points down by more than this: exactly vertical walls of a revolved inner layer come out
# of float32 files with n_z ~ 1e-8, and a 0.01 deg draft is far below any tool's reach.
_UP_FACING_NZ = math.sin(math.radians(0.01))

# Setup counts tried when the note says how many a lens needs (4: a square fixture or
# collet block, 6: a hex one; 8 is the most a shop would index by hand).
SETUP_CHOICES = (2, 3, 4, 6, 8)

# Offsets of the first setup tried within one setup's span: the shop may index the part
# anywhere, so the check finds the best orientation (to span/16, ~1.4 deg at 4 setups).
_INDEX_STEPS = 16


def tool_angles(normal: np.ndarray, setups: int) -> tuple[np.ndarray, float]:
    """Angle (deg) between each unit normal (..., 3) and the nearest of ``setups`` tool axes
    perpendicular to the lamp axis, 360/setups deg apart, at the best indexing.

    Returns (angles (...,) deg, offset deg of the first setup's tool axis from +x).
    """
    n = normal.reshape(-1, 3)
    span = 2 * np.pi / setups
    # A normal at azimuth phi with horizontal part rho meets an axis at azimuth theta at
    # cos = rho cos(phi - theta): the nearest axis is the one nearest in azimuth.
    phi = np.arctan2(n[:, 1], n[:, 0])
    rho = np.hypot(n[:, 0], n[:, 1])

    def cosines(offset):
        d = np.mod(phi - offset, span)
        return rho * np.cos(np.minimum(d, span - d))

    offsets = np.arange(_INDEX_STEPS) * (span / _INDEX_STEPS)
    best = offsets[int(np.argmax([cosines(o).min() for o in offsets]))]
    angles = np.degrees(np.arccos(np.clip(cosines(best), -1.0, 1.0)))
    return angles.reshape(normal.shape[:-1]), float(np.degrees(best))


def tool_axis_cells(f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: outer cells steeper against their setup's tool axis than allowed."""
    if fab.process != "cnc3":
        return np.zeros(f.wall.shape, bool)
    return tool_angles(f.normal, fab.setups)[0] > fab.max_tool_angle_deg


def tool_axis(f: Fields, fab: Fabrication) -> CheckResult:
    """The ``tool_axis`` check of 3-axis milling (see the module docstring)."""
    if fab.process != "cnc3":
        why = ("on the rotary axis the tool axis is radial: max_slope is the slope against it"
               if fab.process == "cnc4" else f"process {fab.process!r} is not 3-axis milling")
        return not_applicable("tool_axis", "deg", why)
    angle, offset = tool_angles(f.normal, fab.setups)
    i, j = np.unravel_index(int(np.argmax(angle)), angle.shape)
    value = float(angle[i, j])
    limit = fab.max_tool_angle_deg
    per = {n: float(tool_angles(f.normal, n)[0].max()) for n in SETUP_CHOICES}
    enough = [n for n in SETUP_CHOICES if per[n] <= limit]
    bad = angle > limit
    note = (f"3-axis: the part lies on its side and is turned about the lamp axis between {fab.setups} "
            f"setups, {360 / fab.setups:g} deg apart (first tool axis at u {offset:.1f} deg); each point is cut "
            f"in the setup whose tool axis is nearest its normal. Steepest against it: {value:.1f} deg "
            f"({f.area[bad].sum():.0f} mm^2 past {limit:g} deg). Worst angle by setup count: "
            + ", ".join(f"{n}: {per[n]:.0f} deg" for n in SETUP_CHOICES)
            + (f"; {enough[0]} setups are enough." if enough else f"; no count up to {SETUP_CHOICES[-1]} is enough.")
            + " Setups meet in witness lines that polishing must blend; occlusion by bumps is not checked.")
    return CheckResult("tool_axis", value, limit, "deg", value <= limit,
                       worst=cylinder_place(f.xyz[int(i), int(j)]), note=note)


def hidden_cavity(iv: np.ndarray, fi: np.ndarray, mount_radius_mm: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """Cavity surface a straight tool entering through the bore along the axis cannot see.

    iv (n, 3) mm, fi (m, 3) int: the inner layer wound outward (normals into the glass).
    Returns ((m,) bool up-facing faces the bore does not remove, (m,) mm^2 their hidden
    area (of a floor face: its share of the floor outside the bore circle), whether
    ``solid.plan_bore`` makes the bore a counterbore).
    """
    from ..solid import plan_bore

    bore = plan_bore(iv, fi, mount_radius_mm)
    area, nz = face_area_nz(iv, fi)
    up = nz < -_UP_FACING_NZ
    floor = up & np.all(np.abs(iv[fi][:, :, 2] - bore.z_floor_mm) <= tolerances.WELD_MM, axis=1)
    hidden_area = np.where(up, area, 0.0)
    if bore.counterbore:
        hidden_area[floor] = 0.0
    elif floor.any():
        # The bore takes a disk out of the floor; the rest (a ledge) is hidden.
        ring = max(float(area[floor].sum()) - math.pi * bore.radius_mm ** 2, 0.0)
        hidden_area[floor] = area[floor] / area[floor].sum() * ring
    return hidden_area > 0, hidden_area, bore.counterbore


def cavity_access(iv: np.ndarray, fi: np.ndarray, fab: Fabrication) -> CheckResult:
    """The ``cavity_access`` check: the cavity area (mm^2) that ``hidden_cavity`` finds
    a tool through the bore cannot reach, for milled and ground lenses.  iv (n, 3) mm,
    fi (m, 3) int: the inner layer wound outward."""
    if fab.process == "sla":
        return not_applicable("cavity_access", "mm^2", "printed, not cut: any cavity shape can be built")
    hidden, area, counterbore = hidden_cavity(iv, fi, fab.mount_radius_mm)
    value = float(area.sum())
    rho = np.hypot(iv[:, 0], iv[:, 1])
    widest = float(rho.max())
    worst = None
    if hidden.any():
        # The hidden point farthest from the axis: the hardest for a tool from below.
        corners = iv[fi[hidden]].reshape(-1, 3)
        worst = cylinder_place(corners[np.argmax(np.hypot(corners[:, 0], corners[:, 1]))])
    kind = "a counterbore opening the whole cavity floor" if counterbore else "a bore through the cavity floor"
    note = (f"made from below through {kind} (radius {fab.mount_radius_mm:g} mm; the cavity is up to "
            f"{widest:.2f} mm from the axis): {value:.1f} mm^2 of cavity surface faces up, hidden from a "
            f"straight tool moving along the axis.")
    if value > 0:
        note += (" Open the floor with a counterbore (mount_radius_mm >= the floor's radius + 0.5 mm), give "
                 "the inner layer no surface that widens upward, or make the lens in two parts bonded with "
                 "index-matched adhesive.")
    else:
        note += (" The cavity is bored from the base (a boring bar or long end mill, the roof with a "
                 "pointed or ball tool); its walls refract the light too and need the same polish.")
    return CheckResult("cavity_access", value, 0.0, "mm^2", value <= 0.0, worst=worst, note=note)


def access_cells(iv: np.ndarray, fi: np.ndarray, f: Fields, fab: Fabrication) -> np.ndarray:
    """(mu, mv) bool: cavity faces hidden from a tool entering through the bore, marked on
    the (u, z) grid of the outer surface (``fields.faces_on_grid``)."""
    if fab.process == "sla":
        return np.zeros(f.wall.shape, bool)
    hidden, _, _ = hidden_cavity(iv, fi, fab.mount_radius_mm)
    return faces_on_grid(iv, fi[hidden], f)
