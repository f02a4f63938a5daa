"""What the made lamp projects: the exported STL traced with its true facets.

Reads only ``design.json`` and the files it names (the STL and the targets), so any
independent tracer that reads the same files can reproduce these figures.  Each wall
is rendered for the ideal point light and for the LED's real size (a Lambertian
sphere of the design's radius), and compared with its target.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import artifacts, metrics, room
from .errors import LampfabError


def read_design(path) -> dict:
    design = artifacts.read_json(path)
    for key in ("units", "light", "material", "lens", "walls"):
        if key not in design:
            raise LampfabError(f"{path}: missing key {key!r}")
    if design["units"] != "mm":
        raise LampfabError(f"{path}: units {design['units']!r}; only mm is supported")
    return design


def render_design(design_path, image_px: int, photons: int, seed: int, max_bounces: int,
                  light_radius_mm: float | None = None) -> tuple[list[room.Wall], list[np.ndarray], dict]:
    """Trace the design's STL onto its walls.  Returns (walls, flux images, info)."""
    from . import stl, trace

    design_path = Path(design_path)
    design = read_design(design_path)
    base = design_path.parent
    vertices, faces = stl.read_stl(base / design["lens"]["stl"])
    walls = [room.Wall.from_json(w) for w in design["walls"]]
    shapes = [room.image_shape(w, image_px) for w in walls]
    radius = design["light"]["radius"] if light_radius_mm is None else light_radius_mm
    scene = trace.MeshScene(vertices, faces)
    images, info = trace.render_walls(scene, np.asarray(design["light"]["position"], float), radius,
                                      float(design["material"]["ior"]), walls, shapes, photons, seed,
                                      max_bounces)
    return walls, images, info


def verify(design_path, out_dir, image_px: int, photons: int, seed: int, max_bounces: int) -> dict:
    """Render point-light and LED-size images, compare with the targets, write images.

    Returns {"walls": {name: {pearson, ssim, share, led_pearson, led_ssim, led_share}},
    "lost_share", "trapped_share"}.
    """
    from . import image

    design_path = Path(design_path)
    out_dir = Path(out_dir)
    design = read_design(design_path)
    walls, point, info = render_design(design_path, image_px, photons, seed, max_bounces, 0.0)
    _, led, led_info = render_design(design_path, image_px, photons, seed + 1, max_bounces)
    figures = {"walls": {}, "lost_share": info["lost"], "trapped_share": info["trapped"],
               "led_radius_mm": design["light"]["radius"], "photons": photons}
    for k, wall in enumerate(walls):
        target_path = design_path.parent / design["walls"][k]["target"]
        target = image.letterbox(artifacts.read_linear_png16(target_path), *point[k].shape)
        sharp = metrics.compare(point[k], target)
        blur = metrics.compare(led[k], target)
        figures["walls"][wall.name] = {
            "pearson": sharp["pearson"], "ssim": sharp["ssim"], "share": info["shares"][k],
            "led_pearson": blur["pearson"], "led_ssim": blur["ssim"], "led_share": led_info["shares"][k]}
        artifacts.write_png(out_dir / f"{wall.name}.png", point[k])
        artifacts.write_png(out_dir / f"{wall.name}_led.png", led[k])
        artifacts.write_npz(out_dir / f"{wall.name}.npz", point=point[k], led=led[k])
    return figures
