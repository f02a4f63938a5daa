#!/usr/bin/env python3
"""Make the README's result pictures from finished builds.

    make lamp TARGET=examples/apple.png && .venv/bin/python examples/figures.py apple

writes examples/results/apple.png: the target, then what verify rendered from the
exported STL on each wall (point light, then the LED's real size), with Pearson r; and
examples/results/apple_room.png, the report's path-traced picture of the lamp in its room.
When the walls have different targets (a panorama, per-wall images), a first row shows
each wall's target.  ``--build DIR`` reads DIR/<name> instead of build/<name>.
"""

import argparse
import json
from pathlib import Path

from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parent.parent
TILE = 192


def tile(path: Path, label: str) -> Image.Image:
    img = Image.open(path).convert("L")
    img = img.resize((TILE, round(TILE * img.height / img.width)), Image.NEAREST)
    out = Image.new("L", (TILE, img.height + 18), 0)
    out.paste(img, (0, 18))
    ImageDraw.Draw(out).text((4, 3), label, fill=220)
    return out


def figure(name: str, builds: Path = ROOT / "build") -> Path:
    build = builds / name
    verify = json.loads((build / "verify.json").read_text())["figures"]["walls"]
    targets = [build / "targets" / f"{wall}_preview.png" for wall in verify]
    tiles = [tile(targets[0], "target")]
    for wall, f in verify.items():
        tiles.append(tile(build / "verify" / f"{wall}.png", f"{wall}: r {f['pearson']:.2f}"))
    for wall, f in verify.items():
        tiles.append(tile(build / "verify" / f"{wall}_led.png", f"{wall}, LED: r {f['led_pearson']:.2f}"))
    columns = 1 + len(verify)
    rows = [tiles[:columns], [Image.new("L", tiles[0].size, 0)] + tiles[columns:]]
    if len({p.read_bytes() for p in targets}) > 1:  # a target per wall: a row of them instead
        columns -= 1
        rows = [[tile(p, f"target: {wall}") for p, wall in zip(targets, verify)], tiles[1:columns + 1],
                tiles[columns + 1:]]
    height = sum(max(t.height for t in row) for row in rows)
    sheet = Image.new("L", (columns * (TILE + 4), height + 4), 0)
    y = 0
    for row in rows:
        for i, t in enumerate(row):
            sheet.paste(t, (i * (TILE + 4), y))
        y += max(t.height for t in row)
    out = ROOT / "examples" / "results" / f"{name}.png"
    out.parent.mkdir(exist_ok=True)
    sheet.save(out)
    room = build / "report" / "room.png"           # the report's picture of the lamp in its room
    if room.exists():
        Image.open(room).save(out.with_name(f"{name}_room.png"))
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="+", help="build names, e.g. apple for build/apple")
    parser.add_argument("--build", type=Path, default=ROOT / "build", help="the builds' folder (default: build)")
    args = parser.parse_args()
    for n in args.names:
        print(figure(n, args.build))
