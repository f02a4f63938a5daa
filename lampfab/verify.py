"""What the made lamp projects: the exported STL traced with its true facets.

Reads only ``design.json`` and the files it names (the STL and the targets), so any
independent tracer that reads the same files can reproduce these figures.  Each wall
is rendered for the ideal point light and for the LED's real size (a Lambertian
sphere of the design's radius), and compared with its target.  A panel's ``light`` is a
collimated beam (``"type": "collimated"``, see ``panel.geometry.light_json``): parallel, then
with its real spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from . import artifacts, metrics, room
from .errors import LampfabError
from .source import Source

# optimize_render.npz's name suffix for each wall's second render (other photons).
SECOND_RENDER = "_again"


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
    vertices: np.ndarray  # (n, 3) float64 mm, the STL read back
    faces: np.ndarray     # (m, 3) int
    painted: np.ndarray   # (m,) bool, the facets painted black (``paint``)
    scene: object         # trace.MeshScene

    def target(self, k: int, shape: tuple[int, int]) -> np.ndarray:
        """Wall ``k``'s prepared target letterboxed to (rows, cols) ``shape``: float64 linear."""
        from . import image

        return image.letterbox(artifacts.read_linear_png16(self.base / self.design["walls"][k]["target"]), *shape)


def load(design_path) -> Loaded:
    from . import paint, trace
    from .export import stl

    design_path = Path(design_path)
    design = read_design(design_path)
    lens = design["lens"]
    vertices, faces = stl.read_stl(design_path.parent / lens["stl"])
    painted = paint.painted_from_json(vertices, faces, lens)
    return Loaded(design, design_path.parent, [room.Wall.from_json(w) for w in design["walls"]],
                  vertices, faces, painted, trace.MeshScene(vertices, faces, painted))


def render_design(loaded: Loaded, image_px: int, photons: int, seed: int, max_bounces: int,
                  point: bool = False, reflection_place=None,
                  kernel_moments=None, ior=None, emitter=None) -> tuple[list[np.ndarray], dict]:
    """Trace the design's STL onto its walls (``loaded.walls``).  Returns (per-wall flux
    images, ``room.image_shape(wall, image_px)`` float64, share of the emitted light per
    pixel; info as ``trace.render_walls``'s).

    ``point`` False: the design's own light (its LED, a beam with its spread); True: the
    point light (the LED's beam from its centre, ``source.Source.point``; a beam:
    parallel).
    ``reflection_place``, ``kernel_moments``, ``ior``, ``emitter`` (another light in
    place of the design's): see ``trace.render_walls``; ``ior`` None: the design's
    material in air."""
    from . import trace

    design, walls = loaded.design, loaded.walls
    shapes = [room.image_shape(w, image_px) for w in walls]
    source = None
    if emitter is None and design["light"].get("type") == "collimated":
        from .panel.geometry import emitter_from_json

        emitter = emitter_from_json(design["light"], divergence=not point)
    elif emitter is None:
        source = Source.from_json(design["light"])
        source = source.point() if point else source
    images, info = trace.render_walls(loaded.scene, source, float(design["material"]["ior"]) if ior is None else ior,
                                      walls, shapes, photons, seed, max_bounces, emitter, reflection_place,
                                      kernel_moments)
    return images, info


