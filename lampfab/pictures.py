"""Pictures for the maker (Pillow only): the optimization as an animated GIF, and the
unrolled heightmap as a colour map.  Both are written atomically as files the report
embeds.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .artifacts import atomic_path
from .room import SECTOR_CENTRE_DEG, SECTOR_WIDTH_DEG
from .surface import Cylinder, sample

FONT = Path(__file__).resolve().parent / "data" / "DejaVuSans-Bold.ttf"
FRAME_MS = 400        # per optimization step shown; the last frame stays 4x longer
GIF_TILE_PX = 160     # each wall's preview is shown this wide in the GIF
MAP_WIDTH_PX = 720    # the heightmap picture: 2 px per degree of u
# Diverging ramp (sRGB 8-bit anchors) for signed offsets: blue = inwards, white = the
# plain cylinder, orange = outwards.
_DIVERGING = np.array([[33, 102, 172], [146, 197, 222], [247, 247, 247], [244, 165, 130], [178, 24, 43]], float)
_PREVIEW = re.compile(r"step(\d+)_(\w+)\.png$")


def _font(size: int):
    from PIL import ImageFont

    return ImageFont.truetype(str(FONT), size)


def preview_name(step: int, wall: str) -> str:
    """The file name of the optimizer's preview of ``wall`` at ``step``, as
    ``optimization_gif`` finds it."""
    return f"step{step:06d}_{wall}.png"


def optimization_gif(previews_dir, wall_names: list[str], out_path) -> int:
    """Animate ``previews_dir/stepNNNNNN_<wall>.png``: one frame per step, the walls side
    by side in ``wall_names`` order, labelled with the step.  Returns the frame count
    (0 writes nothing: there were no previews)."""
    from PIL import Image, ImageDraw

    steps: dict[int, dict[str, Path]] = {}
    for p in Path(previews_dir).glob("step*_*.png"):
        m = _PREVIEW.search(p.name)
        if m and m.group(2) in wall_names:
            steps.setdefault(int(m.group(1)), {})[m.group(2)] = p
    frames = []
    font = _font(13)
    for step in sorted(steps):
        tiles = []
        for name in wall_names:
            if name in steps[step]:
                with Image.open(steps[step][name]) as im:
                    tile = im.convert("L")
                tiles.append(tile.resize((GIF_TILE_PX, max(1, round(GIF_TILE_PX * tile.height / tile.width))),
                                         Image.Resampling.NEAREST))
        if not tiles:
            continue
        gap, top = 4, 20
        frame = Image.new("L", (len(tiles) * (GIF_TILE_PX + gap) - gap, top + max(t.height for t in tiles)), 0)
        for k, tile in enumerate(tiles):
            frame.paste(tile, (k * (GIF_TILE_PX + gap), top))
        ImageDraw.Draw(frame).text((4, 2), f"step {step}   " + "   ".join(wall_names), fill=230, font=font)
        frames.append(frame)
    if not frames:
        return 0
    durations = [FRAME_MS] * (len(frames) - 1) + [4 * FRAME_MS]
    with atomic_path(out_path, suffix=".gif") as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=durations, loop=0)
    return len(frames)


def heightmap_map(cyl: Cylinder, heights: np.ndarray, wall_names: list[str], out_path) -> dict:
    """The outer layer unrolled: radial offset from the plain cylinder over u (0..360°,
    across) and z (up), as a colour map with the wall sectors marked and a scale.

    ``heights``: (nu, nv) float64 mm at the spline's nodes.  Returns the offset range
    {"min_mm", "max_mm"} of the sampled surface.
    """
    from PIL import Image, ImageDraw

    width = MAP_WIDTH_PX
    rows = max(2, int(round(width * cyl.height_mm / (2 * np.pi * cyl.radius_mm))))  # true proportions
    fine = sample(cyl, np.asarray(heights, np.float64), width, rows)   # (u, z) mm
    shift = int(round(width * SECTOR_WIDTH_DEG / 2 / 360))               # start at u = -45°: whole sectors
    fine = np.roll(fine, shift, axis=0)
    span = max(float(np.abs(fine).max()), 1e-6)
    picture = diverging(fine / span).transpose(1, 0, 2)[::-1]       # rows top-down = z down
    pad, top, bar = 60, 26, 14
    canvas = Image.new("RGB", (width + 2 * pad, top + rows + 56), (13, 15, 18))
    canvas.paste(Image.fromarray(picture), (pad, top))
    draw = ImageDraw.Draw(canvas)
    font = _font(12)
    for name, centre in SECTOR_CENTRE_DEG.items():
        x0 = pad + (centre / 360 + 1 / 8) * width
        draw.line([(x0 + width / 8, top), (x0 + width / 8, top + rows)], fill=(40, 40, 40), width=1)
        label = name if name in wall_names else "(no wall)"
        draw.text((x0, top - 4), label, fill=(230, 230, 230), font=font, anchor="md")
    draw.text((pad - 6, top), f"{cyl.height_mm:.0f} mm", fill=(170, 170, 170), font=font, anchor="ra")
    draw.text((pad - 6, top + rows), "0", fill=(170, 170, 170), font=font, anchor="rd")
    y = top + rows + 18
    ramp = diverging(np.linspace(-1, 1, width)[:, None]).transpose(1, 0, 2)
    canvas.paste(Image.fromarray(np.repeat(ramp, bar, axis=0)), (pad, y))
    for value, anchor, x in ((-span, "la", pad), (0.0, "ma", pad + width / 2), (span, "ra", pad + width)):
        draw.text((x, y + bar + 2), f"{value:+.1f} mm", fill=(200, 200, 200), font=font, anchor=anchor)
    draw.text((pad + width / 2, y - 2), "u: -45° → 315° (angle around the lamp), z up", fill=(170, 170, 170),
              font=font, anchor="md")
    with atomic_path(out_path, suffix=".png") as tmp:
        canvas.save(tmp, format="PNG")
    return {"min_mm": float(fine.min()), "max_mm": float(fine.max())}


def diverging(t: np.ndarray) -> np.ndarray:
    """(...) in [-1, 1] -> (..., 3) uint8 sRGB along the diverging ramp."""
    s = (np.clip(t, -1.0, 1.0) + 1.0) / 2.0 * (len(_DIVERGING) - 1)
    k = np.minimum(s.astype(int), len(_DIVERGING) - 2)
    f = (s - k)[..., None]
    return (_DIVERGING[k] * (1 - f) + _DIVERGING[k + 1] * f).round().astype(np.uint8)
