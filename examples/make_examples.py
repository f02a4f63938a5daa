"""Make the bundled example targets (deterministic; run from anywhere).

    python examples/make_examples.py

apple.png     512x512  white apple with stem and leaf on black (the default target)
star.png      512x512  five-point star inside a ring
portrait.png  512x384  synthetic greyscale "photo": a shaded face, continuous tones
panorama.png  1536x512 360° panorama (centre column = front wall): a lit mountain range
              with a moon, wrapping around without a seam (make lamp PANORAMA=...)
astronaut.png 256x256  a real photograph: scikit-image's "astronaut" sample (NASA, public
              domain), in grey
horse.png     400x328  scikit-image's "horse" silhouette, white on black: thin legs with
              dark gaps between them, the hard case for a smooth lens

Silhouettes are drawn at 4x (ImageDraw shapes; the apple body as a smooth signed
distance field) and reduced with area averaging (anti-aliased edges); the portrait is computed with numpy from soft-edged ellipses.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

HERE = Path(__file__).resolve().parent
SS = 4  # supersampling factor


def _canvas(w: int, h: int):
    im = Image.new("L", (w * SS, h * SS), 0)
    return im, ImageDraw.Draw(im)


def _ellipse(draw, cx, cy, rx, ry, fill):
    draw.ellipse([SS * (cx - rx), SS * (cy - ry), SS * (cx + rx), SS * (cy + ry)], fill=fill)


def _down(im: Image.Image) -> Image.Image:
    return im.reduce(SS)  # exact box average over SS x SS blocks


def _quad(p0, p1, p2, n=64):
    """Points on the quadratic Bezier p0-p1-p2."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    p0, p1, p2 = (np.asarray(p, float) for p in (p0, p1, p2))
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * p1 + t ** 2 * p2


def apple() -> Image.Image:
    # Body: a smooth union of two upper lobes and two lower ones (no creases where
    # they meet), with smooth dimples where the stem enters and at the bottom.
    n = 512 * SS
    y, x = (np.mgrid[0:n, 0:n].astype(np.float64) + 0.5) / SS

    def circle(cx, cy, r):
        return np.hypot(x - cx, y - cy) - r

    def smin(a, b, k):
        hh = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
        return b + (a - b) * hh - k * hh * (1.0 - hh)

    def smax(a, b, k):
        return -smin(-a, -b, k)

    body = smin(circle(196, 262, 128), circle(316, 262, 128), 60.0)
    body = smin(body, circle(212, 352, 106), 50.0)
    body = smin(body, circle(300, 352, 106), 50.0)
    body = smax(body, -circle(256, 128, 34), 26.0)  # stem dimple
    body = smax(body, -circle(256, 472, 12), 10.0)  # blossom end
    cover = np.clip(0.5 - body * SS, 0.0, 1.0)  # anti-aliased at the 4x grid
    im = Image.fromarray(np.round(cover * 255).astype(np.uint8))
    d = ImageDraw.Draw(im)
    # Stem: a tapered curve leaning right, drawn as overlapping discs.
    stem = _quad((256, 160), (251, 112), (276, 64))
    for i, (x, y) in enumerate(stem):
        r = 8.5 - 3.0 * i / (len(stem) - 1)
        _ellipse(d, x, y, r, r, 255)
    # Leaf: a pointed oval along a gently curved midrib, from the stem to the right.
    base, tip = np.array([270.0, 96.0]), np.array([402.0, 58.0])
    axis = tip - base
    length = float(np.hypot(*axis))
    u = axis / length
    v = np.array([u[1], -u[0]])  # perpendicular (upwards-ish)
    t = np.linspace(0.0, 1.0, 200)
    half = 0.24 * length * np.sin(np.pi * t) ** 0.85 * (1.0 - 0.25 * t)
    bow = 0.08 * length * np.sin(np.pi * t)  # midrib curvature
    mid = base + np.outer(t * length, u) + np.outer(bow, v)
    upper = mid + half[:, None] * v
    lower = mid - half[:, None] * v
    outline = np.vstack([upper, lower[::-1]]) * SS
    d.polygon([tuple(p) for p in outline], fill=255)
    # Midrib: a thin dark vein, stopping short of the tip.
    vein = mid[8:170] * SS
    d.line([tuple(p) for p in vein], fill=0, width=int(2.5 * SS), joint="curve")
    return _down(im)


def star() -> Image.Image:
    im, d = _canvas(512, 512)
    cx = cy = 256
    _ellipse(d, cx, cy, 236, 236, 255)
    _ellipse(d, cx, cy, 206, 206, 0)
    pts = []
    for k in range(10):
        r = 184 if k % 2 == 0 else 72
        a = -math.pi / 2 + k * math.pi / 5
        pts.append((SS * (cx + r * math.cos(a)), SS * (cy + 10 + r * math.sin(a))))
    d.polygon(pts, fill=255)
    return _down(im)


def _soft_ellipse(x, y, cx, cy, rx, ry, soft, angle=0.0):
    """1 inside the ellipse, 0 outside, with a smooth edge ``soft`` pixels wide."""
    c, s = math.cos(angle), math.sin(angle)
    dx, dy = x - cx, y - cy
    xr, yr = c * dx + s * dy, -s * dx + c * dy
    dist = (np.sqrt((xr / rx) ** 2 + (yr / ry) ** 2) - 1.0) * min(rx, ry)
    return 1.0 / (1.0 + np.exp(np.clip(dist / soft, -50, 50)))


