"""Pictures of the lamp for the report, rendered by Mitsuba: the lamp in its room as a
person would see it, the lens close up as glass, and the lens as a matte object (the
source's "bumpy lens").

The room and the close view path-trace the exported lens as a dielectric.  The walls
glow with the LED's light as lampfab's photon tracer traced it through the same STL
onto the whole walls (``room_light``): a path tracer alone would need hours to find the
small LED through the glass for every wall point, so the caustics come from the photon
tracer and the glass, the room and its bounce light from the path tracer.  Both are
rendered with a box filter (pixels with independent noise, as a denoiser expects) and
cleaned by Intel Open Image Denoise, guided by the surfaces' albedo and normals.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from .room import Wall
from .source import Source

WALL_GLOW = 0.85         # radiance of the brightest part of a projection: just under display white
ROOM_GREY = 0.4          # albedo of walls, floor and table: a mid-grey matte paint
AMBIENT = 0.03           # dim sky through the room's open back and ceiling: shows the room
LED_RADIANCE = 50.0      # the LED: overexposed, as in a photo of a lamp
VISIBLE_LED_RADIUS_MM = 0.5  # a point light is drawn this large: it glows in the picture
# The walls' light is traced onto each wall this many times as wide and tall as its picture
# (centred on it): the light that misses the pictures lands there too.
ROOM_WALL_SCALE = 3
# Where the person stands: this far behind the lamp, eyes this high above the floor.
EYE_BEHIND_MM = 2300.0
EYE_HEIGHT_MM = 1500.0
LOOK_AHEAD_MM = 400.0    # the person looks at a point this far beyond the lamp, at its height
ROOM_FOV_DEG = 84.0      # horizontal: the front wall and both side walls' pictures
ROOM_ASPECT = 9 / 16
TABLE_RADIUS_MM = 300.0  # the side table the lamp stands on
PAINT_ALBEDO = 0.04      # matt black paint, as the lens's painted faces are drawn


def _rect(mi, origin: np.ndarray, right: np.ndarray, down: np.ndarray):
    """Mitsuba's rectangle ([-1, 1]^2, normal +z) onto the rectangle origin + s right + t down.

    Its texture rows then run up the rectangle, so a picture is passed flipped."""
    from .mitsuba_reference import placed

    return placed(mi, origin + (right + down) / 2, right / 2, -down / 2)


def _ply(vertices: np.ndarray, faces: np.ndarray, folder: Path, name: str = "lens") -> str:
    import trimesh

    path = folder / f"{name}.ply"
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    return str(path)


def _camera(mi, eye, target, width: int, height: int, fov_deg: float, spp: int, seed: int,
            rfilter: str = "gaussian") -> dict:
    return {"type": "perspective", "fov": fov_deg, "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(list(eye), list(target), [0, 0, 1]),
            "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "luminance",
                     "rfilter": {"type": rfilter}},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed}}


def room_walls(walls: list[Wall]) -> list[Wall]:
    """The whole walls around the pictures whose light ``room_light`` traces: each
    ``ROOM_WALL_SCALE`` times as wide and tall as its picture, centred on it."""
    grow = (ROOM_WALL_SCALE - 1) / 2
    return [Wall(w.name, w.origin - grow * (w.right + w.down), ROOM_WALL_SCALE * w.right, ROOM_WALL_SCALE * w.down)
            for w in walls]


def _visible(led: Source) -> Source:
    """The LED as the beauty shot draws it: at least ``VISIBLE_LED_RADIUS_MM`` across,
    so that a point still glows in the picture."""
    return dataclasses.replace(led, radius_mm=max(led.radius_mm, VISIBLE_LED_RADIUS_MM))


def _scene(mi, folder: Path, vertices: np.ndarray, faces: np.ndarray, painted: np.ndarray, ior: float, led: dict,
           walls: list[Wall], light: list[np.ndarray], floor_z: float) -> dict:
    """The room: the lens as glass (its ``painted`` facets matt black), the glowing LED,
    each wall lit by its traced ``light`` (per wall of ``room_walls``: (rows, cols) flux),
    the floor and the lamp's table."""
    from .mitsuba_reference import lights as led_emitters

    top = max(float(np.percentile(img[img > 0], 99.5)) if (img > 0).any() else 0.0 for img in light) or 1.0
    reach = max(float(np.abs(w.centre[:2]).max()) for w in walls) * 3.0
    grey = {"type": "diffuse", "reflectance": ROOM_GREY}
    scene = {"type": "scene",
             "sky": {"type": "constant", "radiance": {"type": "spectrum", "value": AMBIENT}},
             **led_emitters(mi, _visible(Source.from_json(led)), LED_RADIANCE),
             "lens": {"type": "ply", "filename": _ply(vertices, faces[~painted], folder), "face_normals": True,
                      "bsdf": {"type": "dielectric", "int_ior": float(ior), "ext_ior": 1.0}},
             "floor": {"type": "rectangle", "bsdf": grey,
                       "to_world": _rect(mi, np.array([-reach, reach, floor_z]), np.array([2 * reach, 0, 0]),
                                         np.array([0, -2 * reach, 0]))}}
    if painted.any():
        scene["lens_paint"] = {"type": "ply", "filename": _ply(vertices, faces[painted], folder, "paint"),
                               "face_normals": True, "bsdf": {"type": "diffuse", "reflectance": PAINT_ALBEDO}}
    if floor_z < -1.0:  # the lamp stands on a round side table with one leg
        top_z = -0.5
        scene["table_top"] = {"type": "disk", "bsdf": grey,
                              "to_world": mi.ScalarTransform4f().translate([0, 0, top_z]).scale(TABLE_RADIUS_MM)}
        scene["table_edge"] = {"type": "cylinder", "radius": TABLE_RADIUS_MM, "p0": [0, 0, top_z - 25.0],
                               "p1": [0, 0, top_z], "bsdf": grey}
        scene["table_leg"] = {"type": "cylinder", "radius": 30.0, "p0": [0, 0, floor_z], "p1": [0, 0, top_z - 25.0],
                              "bsdf": grey}
    for k, (wall, img) in enumerate(zip(walls, light)):
        glow = np.clip(img / top, 0.0, 1.0) * WALL_GLOW
        bitmap = mi.Bitmap(np.ascontiguousarray(glow[::-1, :, None], dtype=np.float32))
        # Diffuse and glowing at once: the wall shows the lamp's light and the room's.
        scene[f"wall_{k}"] = {"type": "rectangle", "to_world": _rect(mi, wall.origin, wall.right, wall.down),
                              "bsdf": grey, "emitter": {"type": "area", "radiance": {
                                  "type": "bitmap", "bitmap": bitmap, "raw": True, "filter_type": "bilinear"}}}
    return scene


