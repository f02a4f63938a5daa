#!/usr/bin/env python3
"""Make the README's result pictures from finished builds.

    make lamp TARGET=examples/apple.png && .venv/bin/python examples/figures.py apple

writes examples/results/apple.png: the target, then what verify rendered from the
exported STL on each wall (point light, then the LED's real size), with Pearson r.
"""

import json
import sys
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


def figure(name: str) -> Path:
    build = ROOT / "build" / name
    verify = json.loads((build / "verify.json").read_text())["figures"]["walls"]
    tiles = [tile(build / "targets" / f"{next(iter(verify))}_preview.png", "target")]
    for wall, f in verify.items():
        tiles.append(tile(build / "verify" / f"{wall}.png", f"{wall}: r {f['pearson']:.2f}"))
    for wall, f in verify.items():
        tiles.append(tile(build / "verify" / f"{wall}_led.png", f"{wall}, LED: r {f['led_pearson']:.2f}"))
    columns = 1 + len(verify)
    rows = [tiles[:columns], [Image.new("L", tiles[0].size, 0)] + tiles[columns:]]
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
    return out


if __name__ == "__main__":
    for n in sys.argv[1:]:
        print(figure(n))