def portrait() -> Image.Image:
    w, h = 512, 384
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    light = np.array([-0.5, -0.45, 0.74])  # from the upper left, towards the viewer
    light /= np.linalg.norm(light)

    def shaded(cx, cy, rx, ry, albedo, ambient=0.35):
        """Lambert shading of an ellipsoid seen face on."""
        nx, ny = (x - cx) / rx, (y - cy) / ry
        nz = np.sqrt(np.clip(1.0 - nx ** 2 - ny ** 2, 0.0, 1.0))
        lam = np.clip(nx * light[0] + ny * light[1] + nz * light[2], 0.0, 1.0)
        return albedo * (ambient + (1 - ambient) * lam)

    def over(img, mask, value):
        return img * (1 - mask) + mask * value

    # Background: a soft diagonal gradient with a glow behind the head.
    img = 0.10 + 0.28 * (1.0 - x / w) * (1.0 - 0.5 * y / h)
    img += 0.25 * np.exp(-(((x - 230) / 150) ** 2 + ((y - 140) / 130) ** 2))
    # Hair behind the head, shoulders (dark clothes) and neck.
    img = over(img, _soft_ellipse(x, y, 256, 178, 104, 128, 1.5),
               shaded(256, 178, 104, 128, 0.30, ambient=0.5))
    img = over(img, _soft_ellipse(x, y, 256, 430, 200, 110, 1.2), shaded(256, 430, 200, 110, 0.42))
    img = over(img, _soft_ellipse(x, y, 256, 300, 40, 70, 1.2), shaded(256, 300, 40, 70, 0.70) * 0.8)
    # Face.
    head = _soft_ellipse(x, y, 256, 186, 80, 102, 1.0)
    img = over(img, head, shaded(256, 186, 80, 102, 0.95))
    # Fringe: hair over the forehead down to a sweeping curve.
    edge = 128 + 0.0022 * (x - 236) ** 2 - 0.10 * (x - 256)
    fringe = head / (1.0 + np.exp(np.clip((y - edge) / 1.5, -50, 50)))
    img = over(img, fringe, shaded(256, 178, 104, 128, 0.34, ambient=0.5))
    # Features: soft sockets, eyes with catch lights, brows, nose, mouth, cheek shade.
    for ex, tilt in ((224, -0.12), (288, 0.12)):
        img *= 1 - 0.22 * _soft_ellipse(x, y, ex, 182, 22, 12, 4.0)
        img = over(img, _soft_ellipse(x, y, ex, 184, 12, 6.5, 0.8), 0.93)
        img = over(img, _soft_ellipse(x, y, ex + 1, 184, 5.5, 5.5, 0.6), 0.12)
        img = over(img, _soft_ellipse(x, y, ex - 1, 182, 1.6, 1.6, 0.5), 0.95)
        img = over(img, _soft_ellipse(x, y, ex, 164, 18, 3.5, 0.9, angle=tilt), 0.22)
    img *= 1 - 0.28 * _soft_ellipse(x, y, 266, 218, 7, 18, 3.0)  # nose shadow
    img *= 1 - 0.30 * _soft_ellipse(x, y, 256, 236, 10, 4, 2.0)  # under the nose
    img += 0.05 * _soft_ellipse(x, y, 250, 208, 4, 16, 3.0)  # nose highlight
    img = over(img, _soft_ellipse(x, y, 256, 256, 22, 4.5, 1.0), 0.40)  # lips
    img *= 1 - 0.10 * _soft_ellipse(x, y, 302, 215, 24, 38, 12.0)  # cheek in shade
    img = np.clip(img, 0.0, 1.0)
    return Image.fromarray(np.round(img * 255).astype(np.uint8))


def panorama() -> Image.Image:
    # The ridge is a sum of sines with whole periods over 360°, so the two ends meet.
    w, h = 1536, 512
    x = np.arange(w * SS) / (w * SS) * 2 * np.pi
    ridge = 0.55 + 0.10 * np.sin(3 * x + 0.4) + 0.07 * np.sin(7 * x + 1.9) + 0.04 * np.sin(17 * x + 0.3) \
        + 0.02 * np.sin(41 * x + 2.2)
    y = (np.arange(h * SS)[:, None] + 0.5) / (h * SS)
    img = (y > ridge[None, :]).astype(np.float64)  # lit mountains below the ridge line
    im = Image.fromarray(np.round(img * 255).astype(np.uint8))
    draw = ImageDraw.Draw(im)
    _ellipse(draw, w / 2 + 90, 158, 40, 40, 255)  # the moon above the front wall
    _ellipse(draw, w / 2 + 106, 149, 34, 34, 0)  # ... a crescent
    return _down(im)


def astronaut() -> Image.Image:
    """A real photograph: scikit-image's "astronaut" sample (Eileen Collins, NASA; public
    domain), in grey, reduced to 256 x 256."""
    from skimage import data

    return Image.fromarray(data.astronaut()).convert("L").reduce(2)


def horse() -> Image.Image:
    """scikit-image's "horse" silhouette (its test data), inverted: a white horse on black."""
    from skimage import data

    return Image.fromarray(np.where(data.horse(), 0, 255).astype(np.uint8))


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                            epilog="Writes the six images next to this script.").parse_args()
    for name, make in (("apple", apple), ("star", star), ("portrait", portrait), ("panorama", panorama),
                       ("astronaut", astronaut), ("horse", horse)):
        out = HERE / f"{name}.png"
        make().save(out, format="PNG", optimize=True)
        print(out)


if __name__ == "__main__":
    main()
