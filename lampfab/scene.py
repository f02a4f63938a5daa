"""The source's Mitsuba scene: the lens, a point light, and per wall a diffuse rectangle
with a perspective sensor looking straight at it (``ptracer`` cannot connect to an
orthographic sensor).  Used by the ``ptracer`` optimizer.

The lens is one PLY mesh with ``face_normals``: Mitsuba then neither interpolates
shading normals nor regenerates them when the vertices move, so the optimizer refracts
through the same facets that get printed.  ``optimize=False`` keeps the lens a shape
of its own so its vertices stay in ``mi.traverse``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from .mi_env import mitsuba
from .room import Wall

# The sensor sits this fraction of the lamp-to-wall distance in front of the wall,
# looking straight at it: connections from the wall never cross the lens.
SENSOR_STANDOFF = 0.5
# Radiant intensity of the point light (W/sr): irradiance ~1 at 1 m, so images have
# values near 1 and float32 keeps its precision.
LIGHT_INTENSITY = 1e6


def _wall_dicts(mi, wall: Wall, rows: int, cols: int, spp: int, distance_mm: float) -> tuple[dict, dict]:
    up = (-wall.down / wall.height_mm).tolist()
    centre = wall.centre
    normal = wall.normal
    to_wall = mi.ScalarTransform4f().translate(centre.tolist()) @ \
        mi.ScalarTransform4f().look_at([0, 0, 0], normal.tolist(), up) @ \
        mi.ScalarTransform4f().scale([wall.width_mm / 2, wall.height_mm / 2, 1])
    standoff = SENSOR_STANDOFF * distance_mm
    camera = centre + normal * standoff
    fov = float(np.degrees(2 * np.arctan(0.5 * wall.width_mm / standoff)))
    rect = {"type": "rectangle", "to_world": to_wall, "bsdf": {"type": "diffuse"}}
    sensor = {"type": "perspective", "fov": fov, "fov_axis": "x",
              "to_world": mi.ScalarTransform4f().look_at(camera.tolist(), centre.tolist(), up),
              "film": {"type": "hdrfilm", "width": cols, "height": rows, "rfilter": {"type": "box"},
                       "pixel_format": "luminance"},
              "sampler": {"type": "independent", "sample_count": spp}}
    return rect, sensor


def build(lens_vertices: np.ndarray, lens_faces: np.ndarray, light_mm: np.ndarray, ior: float,
          walls: list[Wall], shapes: list[tuple[int, int]], spp: int, max_depth: int = 8):
    """(scene, params, vertex key).  lens_*: the optical solid (mm, outward normals)."""
    import trimesh

    mi = mitsuba()
    with tempfile.TemporaryDirectory() as tmp:
        ply = Path(tmp) / "lens.ply"
        trimesh.Trimesh(lens_vertices, lens_faces, process=False).export(ply)
        scene = {"type": "scene",
                 "integrator": {"type": "ptracer", "max_depth": max_depth, "hide_emitters": True},
                 "light": {"type": "point", "position": light_mm.tolist(),
                           "intensity": {"type": "spectrum", "value": LIGHT_INTENSITY}},
                 "lens": {"type": "ply", "filename": str(ply), "face_normals": True,
                          "bsdf": {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}}}
        for wall, (rows, cols) in zip(walls, shapes):
            distance = float(np.linalg.norm(wall.centre - light_mm))
            rect, sensor = _wall_dicts(mi, wall, rows, cols, spp, distance)
            scene[f"wall_{wall.name}"] = rect
            scene[f"sensor_{wall.name}"] = sensor
        loaded = mi.load_dict(scene, optimize=False)
    params = mi.traverse(loaded)
    return loaded, params, "lens.vertex_positions"
