#!/usr/bin/env python3
"""Where on a wall the LED's picture loses SSIM against the LED reference.

    .venv/bin/python bench/ssim_regions.py build/apple [build/text ...] [--photons 64000000]

verify's ``led_reference_ssim`` scores the target blurred by the lamp's own LED kernels
(a perfect point-light design, nothing else); ``led_ssim`` scores the made lens's LED
render.  This splits the difference by where it arises.  Each build's STL is traced
again with its own light (``--photons``, a fresh seed), the light reflected inside the
lens kept apart, and the local SSIM (``metrics.ssim_map``, whose mean is the wall's
SSIM) of three pictures is averaged over five regions of the target:

* far black: black (under 5 % of the peak) and more than ``NEAR_PX`` from anything
  brighter, where a perfect design leaves the wall dark;
* near black: the rest of the black, where the LED's blur spreads the picture;
* bright edge / bright interior: over half the peak, within ``NEAR_PX`` of a darker
  pixel or farther;
* mid-tones: the rest (a photograph's shades).

The pictures: the reference (verify's), the LED render, and its direct light alone
(without the reflections).  Per region: its share of the wall, the three means, and
what the region takes off the wall's SSIM (its share of the wall times the reference's
mean less the render's).  The interior's ripple (the rms of the render less the
reference there, both scaled to the same light, over the reference's mean there) is
printed too: SSIM counts any ripple on a flat bright area over about 1 % of it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import artifacts, metrics, verify  # noqa: E402

NEAR_PX = 4  # about the LED's blur at 64 px (2-4 px)
SEED = 101   # not verify's own
REGIONS = ("far black", "near black", "bright edge", "bright interior", "mid-tones")


def regions(target: np.ndarray) -> dict[str, np.ndarray]:
    """The five regions of ``target`` (rows, cols), as boolean masks of its shape."""
    from scipy import ndimage

    peak = float(target.max())
    black, bright = target < 0.05 * peak, target > 0.5 * peak
    far = ndimage.distance_transform_edt(black) > NEAR_PX
    inside = ndimage.distance_transform_edt(bright) > NEAR_PX
    return {"far black": far, "near black": black & ~far, "bright edge": bright & ~inside,
            "bright interior": inside, "mid-tones": ~black & ~bright}


def wall_regions(target: np.ndarray, pictures: dict[str, np.ndarray]) -> dict:
    """{region: {"share", picture name: mean local SSIM there}} and {"ripple"} (of the
    "LED render" against the "reference") for ``pictures`` ({name: (rows, cols)
    image}) of one wall."""
    maps = {name: metrics.ssim_map(image, target) for name, image in pictures.items()}
    rows, cols = next(iter(maps.values())).shape
    pad = (target.shape[0] - rows) // 2, (target.shape[1] - cols) // 2
    out = {}
    found = regions(target)
    for name, mask in found.items():
        mask = mask[pad[0]:pad[0] + rows, pad[1]:pad[1] + cols]
        if mask.any():
            out[name] = {"share": float(mask.mean()), **{k: float(m[mask].mean()) for k, m in maps.items()}}
    inside = found["bright interior"]
    led, reference = (pictures[k] / pictures[k].mean() for k in ("LED render", "reference"))
    out["ripple"] = float((led - reference)[inside].std() / reference[inside].mean()) if inside.sum() > 1 else None
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("builds", nargs="+", type=Path)
    ap.add_argument("--photons", type=int, default=64_000_000, help="photons of the LED render (default 64 M)")
    args = ap.parse_args()
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        images, info = verify.render_design(loaded, 64, args.photons, SEED, 8)
        print(f"\n{build}: {args.photons / 1e6:g} M photons; per region: share of the wall, local SSIM of the "
              f"reference / LED render / its direct light, and what it takes off the wall's SSIM")
        print("| wall | SSIM ref / LED / direct | " + " | ".join(REGIONS) + " | interior ripple |")
        print("|---" * (len(REGIONS) + 3) + "|")
        for k, wall in enumerate(loaded.walls):
            _, _, npz = verify.wall_files(build / "verify", wall.name)
            reference = artifacts.read_npz(npz).get("led_reference")
            if reference is None:
                continue
            led = images[k]
            target = loaded.target(k, led.shape)
            pictures = {"reference": reference, "LED render": led, "direct": led - info["ghosts"][k]}
            found = wall_regions(target, pictures)
            cells = []
            for name in REGIONS:
                r = found.get(name)
                cells.append("—" if r is None else
                             f"{r['share']:.0%}: {r['reference']:.2f} / {r['LED render']:.2f} / {r['direct']:.2f} "
                             f"({r['share'] * (r['LED render'] - r['reference']):+.3f})")
            whole = " / ".join(f"{metrics.ssim(p, target):.3f}" for p in pictures.values())
            ripple = "—" if found["ripple"] is None else f"{found['ripple']:.1%}"
            print(f"| {wall.name} | {whole} | " + " | ".join(cells) + f" | {ripple} |")


if __name__ == "__main__":
    main()
