#!/usr/bin/env python3
"""What a bare LED on its board would project through a made lens, against the glowing
ball lampfab designs for.

    .venv/bin/python bench/led_emission.py build/apple [build/text ...] [--photons 4e6]

lampfab traces a ball-shaped LED (``shape = "sphere"``) as a glowing ball: the same
light in every direction, the lamp's walls lit from every elevation the lens covers.
An LED package on a flat board is a flat Lambertian emitter: facing up, as the board
sits on its stalk under the lens, it sends light upward in proportion to the cosine of
the angle from straight up, nothing sideways and nothing down.  This script traces each
build's exported STL as verify does (64 px, stratified photons) with the build's own
ball LED, and with a flat disc of the same radius at the same place facing up, and per
wall prints the render's r and SSIM against the target, the wall's light (as a share of
the emitted light) and the share of it in the picture's lower half.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import metrics, trace, verify  # noqa: E402


def flat_facing_up(light_mm: np.ndarray, radius_mm: float):
    """``trace.render_walls``'s ``emitter``: a Lambertian disc of ``radius_mm`` centred on
    ``light_mm``, facing +z (up the lamp's axis): stratified cosine-weighted directions,
    each from a random point of the disc."""
    def emit(mi, n: int, seed: int):
        square, count = trace.stratified_square(mi, n, 1.0, seed)
        d = mi.warp.square_to_cosine_hemisphere(square)
        rng = trace.direction_rng(mi, count, seed)
        disc = mi.warp.square_to_uniform_disk_concentric(mi.Point2f(rng.next_float32(), rng.next_float32()))
        x, y, z = (float(c) for c in light_mm)
        return mi.Point3f(x + radius_mm * disc.x, y + radius_mm * disc.y, z), mi.Vector3f(d.x, d.y, d.z)
    return emit


def figures(loaded: verify.Loaded, photons: int, seed: int) -> dict[str, list[dict]]:
    """{emitter: per wall {"wall", "r", "ssim", "share", "lower_half"}} for the ball and
    the flat disc facing up."""
    light = loaded.design["light"]
    flat = flat_facing_up(np.asarray(light["position"], float), float(light["radius"]))
    out = {}
    for name, emitter in (("ball (designed for)", None), ("flat, facing up", flat)):
        images, _ = verify.render_design(loaded, 64, photons, seed, 8, emitter=emitter)
        rows = []
        for k, (wall, img) in enumerate(zip(loaded.walls, images)):
            target = loaded.target(k, img.shape)
            total = float(img.sum())
            rows.append({"wall": wall.name, "r": metrics.pearson(img, target), "ssim": metrics.ssim(img, target),
                         "share": total, "lower_half": float(img[img.shape[0] // 2:].sum()) / total if total else 0.0})
        out[name] = rows
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json (make lamp's)")
    parser.add_argument("--photons", type=float, default=4e6, help="photons per emitter (default 4 M)")
    args = parser.parse_args()
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        if loaded.design["light"].get("type") == "collimated" or loaded.design["light"].get("length", 0.0):
            print(f"\n{build}: not a ball-shaped LED; skipped")
            continue
        print(f"\n{build}: LED radius {loaded.design['light']['radius']:g} mm, {args.photons / 1e6:g} M photons each")
        print("| wall | LED | r | SSIM | light on the wall | of it in the lower half |")
        print("|---|---|---|---|---|---|")
        for name, rows in figures(loaded, int(args.photons), 7).items():
            for f in rows:
                print(f"| {f['wall']} | {name} | {f['r']:.3f} | {f['ssim']:.3f} | {f['share']:.1%} "
                      f"| {f['lower_half']:.0%} |")


if __name__ == "__main__":
    main()
