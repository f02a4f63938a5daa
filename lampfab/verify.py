"""What the made lamp projects: the exported STL traced with its true facets.

Reads only ``design.json`` and the files it names (the STL and the targets), so any
independent tracer that reads the same files can reproduce these figures.  Each wall
is rendered for the ideal point light and for the LED's real size (a Lambertian
sphere of the design's radius), and compared with its target.  A panel's ``light`` is a
collimated beam (``"type": "collimated"``, see ``panel.geometry.light_json``): parallel, then
with its real spread.
"""

from __future__ import annotations

from dataclasses import dataclass
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


@dataclass
class Loaded:
    """A design read for tracing: design.json's dict, its folder, its walls and its STL as
    a ray-tracing scene (read and built once, traced for every light)."""
    design: dict
    base: Path
    walls: list[room.Wall]
    scene: object  # trace.MeshScene


def load(design_path) -> Loaded:
    from . import trace
    from .export import stl

    design_path = Path(design_path)
    design = read_design(design_path)
    vertices, faces = stl.read_stl(design_path.parent / design["lens"]["stl"])
    return Loaded(design, design_path.parent, [room.Wall.from_json(w) for w in design["walls"]],
                  trace.MeshScene(vertices, faces))


def render_design(loaded: Loaded, image_px: int, photons: int, seed: int, max_bounces: int,
                  light_radius_mm: float | None = None,
                  reflection_place=None) -> tuple[list[np.ndarray], dict]:
    """Trace the design's STL onto its walls (``loaded.walls``).  Returns (per-wall flux
    images, ``room.image_shape(wall, image_px)`` float64, share of the emitted light per
    pixel; info as ``trace.render_walls``'s).

    ``light_radius_mm`` None: the design's own light (an LED of its radius, a beam with
    its spread); a number: an LED of that radius (a beam: parallel).
    ``reflection_place``: see ``trace.render_walls``."""
    from . import trace

    design, walls = loaded.design, loaded.walls
    shapes = [room.image_shape(w, image_px) for w in walls]
    radius = design["light"]["radius"] if light_radius_mm is None else light_radius_mm
    emitter = None
    if design["light"].get("type") == "collimated":
        from .panel.geometry import emitter_from_json

        emitter = emitter_from_json(design["light"], divergence=light_radius_mm is None)
    images, info = trace.render_walls(loaded.scene, np.asarray(design["light"]["position"], float), radius,
                                      float(design["material"]["ior"]), walls, shapes, photons, seed,
                                      max_bounces, emitter, reflection_place)
    return images, info


def verify(design_path, out_dir, image_px: int, photons: int, seed: int, max_bounces: int) -> dict:
    """Render point-light and LED-size images, compare with the targets, write images.

    Returns {"walls": {name: {pearson, ssim, share, ghost_share, direct_ssim, ssim_ceiling,
    led_pearson, led_ssim, led_share}}, "lost_share", "trapped_share"}.

    ``ghost_share`` is the part of the wall's light that was reflected inside the lens
    (Fresnel ghosts), ``direct_ssim`` the SSIM of the rest (the light the outer surface
    steers: the design's own contrast), and ``ssim_ceiling`` the SSIM of the target
    itself with these ghosts added: what an outer surface that put its light exactly on
    the target would score, unless it also changed the ghosts.
    """
    from . import image

    out_dir = Path(out_dir)
    loaded = load(design_path)
    design = loaded.design
    walls = loaded.walls
    point, info = render_design(loaded, image_px, photons, seed, max_bounces, 0.0)
    led, led_info = render_design(loaded, image_px, photons, seed + 1, max_bounces)
    figures = {"walls": {}, "lost_share": info["lost"], "trapped_share": info["trapped"],
               "led_radius_mm": design["light"]["radius"], "photons": photons,
               "real_light": _real_light(design["light"])}
    for k, wall in enumerate(walls):
        target_path = loaded.base / design["walls"][k]["target"]
        target = image.letterbox(artifacts.read_linear_png16(target_path), *point[k].shape)
        sharp = metrics.compare(point[k], target)
        blur = metrics.compare(led[k], target)
        ghosts = info["ghosts"][k]
        direct = point[k] - ghosts
        exact = target / max(float(target.sum()), 1e-300) * float(direct.sum())
        figures["walls"][wall.name] = {
            "pearson": sharp["pearson"], "ssim": sharp["ssim"], "share": info["shares"][k],
            "ghost_share": float(ghosts.sum() / max(point[k].sum(), 1e-300)),
            "direct_ssim": metrics.ssim(direct, target), "ssim_ceiling": metrics.ssim(exact + ghosts, target),
            "led_pearson": blur["pearson"], "led_ssim": blur["ssim"], "led_share": led_info["shares"][k]}
        point_png, led_png, arrays = wall_files(out_dir, wall.name)
        artifacts.write_png(point_png, point[k])
        artifacts.write_png(led_png, led[k])
        artifacts.write_npz(arrays, point=point[k], led=led[k], ghosts=ghosts)
    return figures


def wall_files(out_dir, name: str) -> tuple[Path, Path, Path]:
    """Where ``verify`` puts a wall's renders in ``out_dir``: (point light PNG, LED PNG,
    the float images as .npz: point, led, ghosts)."""
    out_dir = Path(out_dir)
    return out_dir / f"{name}.png", out_dir / f"{name}_led.png", out_dir / f"{name}.npz"


def optimizer_agreement(out_dir, reference_npz, names: list[str]) -> dict[str, float]:
    """Pearson r between verify's point-light render of each wall (``wall_files``)
    and the optimizer's own final render of it (``reference_npz``, one array per wall,
    written by the optimize stage), the verify render resampled to the optimizer's shape.

    The two trace the same lens with different tracers (the exported STL with Fresnel
    and every bounce vs the optimizer's splatting), so r near 1 says the exported file
    is the lens that was optimized.  Returns {wall: r}.
    """
    from . import image

    reference = artifacts.read_npz(reference_npz)
    out = {}
    for name in names:
        mine = artifacts.read_npz(wall_files(out_dir, name)[2])["point"]
        theirs = np.asarray(reference[name], np.float64)
        out[name] = metrics.pearson(image.letterbox(mine, *theirs.shape), theirs)
    return out


def _real_light(light: dict) -> str:
    """The second render's light, in words."""
    if light.get("type") == "collimated":
        return f"beam ±{light['divergence_deg']:g}°"
    return f"LED {light['radius']:g} mm"
