#!/usr/bin/env python3
"""Make the result pictures from finished builds.

    make lamp TARGET=examples/apple.png && .venv/bin/python examples/figures.py apple

writes examples/results/apple.png: the target, then what verify traced from the exported
STL on each wall: with the LED's real size (what a person sees) in the first row, with
an ideal point light in the second, and Mitsuba's light tracer (LED) in a third when
verify ran it; each with its Pearson r.  Also examples/results/apple_room.png and
apple_closeup.png, the report's pictures of the lamp in its room and of the lens.  When
the walls have different targets (a panorama, per-wall images), a first row shows each
wall's target.  ``--build DIR`` reads DIR/<name> instead of build/<name>.
"""

import argparse
import json
import shutil
from pathlib import Path

from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "examples" / "results"
TILE = 192


def tile(path: Path, label: str) -> Image.Image:
    img = Image.open(path).convert("L")
    img = img.resize((TILE, round(TILE * img.height / img.width)), Image.BICUBIC)
    out = Image.new("L", (TILE, img.height + 18), 0)
    out.paste(img, (0, 18))
    ImageDraw.Draw(out).text((4, 3), label, fill=220)
    return out


def figure(name: str, builds: Path = ROOT / "build") -> Path:
    build = builds / name
    verify = json.loads((build / "verify.json").read_text())["figures"]
    walls = verify["walls"]
    light = verify["real_light"]
    targets = [build / "targets" / f"{wall}_preview.png" for wall in walls]
    # r first: a long light's name is cut at the tile's edge, not the figure.
    rows = [[tile(build / "verify" / f"{wall}_led.png", f"{wall}, r {f['led_pearson']:.2f}: {light}")
             for wall, f in walls.items()],
            [tile(build / "verify" / f"{wall}.png", f"{wall}, point: r {f['pearson']:.2f}")
             for wall, f in walls.items()]]
    if all((build / "verify" / f"{wall}_mitsuba.png").exists() for wall in walls):
        rows.append([tile(build / "verify" / f"{wall}_mitsuba.png", f"{wall}, Mitsuba: r {f['mitsuba_pearson']:.3f}")
                     for wall, f in walls.items()])
    if len({p.read_bytes() for p in targets}) > 1:  # a target per wall: a row of them above
        rows.insert(0, [tile(p, f"target: {wall}") for p, wall in zip(targets, walls)])
    else:
        blank = Image.new("L", rows[0][0].size, 0)
        rows = [[tile(targets[0], "target")] + rows[0]] + [[blank] + row for row in rows[1:]]
    columns = max(len(row) for row in rows)
    height = sum(max(t.height for t in row) + 4 for row in rows)
    sheet = Image.new("L", (columns * (TILE + 4), height), 0)
    y = 0
    for row in rows:
        for i, t in enumerate(row):
            sheet.paste(t, (i * (TILE + 4), y))
        y += max(t.height for t in row) + 4
    out = RESULTS / f"{name}.png"
    out.parent.mkdir(exist_ok=True)
    sheet.save(out)
    for picture in ("room", "closeup"):  # the report's pictures of the lamp and the lens
        made = build / "report" / f"{picture}.png"
        if made.exists():
            shutil.copyfile(made, RESULTS / f"{name}_{picture}.png")
    return out


def before_after(pairs: list[tuple[str, str]], builds: Path = ROOT / "build", wall: str = "front",
                 labels: tuple[str, str] = ("point design", "LED design"), name: str = "led_design") -> Path:
    """examples/results/<name>.png: per (before, after) pair of build names (the
    point-light design and the LED-aware one; a lens without slots and with them), ``wall``'s target
    and what the LED draws through each lens, captioned with ``labels``."""

    def seen(build: str, label: str) -> Image.Image:
        f = json.loads((builds / build / "verify.json").read_text())["figures"]["walls"][wall]
        words = f", {f['led_words_read']}/{f['words']} words" if "words" in f else ""
        return tile(builds / build / "verify" / f"{wall}_led.png", f"{label}: SSIM {f['led_ssim']:.2f}{words}")

    rows = [[tile(builds / after / "targets" / f"{wall}_preview.png", f"target ({wall})"),
             seen(before, labels[0]), seen(after, labels[1])] for before, after in pairs]
    height = max(t.height for row in rows for t in row) + 4
    sheet = Image.new("L", (3 * (TILE + 4), height * len(rows)), 0)
    for y, row in enumerate(rows):
        for i, t in enumerate(row):
            sheet.paste(t, (i * (TILE + 4), y * height))
    out = RESULTS / f"{name}.png"
    sheet.save(out)
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="+", help="build names, e.g. apple for build/apple")
    parser.add_argument("--build", type=Path, default=ROOT / "build", help="the builds' folder (default: build)")
    args = parser.parse_args()
    for n in args.names:
        print(figure(n, args.build))