def verify(loaded: Loaded, out_dir, image_px: int, photons: int, seed: int, max_bounces: int,
           mitsuba_photons: int = 0, texts: dict[str, str] | None = None, led_photons: int = 0) -> dict:
    """Render a design (``load``'s) with point-light and LED-size images (``photons``
    and ``led_photons``, 0: as many), compare with the targets, write images.

    Returns {"walls": {name: {pearson, ssim, share, ghost_share, direct_ssim, ssim_ceiling,
    led_pearson, led_ssim, led_share, ...}}, "lost_share", "trapped_share", "photons",
    "led_photons" (the second render's, as traced), ...}.

    Where the target has a black background (``metrics.contrast``), ``contrast_ratio``
    and ``black_share`` (point light) and ``led_contrast_ratio`` and ``led_black_share``
    say how dark the lamp keeps it.  A wall with words (``texts``: {wall: its phrase})
    gets ``words`` and how many of them Tesseract reads in each render
    (``led_words_read``, ``point_words_read``) and in the sharp target
    (``target_words_read``; ``ocr``).

    ``ghost_share`` is the part of the wall's light that was reflected inside the lens
    (Fresnel ghosts), ``direct_ssim`` the SSIM of the rest (the light the outer surface
    steers: the design's own contrast), and ``ssim_ceiling`` the SSIM of the target
    itself with these ghosts and the render's own photon noise added (``trace``'s
    ``direct_noise``): what verify would score for an outer surface that put its light
    exactly on the target, unless it also changed the ghosts.

    For an LED (not a panel's beam) each wall also gets the LED's blur measured on this
    lens (``sharpness``): ``led_blur_mm`` (median diameters across and up, and their
    10-90 % range), ``led_reference_pearson`` / ``led_reference_ssim`` (the target
    blurred by these kernels: what a perfect point-light design would show with this
    LED), ``led_ssim_ceiling`` (that, with the lens's own reflections of the LED's
    light and the LED render's photon noise added, as ``ssim_ceiling``: the figure to
    hold ``led_ssim`` against), ``led_ssim_photon_noise`` (what that noise takes off:
    a lamp, free of it, would score about that much more than ``led_ssim``) and
    ``led_kernel_pearson`` (the point-light render
    blurred by the kernels against the LED render: how well the kernels describe the
    blur).  With ``mitsuba_photons`` Mitsuba's light tracer renders the lens too
    (``mitsuba_reference``): ``mitsuba_pearson`` (LED) and ``mitsuba_point_pearson``.

    A lens with black-filled slots is traced a third time with its slots left empty
    (``slots_left_empty``, ``photons``): each wall's ``led_ssim_slots_empty``, and
    ``led_ghost_share`` / ``led_ghost_share_slots_empty``, the part of the LED's light on
    it reflected inside the lens with the slots filled and empty: what the report tells
    a maker who might skip the filling.
    """
    out_dir = Path(out_dir)
    design = loaded.design
    walls = loaded.walls
    point, info, led, led_info, kernels = render_both(loaded, image_px, photons, seed, max_bounces,
                                                      led_photons=led_photons)
    mitsuba = _mitsuba(loaded, [p.shape for p in point], mitsuba_photons, seed + 2) \
        if kernels is not None and mitsuba_photons else None
    slotted = bool(design["lens"].get("slots"))
    if slotted:
        empty, empty_info = render_design(slots_left_empty(loaded), image_px, photons, seed + 3, max_bounces)
    figures = {"walls": {}, "lost_share": info["lost"], "trapped_share": info["trapped"],
               "led_radius_mm": design["light"]["radius"], "photons": photons,
               "led_photons": int(led_info["photons"]),
               "real_light": _real_light(design["light"]), **({"slots_empty_photons": photons} if slotted else {})}
    for k, wall in enumerate(walls):
        target = loaded.target(k, point[k].shape)
        sharp = metrics.compare(point[k], target)
        blur = metrics.compare(led[k], target)
        ghosts = info["ghosts"][k]
        direct = point[k] - ghosts
        exact = _with_flux(target, direct)
        f = figures["walls"][wall.name] = {
            "pearson": sharp["pearson"], "ssim": sharp["ssim"], "share": info["shares"][k],
            "ghost_share": _share(ghosts, point[k]),
            "direct_ssim": metrics.ssim(direct, target),
            "ssim_ceiling": metrics.ssim(_noisy(exact + ghosts, info["direct_noise"][k]), target),
            "led_pearson": blur["pearson"], "led_ssim": blur["ssim"], "led_share": led_info["shares"][k]}
        for prefix, render in (("", point[k]), ("led_", led[k])):
            dark = metrics.contrast(render, target)
            if dark is not None:
                f.update({f"{prefix}contrast_ratio": dark["ratio"], f"{prefix}black_share": dark["black_share"]})
        if texts and wall.name in texts:
            f.update(_words_read(texts[wall.name], target, point[k], led[k]))
        if slotted:
            f.update(_slots_empty(empty[k], empty_info["ghosts"][k], led_info["ghosts"][k], led[k], target))
        arrays = {"point": point[k], "led": led[k], "ghosts": ghosts}
        if kernels is not None and len(kernels.on(k, wall)):
            f.update(_led_reference(kernels, k, wall, target, point[k], led[k], led_info["ghosts"][k],
                                    led_info["direct_noise"][k], arrays))
        point_png, led_png, npz = wall_files(out_dir, wall.name)
        if mitsuba is not None:
            f["mitsuba_pearson"] = metrics.pearson(mitsuba["led"][k], led[k])
            f["mitsuba_point_pearson"] = metrics.pearson(mitsuba["point"][k], point[k])
            arrays.update(mitsuba=mitsuba["led"][k], mitsuba_point=mitsuba["point"][k])
            artifacts.write_png(mitsuba_file(out_dir, wall.name), mitsuba["led"][k])
        artifacts.write_png(point_png, point[k])
        artifacts.write_png(led_png, led[k])
        artifacts.write_npz(npz, **arrays)
    if mitsuba is not None:
        figures["mitsuba"] = {"photons_per_wall": mitsuba["photons"], "seconds": mitsuba["seconds"]}
    return figures


