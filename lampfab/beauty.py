"""Two Mitsuba pictures for the report: the lamp as a glass object in its room (the
source's "final rendered scene"), and the displaced lens on its own (the source's
"bumpy lens").

The room picture path-traces the exported lens as a dielectric.  The walls show the
projections verify traced from the same STL, as glowing pictures: a path tracer alone
would need hours to find the LED through the glass for every wall point, so the
caustics come from verify's photon tracer and the glass from the path tracer.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from .room import Wall

WALL_GLOW = 1.0          # radiance of the brightest part of a projection (display white)
ROOM_GREY = 0.35         # albedo of walls, floor and table around the pictures
AMBIENT = 0.04           # dim sky through the room's open back and ceiling: shows the room
LED_RADIANCE = 50.0      # the LED bead: overexposed, as in a photo of a lamp


def _rect(mi, origin: np.ndarray, right: np.ndarray, down: np.ndarray):
    """Mitsuba's rectangle ([-1, 1]^2, normal +z) onto the rectangle origin + s right + t down.

    Its texture rows then run up the rectangle, so a picture is passed flipped."""
    m = np.eye(4)
    m[:3, 0], m[:3, 1] = right / 2, -down / 2
    n = np.cross(right, -down)
    m[:3, 2] = n / np.linalg.norm(n)
    m[:3, 3] = origin + (right + down) / 2
    return mi.ScalarTransform4f(m)


def _ply(vertices: np.ndarray, faces: np.ndarray, folder: Path) -> str:
    import trimesh

    path = folder / "lens.ply"
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return str(path)


def _camera(mi, eye, target, width: int, height: int, fov_deg: float, spp: int, seed: int) -> dict:
    return {"type": "perspective", "fov": fov_deg, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(list(eye), list(target), [0, 0, 1]),
            "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "luminance",
                     "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed}}


def room_scene(vertices: np.ndarray, faces: np.ndarray, ior: float, light_mm: np.ndarray, led_radius_mm: float,
               walls: list[Wall], pictures: list[np.ndarray], width_px: int, spp: int, seed: int = 0) -> np.ndarray:
    """The glass lamp in its room, seen from behind and above the viewer's shoulder.

    vertices (n, 3) float64 mm, faces (m, 3): the lens solid in the STL frame;
    ``pictures``: per wall (rows, cols) float64 flux, as verify rendered them.
    Returns (rows, cols) float64 linear radiance, about 1 for a projection's white.
    """
    from .mi_env import mitsuba

    mi = mitsuba()
    top = max(float(np.percentile(p, 99.5)) for p in pictures) or 1.0
    low = min(float((w.origin + w.down)[2]) for w in walls)
    floor_z = min(low, 0.0) - 1.0
    reach = max(float(np.abs(w.centre[:2]).max()) for w in walls) * 1.3
    scene = {"type": "scene",
             "integrator": {"type": "path", "max_depth": 16},
             "sky": {"type": "constant", "radiance": {"type": "spectrum", "value": AMBIENT}},
             "led": {"type": "sphere", "center": light_mm.tolist(), "radius": float(led_radius_mm),
                     "emitter": {"type": "area", "radiance": {"type": "spectrum", "value": LED_RADIANCE}}},
             "floor": {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": ROOM_GREY},
                       "to_world": _rect(mi, np.array([-reach, reach, floor_z]), np.array([2 * reach, 0, 0]),
                                         np.array([0, -2 * reach, 0]))}}
    if floor_z < -1.0:  # the images reach below the lamp: it stands on a table
        scene["table"] = {"type": "cylinder", "radius": 250.0, "p0": [0, 0, floor_z], "p1": [0, 0, -0.5],
                          "bsdf": {"type": "diffuse", "reflectance": ROOM_GREY}}
        scene["table_top"] = {"type": "disk", "bsdf": {"type": "diffuse", "reflectance": ROOM_GREY},
                              "to_world": mi.ScalarTransform4f().translate([0, 0, -0.5]).scale(250.0)}
    for k, (wall, picture) in enumerate(zip(walls, pictures)):
        glow = np.clip(picture / top, 0.0, 1.0) * WALL_GLOW
        bitmap = mi.Bitmap(np.ascontiguousarray(glow[::-1, :, None], dtype=np.float32))
        scene[f"picture_{k}"] = {"type": "rectangle", "to_world": _rect(mi, wall.origin, wall.right, wall.down),
                                 "bsdf": {"type": "diffuse", "reflectance": 0.0},
                                 "emitter": {"type": "area", "radiance": {"type": "bitmap", "bitmap": bitmap,
                                                                          "raw": True}}}
        if wall.name != "floor":  # the wall itself, a little wider, just behind the picture
            grow = 0.6
            back = -wall.normal * 1.0
            origin = wall.origin - grow * (wall.right + wall.down) + back
            scene[f"wall_{k}"] = {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": ROOM_GREY},
                                  "to_world": _rect(mi, origin, (1 + 2 * grow) * wall.right,
                                                    (1 + 2 * grow) * wall.down)}
    # Close behind the lamp with a wide lens: the glass fills a sixth of the picture
    # and all three walls are in view.
    height = float(vertices[:, 2].max())
    eye = np.array([0.25 * height, -4.0 * height, 2.6 * height])
    look = np.array([0.0, 0.8 * reach, -0.1 * reach])
    rows = max(1, int(round(width_px * 0.625)))
    with tempfile.TemporaryDirectory() as tmp:
        scene["lens"] = {"type": "ply", "filename": _ply(vertices, faces, Path(tmp)), "face_normals": True,
                         "bsdf": {"type": "dielectric", "int_ior": float(ior), "ext_ior": 1.0}}
        scene["camera"] = _camera(mi, eye, look, width_px, rows, 100.0, spp, seed)
        loaded = mi.load_dict(scene)
    return np.asarray(mi.render(loaded), np.float64)[..., 0]


def bumpy_lens(vertices: np.ndarray, faces: np.ndarray, width_px: int, spp: int, seed: int = 0) -> np.ndarray:
    """The lens solid as a matte white object under a key and a fill light, so the
    bumps of the outer layer read as light and shade.  (rows, cols) float64 radiance.

    One directional light per render, summed: with both in one scene each sample
    would pick one at random, and the picture would be grainy.
    """
    from .mi_env import mitsuba

    mi = mitsuba()
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre = (lo + hi) / 2
    size = float(np.max(hi - lo))
    eye = centre + np.array([0.55, -1.0, 0.3]) * 2.6 * size
    rows = max(1, int(round(width_px * 0.75)))
    total = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        lens = {"type": "ply", "filename": _ply(vertices, faces, Path(tmp)), "face_normals": True,
                "bsdf": {"type": "diffuse", "reflectance": 0.8}}
        for direction, irradiance in (([-0.6, 0.5, -0.6], 2.2), ([0.7, 0.6, -0.2], 0.6)):  # key, fill
            loaded = mi.load_dict({"type": "scene", "integrator": {"type": "direct"}, "lens": lens,
                                   "sun": {"type": "directional", "direction": direction,
                                           "irradiance": {"type": "spectrum", "value": irradiance}},
                                   "camera": _camera(mi, eye, centre, width_px, rows, 28.0, spp, seed)})
            total = total + np.asarray(mi.render(loaded), np.float64)[..., 0]
    return total