def _denoised(mi, scene: dict, camera: dict) -> np.ndarray:
    """``scene`` seen by ``camera`` (box filter), path-traced with albedo and normal
    guides and denoised by Intel Open Image Denoise: (rows, cols) float64 radiance."""
    import pyoidn

    scene = {**scene, "camera": camera,
             "integrator": {"type": "aov", "aovs": "albedo:albedo,nn:sh_normal",
                            "integrator": {"type": "path", "max_depth": 12}}}
    out = np.asarray(mi.render(mi.load_dict(scene)), np.float32)  # Y, albedo RGB, normal XYZ
    colour = np.ascontiguousarray(np.repeat(out[..., :1], 3, axis=2))
    albedo = np.ascontiguousarray(np.clip(out[..., 1:4], 0.0, 1.0))
    normal = np.ascontiguousarray(out[..., 4:7])
    return np.asarray(pyoidn.denoise(colour, albedo, normal, hdr=True)[..., 0], np.float64)


def room_pictures(vertices: np.ndarray, faces: np.ndarray, painted: np.ndarray, ior: float, led: dict,
                  walls: list[Wall], light: list[np.ndarray], floor_z: float, width_px: int, spp: int,
                  seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The lamp in its room at a person's eye height, and the lens close up as glass.

    vertices (n, 3) float64 mm, faces (m, 3): the lens solid in the STL frame, its
    ``painted`` facets ((m,) bool, ``paint``) matt black; ``led``:
    design.json's light (position, radius, length); ``walls``: ``room_walls`` of the
    design's walls, ``light`` their traced flux (rows, cols) each; ``floor_z`` mm.
    Returns ((rows, width_px) room, a 4:3 close view 5/8 as wide), float64 linear
    radiance, about 1 for a projection's white.
    """
    from .mi_env import mitsuba

    mi = mitsuba()
    position = np.asarray(led["position"], float)
    height = float(vertices[:, 2].max())
    rows = max(1, int(round(width_px * ROOM_ASPECT)))
    with tempfile.TemporaryDirectory() as tmp:
        scene = _scene(mi, Path(tmp), vertices, faces, painted, ior, led, walls, light, floor_z)
        eye = np.array([0.0, -EYE_BEHIND_MM, floor_z + EYE_HEIGHT_MM]) if floor_z < -1.0 else \
            np.array([0.0, -EYE_BEHIND_MM, position[2] + EYE_HEIGHT_MM / 2])
        look = [0.0, LOOK_AHEAD_MM, position[2] - 50.0]
        room_view = _denoised(mi, scene, _camera(mi, eye, look, width_px, rows, ROOM_FOV_DEG, spp, seed, "box"))
        # Close: a third of the way up, from the right and a little to the front, the lens
        # filling most of the view: the right wall's sector in glass against the lit left
        # wall, a painted back at its edge.
        close_eye = np.array([3.7 * height, 0.8 * height, 1.9 * height])
        look = np.array([0.0, 0.0, 0.5 * height])
        close_px = (5 * width_px) // 8
        close = _denoised(mi, scene, _camera(mi, close_eye, look, close_px, (3 * close_px) // 4, 30.0, spp,
                                             seed + 1, "box"))
    return room_view, close


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