def slots_left_empty(loaded: Loaded) -> Loaded:
    """``loaded`` with its black-filled slots left empty: their walls clear glass, an air
    gap behind them."""
    from . import paint, trace

    painted = paint.painted_from_json(loaded.vertices, loaded.faces, loaded.design["lens"], slots_filled=False)
    return replace(loaded, painted=painted, scene=trace.MeshScene(loaded.vertices, loaded.faces, painted))


def _slots_empty(empty: np.ndarray, empty_ghosts: np.ndarray, led_ghosts: np.ndarray, led: np.ndarray,
                 target: np.ndarray) -> dict:
    """A wall's figures for a lens whose slots are left empty: its LED render (``empty``,
    with ``empty_ghosts`` the light in it reflected inside the lens) against the target,
    and the share of the light reflected inside with the slots filled (``led``,
    ``led_ghosts``) and empty.  The empty render traces verify's ``photons``, not
    ``led_photons`` (a quarter of them in the default profile): its own noise then takes
    up to about 0.02 more off its SSIM on a black background (bench/RESULTS.md), far
    less than leaving the slots empty does."""
    return {"led_ssim_slots_empty": metrics.ssim(empty, target),
            "led_ghost_share": _share(led_ghosts, led), "led_ghost_share_slots_empty": _share(empty_ghosts, empty)}


def render_both(loaded: Loaded, image_px: int, photons: int, seed: int, max_bounces: int, ior=None,
                led_photons: int = 0):
    """The point light's render (``seed``) and the design's own light's (``seed + 1``,
    ``led_photons``, 0: as many as ``photons``), as ``render_design`` makes them, with
    the LED's kernels measured on both (``sharpness.Kernels``, on cells sized for
    ``photons``; None for a panel's beam).  Returns (point images, its info, light
    images, its info, kernels).

    The second render's figures are the ones held against the LED reference, and its
    photon noise, which the lamp does not have, costs SSIM on black backgrounds: the
    apple's LED SSIM was 0.80 / 0.75 / 0.77 at 16 M photons, 0.82 / 0.77 / 0.79 at 64 M
    and 0.82 / 0.78 / 0.79 at 256 M, and the bundled phrase read 3 of 4 words on its
    front wall at 16 M and all four at 64 M (bench/RESULTS.md)."""
    from . import sharpness

    led_light = loaded.design["light"].get("type") != "collimated"
    moments = [sharpness.Moments(sharpness.Cells.for_photons(*_height_range(loaded), photons), len(loaded.walls))
               for _ in range(2)] if led_light else [None, None]
    point, info = render_design(loaded, image_px, photons, seed, max_bounces, True, kernel_moments=moments[0],
                                ior=ior)
    led, led_info = render_design(loaded, image_px, led_photons or photons, seed + 1, max_bounces,
                                  kernel_moments=moments[1], ior=ior)
    return point, info, led, led_info, sharpness.Kernels.of(*moments) if led_light else None


def _led_reference(kernels, k: int, wall: room.Wall, target: np.ndarray, point: np.ndarray, led: np.ndarray,
                   led_ghosts: np.ndarray, led_noise: np.ndarray, arrays: dict) -> dict:
    """verify.json's LED blur figures of wall ``k`` (see ``verify``); adds the reference
    image to ``arrays``."""
    from . import sharpness

    field = kernels.field(k, wall, target.shape)
    reference = sharpness.blur(target, field, wall)
    exact = _with_flux(reference, led - led_ghosts)
    arrays["led_reference"] = reference
    ceiling = metrics.ssim(_noisy(exact + led_ghosts, led_noise), target)
    return {**kernels.blur_figures(k, wall),
            "led_reference_pearson": metrics.pearson(reference, target),
            "led_reference_ssim": metrics.ssim(reference, target),
            "led_ssim_ceiling": ceiling,
            "led_ssim_photon_noise": metrics.ssim(exact + led_ghosts, target) - ceiling,
            "led_kernel_pearson": metrics.pearson(sharpness.blur(point, field, wall), led)}


def _share(part: np.ndarray, whole: np.ndarray) -> float:
    """The part of a render's light (``whole``) that ``part`` holds (a render's ghosts)."""
    return float(part.sum() / max(whole.sum(), 1e-300))


def _with_flux(image: np.ndarray, like: np.ndarray) -> np.ndarray:
    """``image`` scaled to the total light of ``like``: a perfect picture of that light."""
    return image / max(float(image.sum()), 1e-300) * float(like.sum())


