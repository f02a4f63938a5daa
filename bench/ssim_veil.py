#!/usr/bin/env python3
"""How much a faint, even veil of light costs SSIM on a black background.

    .venv/bin/python bench/ssim_veil.py build/apple [build/star ...]

verify's ``led_reference_ssim`` scores the target blurred by the lamp's LED: a perfect
point-light design with nothing else, its black exactly black.  A made lens always
sends some light into the black (Fresnel reflections inside the glass, light scattered
at the edges of the design's regions), and SSIM on a black background falls fast with
it: where the target is black its local SSIM is C1 / (mean^2 + C1) x C2 / (var + C2), with
C1 = (0.01 x the target's peak)^2.  Per wall of each build (verify's images, nothing is
traced), this prints the reference's SSIM with an even veil of 0, 0.5, 1, 2 and 4 % of
the picture's mean brightness added, the veil of the LED render (its mean light more
than 6 pixels from the picture, over the picture's mean) and its SSIM.  Walls whose
target has no black background are skipped.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import artifacts, metrics, verify  # noqa: E402

VEILS = (0.0, 0.005, 0.01, 0.02, 0.04)  # of the picture's mean brightness
FAR_PX = 6  # farther than the LED's blur (2-4 px at 64 px) from the picture


def wall_veils(target: np.ndarray, reference: np.ndarray, led: np.ndarray) -> dict | None:
    """SSIM of ``reference`` with each veil of ``VEILS`` and the veil of ``led``, all
    (rows, cols) float64 images of one wall; None without a black background."""
    from scipy import ndimage

    bright = target > 0.5 * target.max()
    far = ndimage.distance_transform_edt(target < 0.05 * target.max()) > FAR_PX
    if metrics.contrast(led, target) is None or not far.any():
        return None
    level = reference[bright].mean()
    return {"reference": [metrics.ssim(reference + v * level, target) for v in VEILS],
            "led_veil": float(led[far].mean() / led[bright].mean()), "led_ssim": metrics.ssim(led, target)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("builds", nargs="+", type=Path)
    args = ap.parse_args()
    print("reference SSIM with a veil of " + " ".join(f"{v:>5.1%}" for v in VEILS) + "   LED render: veil  SSIM")
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        for k, wall in enumerate(loaded.walls):
            _, _, npz = verify.wall_files(build / "verify", wall.name)
            images = artifacts.read_npz(npz)
            if "led_reference" not in images:
                continue
            target = loaded.target(k, images["led"].shape)
            row = wall_veils(target, images["led_reference"], images["led"])
            if row is not None:
                print(f"{build.name + ' ' + wall.name:<29}" + " ".join(f"{s:5.3f}" for s in row["reference"])
                      + f"   {row['led_veil']:>16.1%} {row['led_ssim']:5.3f}")


if __name__ == "__main__":
    main()
