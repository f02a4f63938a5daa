#!/usr/bin/env python3
"""What a lens projects with the LED it was designed for, against the other kind of LED
of the same size at the same place: a glowing ball, a flat LED facing up, flat LEDs
facing the walls.

    .venv/bin/python bench/led_emission.py build/apple [build/text ...] [--photons 4e6]
        [--picture bench/log/led_beam.png]

An LED in a small opal ball (``shape = "sphere"``) shines the same every way, the lamp's
walls lit from every elevation the lens covers.  An LED package on its flat board
(``shape = "disc"``) is a flat Lambertian emitter: facing up, as the board sits on its
stalk under the lens, it sends light upward in proportion to the cosine of the angle
from straight up, nothing sideways and nothing down.  A lens designed for one and lit
by the other shows what choosing the wrong part costs.  This script traces each build's
exported STL as verify does (64 px, stratified photons) with the build's own LED and
with the other shape, and per wall prints the render's r and SSIM against the target,
the wall's light (as a share of the emitted light) and the share of it in the picture's
lower half.  A lens designed for LEDs facing the walls (``shape = "post"``) is lit by
one such package facing up at the post's place instead.  ``--picture`` also writes each build's front wall as a row: the target,
then the lens with the LED it was designed for, then with the other LED.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import artifacts, metrics, trace, verify  # noqa: E402
from lampfab.source import Source  # noqa: E402

OTHER = {"sphere": "disc", "disc": "sphere", "post": "disc"}
NAMES = {"sphere": "ball", "disc": "flat, facing up", "post": "facing the walls"}


def figures(loaded: verify.Loaded, photons: int, seed: int) -> dict[str, list[dict]]:
    """{LED: per wall {"wall", "r", "ssim", "share", "lower_half", "image"}} for the
    design's own LED and the other shape of the same radius."""
    own = Source.from_json(loaded.design["light"])
    other = dataclasses.replace(own, shape=OTHER[own.shape], facing_deg=(), offset_mm=0.0, fin_radius_mm=0.0,
                                fin_height_mm=0.0)
    out = {}
    for name, source in ((f"{NAMES[own.shape]} (designed for)", own), (NAMES[other.shape], other)):
        images, _ = verify.render_design(loaded, 64, photons, seed, 8,
                                         emitter=lambda mi, n, s, source=source: trace.emit(mi, source, n, s))
        rows = []
        for k, (wall, img) in enumerate(zip(loaded.walls, images)):
            target = loaded.target(k, img.shape)
            total = float(img.sum())
            rows.append({"wall": wall.name, "r": metrics.pearson(img, target), "ssim": metrics.ssim(img, target),
                         "share": total, "lower_half": float(img[img.shape[0] // 2:].sum()) / total if total else 0.0,
                         "image": img, "target": target})
        out[name] = rows
    return out


def picture(rows: list[tuple[str, dict[str, list[dict]]]], path: Path, tile_px: int = 256) -> None:
    """One row per build: its front wall's target, then its renders (``figures``' order),
    each labelled, tone-mapped as verify's PNGs."""
    from PIL import Image, ImageDraw

    def tile(image, label):
        img = Image.fromarray(artifacts.srgb8(image))
        img = img.resize((tile_px, round(tile_px * img.height / img.width)), Image.BICUBIC)
        out = Image.new("L", (tile_px, img.height + 18), 0)
        out.paste(img, (0, 18))
        ImageDraw.Draw(out).text((4, 3), label, fill=220)
        return out

    grid = []
    for name, by_led in rows:
        front = {led: walls[0] for led, walls in by_led.items()}
        first = next(iter(front.values()))
        grid.append([tile(first["target"], f"{name}: target")]
                    + [tile(f["image"], f"{led}: r {f['r']:.2f}") for led, f in front.items()])
    w, h = grid[0][0].size
    sheet = Image.new("L", (w * max(len(r) for r in grid), h * len(grid)), 0)
    for i, row in enumerate(grid):
        for j, t in enumerate(row):
            sheet.paste(t, (j * w, i * h))
    sheet.save(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json (make lamp's)")
    parser.add_argument("--photons", type=float, default=4e6, help="photons per emitter (default 4 M)")
    parser.add_argument("--picture", type=Path, help="write the front walls side by side to this PNG")
    args = parser.parse_args()
    shown = []
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        light = loaded.design["light"]
        if light.get("type") == "collimated" or Source.from_json(light).shape not in OTHER:
            print(f"\n{build}: neither a ball nor a flat LED; skipped")
            continue
        print(f"\n{build}: LED radius {loaded.design['light']['radius']:g} mm, {args.photons / 1e6:g} M photons each")
        print("| wall | LED | r | SSIM | light on the wall | of it in the lower half |")
        print("|---|---|---|---|---|---|")
        found = figures(loaded, int(args.photons), 7)
        shown.append((build.name, found))
        for name, rows in found.items():
            for f in rows:
                print(f"| {f['wall']} | {name} | {f['r']:.3f} | {f['ssim']:.3f} | {f['share']:.1%} "
                      f"| {f['lower_half']:.0%} |")
    if args.picture and shown:
        picture(shown, args.picture)
        print(f"\n-> {args.picture}")


if __name__ == "__main__":
    main()
