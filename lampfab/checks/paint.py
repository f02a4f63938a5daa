"""``checks.png``: the fabrication checks drawn on the unrolled outer surface (Pillow only).

One panel per check, stacked: u runs across from 0 to 360 deg, z up from the base, one
pixel per sample cell (max-pooled when the grid is wider than ``MAX_WIDTH``, so a single
failing cell never vanishes).  Every panel is coloured by wall thickness; the cells that
fail that check are red, the worst place is ringed, a check that does not apply is
greyed out.
"""

from __future__ import annotations

import numpy as np

from ..profile import Fabrication
from .fields import Fields
from .result import CheckResult

MAX_WIDTH = 1024
TITLE_PX = 18
RED = np.array([230, 20, 20], np.uint8)
NEGATIVE = np.array([255, 0, 255], np.uint8)    # outer surface inside the cavity
# A viridis-like ramp (sRGB 8-bit anchors): dark = thin, bright = thick; no red in it, so
# red cells always mean "fails".
_RAMP = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)


def colour_wall(wall: np.ndarray, vmax: float) -> np.ndarray:
    """(h, w) mm -> (h, w, 3) uint8 sRGB: 0..vmax along the ramp, negative walls magenta."""
    t = np.clip(wall / vmax, 0.0, 1.0) * (len(_RAMP) - 1)
    k = np.minimum(t.astype(int), len(_RAMP) - 2)
    f = (t - k)[..., None]
    rgb = (_RAMP[k] * (1 - f) + _RAMP[k + 1] * f).round().astype(np.uint8)
    rgb[wall < 0] = NEGATIVE
    return rgb


def _pool(a: np.ndarray, step: int, how) -> np.ndarray:
    """(mu, mv) -> (mu // step, mv): pool along u (the grid's wide axis)."""
    if step == 1:
        return a
    mu = a.shape[0] // step * step
    return how(a[:mu].reshape(mu // step, step, *a.shape[1:]), axis=1)


def paint(path_png, f: Fields, results: list[CheckResult], cells: dict, fab: Fabrication) -> None:
    """Compose the panels and write them atomically (``artifacts.atomic_path``)."""
    from PIL import Image, ImageDraw, ImageFont

    from ..artifacts import atomic_path

    mu, mv = f.wall.shape
    step = max(1, -(-mu // MAX_WIDTH))
    wall = _pool(f.wall, step, np.min)                  # the thinnest cell in each pixel
    w, h = wall.shape
    finite = f.wall[np.isfinite(f.wall)]
    vmax = max(3.0 * fab.min_wall_mm, float(np.percentile(finite, 99)) if finite.size else 1.0)
    # Image rows run top-down, z runs up: transpose (u, z) -> (z, u) and flip z.
    base = colour_wall(wall, vmax).transpose(1, 0, 2)[::-1]
    font = _font(ImageFont)

    panels = [_header(Image, ImageDraw, font, w, fab, results, vmax)]
    for r in results:
        img = base.copy()
        mask = cells.get(r.name)
        if mask is not None and r.failed:
            m = _pool(mask, step, np.any).T[::-1]
            img[m] = RED
        if not r.applies:
            img = (0.35 * img + 0.65 * 128).astype(np.uint8)
        panel = Image.new("RGB", (w, h + TITLE_PX), (24, 24, 24))
        panel.paste(Image.fromarray(img), (0, TITLE_PX))
        draw = ImageDraw.Draw(panel)
        draw.text((4, 2), _title(r), fill=_status_colour(r), font=font)
        if r.worst is not None and r.applies:
            x = r.worst["u_deg"] / 360.0 * w
            y = TITLE_PX + (1.0 - r.worst["z_mm"] / f.z[-1]) * (h - 1)
            for rad, col in ((7, (0, 0, 0)), (6, (0, 255, 255)), (5, (0, 0, 0))):
                draw.ellipse([x - rad, y - rad, x + rad, y + rad], outline=col)
        panels.append(panel)

    sheet = Image.new("RGB", (w, sum(p.height for p in panels)), (0, 0, 0))
    y = 0
    for p in panels:
        sheet.paste(p, (0, y))
        y += p.height
    # The sheet is already 8-bit sRGB: save it as it is (``artifacts.write_png`` takes
    # linear floats and would re-encode 2.5 M pixels for nothing), through the same
    # atomic write every artifact uses.
    with atomic_path(path_png, suffix=".png") as tmp:
        sheet.save(tmp, format="PNG")


def _font(ImageFont):
    try:
        return ImageFont.load_default(size=12)
    except TypeError:                                   # Pillow < 10.1: bitmap font only
        return ImageFont.load_default()


def _title(r: CheckResult) -> str:
    if not r.applies:
        return f"{r.name}: does not apply"
    val = "-" if r.value is None else f"{r.value:.4g}"
    lim = "-" if r.limit is None else f"{r.limit:.4g}"
    where = ""
    if r.worst is not None:
        where = f"  at u {r.worst['u_deg']:.1f} deg, z {r.worst['z_mm']:.2f} mm"
    return f"{r.name}: {val} {r.unit} (limit {lim})  {'PASS' if r.passed else 'FAIL'}{where}"


def _status_colour(r: CheckResult):
    if not r.applies:
        return (160, 160, 160)
    return (120, 230, 120) if r.passed else (255, 90, 90)


def _header(Image, ImageDraw, font, w, fab, results, vmax):
    """Title line and the wall-thickness colour bar."""
    bar_h = 10
    panel = Image.new("RGB", (w, 2 * TITLE_PX + bar_h + 4), (24, 24, 24))
    draw = ImageDraw.Draw(panel)
    n_fail = sum(1 for r in results if r.failed)
    draw.text((4, 2), f"lampfab checks, profile {fab.name or '?'} ({fab.process}): "
              f"{'all pass' if n_fail == 0 else f'{n_fail} FAIL'}; u 0..360 deg across, z up; "
              f"colour = wall thickness, red = fails, magenta = negative wall",
              fill=(230, 230, 230), font=font)
    ramp = colour_wall(np.linspace(0, vmax, w)[:, None].repeat(bar_h, 1), vmax).transpose(1, 0, 2)
    panel.paste(Image.fromarray(np.ascontiguousarray(ramp)), (0, TITLE_PX))
    draw.text((4, TITLE_PX + bar_h + 2), "0 mm", fill=(230, 230, 230), font=font)
    label = f"{vmax:.1f} mm"
    draw.text((w - 8 * len(label), TITLE_PX + bar_h + 2), label, fill=(230, 230, 230), font=font)
    return panel