def _noisy(image: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """``image`` with a render's photon noise sample added, kept non-negative like any
    render."""
    return np.maximum(image + noise, 0.0)


def _height_range(loaded: Loaded) -> tuple[float, float]:
    """(lowest, highest) z of the lens, mm: the span of ``sharpness.Cells``."""
    z = loaded.vertices[:, 2]
    return float(z.min()), float(z.max())


def _mitsuba(loaded: Loaded, shapes: list, photons: int, seed: int) -> dict:
    """Mitsuba's pictures of every wall for the LED and the point light."""
    import time

    from . import mitsuba_reference

    led = Source.from_json(loaded.design["light"])
    ior = float(loaded.design["material"]["ior"])
    t0 = time.time()
    out = {"photons": photons}
    for name, source in (("point", led.point()), ("led", led)):
        out[name] = mitsuba_reference.render(loaded.vertices, loaded.faces, ior, source, loaded.walls, shapes,
                                             photons, seed, loaded.painted)
    out["seconds"] = time.time() - t0
    return out


def room_light(loaded: Loaded, walls: list[room.Wall], width_px: int, photons: int, seed: int) -> list[np.ndarray]:
    """The design's own light (its LED, a panel's beam with its spread) traced through its
    STL (``load``'s) onto ``walls``: per wall (rows, cols) flux, ``width_px`` wide (the room
    picture's walls)."""
    images, _ = render_design(replace(loaded, walls=walls), width_px, photons, seed, 8)
    return images


def mitsuba_file(out_dir, name: str) -> Path:
    """Where ``verify`` puts Mitsuba's LED picture of a wall."""
    return Path(out_dir) / f"{name}_mitsuba.png"


def wall_files(out_dir, name: str) -> tuple[Path, Path, Path]:
    """Where ``verify`` puts a wall's renders in ``out_dir``: (point light PNG, LED PNG,
    the float images as .npz: point, led, ghosts)."""
    out_dir = Path(out_dir)
    return out_dir / f"{name}.png", out_dir / f"{name}_led.png", out_dir / f"{name}.npz"


def optimizer_agreement(out_dir, reference_npz, names: list[str]) -> dict[str, dict[str, float]]:
    """How well verify's render of each wall (``wall_files``) matches the optimizer's own
    final renders of it (``reference_npz``, written by the optimize stage: per wall two
    renders with different photons, ``<wall>`` and ``<wall>`` + ``SECOND_RENDER``, and
    ``light``, "point" or "led", the light it designed for, which picks verify's render).

    The two trace the same lens with different tracers (the exported STL with Fresnel
    and every bounce vs the optimizer's splatting), so r near 1 says the exported file
    is the lens that was optimized.  The optimizer's renders carry the noise of its
    photons, which alone lowers r, most on a low-contrast photograph (scikit-image's cat:
    0.977 against one render).  So r is taken against the mean of the two and divided by
    the square root of that mean's reliability, the share of its variance that is not
    noise, which the two renders' own r (``rho``) gives: 2 rho / (1 + rho) (Spearman's
    correction for attenuation).  verify's own render has 16 times the photons and counts
    as exact, so the figure errs low.  Returns {wall: {"r": corrected r, "raw_r": r
    against the first render alone, "reliability": the mean's}}.
    """
    from . import image

    reference = artifacts.read_npz(reference_npz)
    light = str(reference.get("light", "point"))
    out = {}
    for name in names:
        mine = artifacts.read_npz(wall_files(out_dir, name)[2])[light]
        first = np.asarray(reference[name], np.float64)
        mine = image.letterbox(mine, *first.shape)
        raw = metrics.pearson(mine, first)
        if name + SECOND_RENDER in reference:
            second = np.asarray(reference[name + SECOND_RENDER], np.float64)
            rho = max(metrics.pearson(first, second), 1e-9)
            reliability = 2.0 * rho / (1.0 + rho)
            r = min(1.0, metrics.pearson(mine, first + second) / math.sqrt(reliability))
        else:  # an optimize stage from before the second render
            reliability, r = 1.0, raw
        out[name] = {"r": r, "raw_r": raw, "reliability": reliability}
    return out


def _words_read(phrase: str, target: np.ndarray, point: np.ndarray, led: np.ndarray) -> dict:
    """How many of ``phrase``'s words Tesseract reads in a wall's two renders, and in its
    sharp target at the same size (the most a render can be expected to give)."""
    from . import ocr

    return {"words": len(ocr.words(phrase)), "led_words_read": ocr.words_read(led, phrase),
            "point_words_read": ocr.words_read(point, phrase), "target_words_read": ocr.words_read(target, phrase)}


def _real_light(light: dict) -> str:
    """The second render's light, in words."""
    if light.get("type") == "collimated":
        return f"beam ±{light['divergence_deg']:g}°"
    return Source.from_json(light).describe()
