#!/usr/bin/env python3
"""Which of a post's LEDs lights each part of a wall's picture.

    .venv/bin/python bench/neighbour_light.py build/text [build/apple ...] [--photons 4000000] [--record]

Traces each build's exported STL as verify does (the LEDs' real size, 64 px) with all
its LEDs, then with each LED alone (its own two fins; a fin between two other LEDs only
stops light reflected back across the hollow, a small part).  For every wall and each
eighth of its picture's columns, left to right: the share of that eighth's light that
each LED sends, and the eighth's light over what the target blurred by the LED
(verify's ``led_reference``) puts there, both pictures scaled to the same total: under 1
the lens leaves that eighth dimmer than a perfect design would.

A patch of the lens within 10-14° of the edge between two walls' sectors sees the
neighbouring wall's LED past the fins' tips, through the glass beside the cavity, and
draws a second copy of its picture there, offset by several pixels.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from lampfab import room, verify  # noqa: E402
from lampfab.profile import Verify  # noqa: E402

BANDS = 8
SEED = 1  # one seed for every render of a build: the LEDs' photons leave alike


def _bands(image: np.ndarray) -> np.ndarray:
    """(BANDS,) the light in each eighth of ``image``'s columns."""
    return np.array([part.sum() for part in np.array_split(image.sum(axis=0), BANDS)])


def table(build: Path, photons: int) -> str:
    loaded = verify.load(build / "design.json")
    light = loaded.design["light"]
    if light.get("shape") != "post":
        return f"{build.name}: not a post's LEDs ({light.get('shape')}); nothing to split"
    settings = Verify()
    full, _ = verify.render_design(loaded, settings.image_px, photons, SEED, settings.max_bounces)
    alone = {}
    for facing in light["facing_deg"]:
        loaded.design["light"] = dict(light, facing_deg=[facing])
        alone[facing], _ = verify.render_design(loaded, settings.image_px, photons, SEED, settings.max_bounces)
    loaded.design["light"] = light
    n_leds = len(light["facing_deg"])
    head = " | ".join(f"{i + 1}/{BANDS}" for i in range(BANDS))
    rows = [f"`{build.name}`, {photons / 1e6:g} M photons; columns: the picture's eighths, left to right", "",
            f"| wall | light from | {head} |", "|---|---|" + "---|" * BANDS]
    for k, wall in enumerate(loaded.walls):
        total = _bands(full[k])
        # Each LED alone emits all the photons; in the full render each sends one n-th of them.
        for facing, images in alone.items():
            facing_wall = _facing_wall(loaded.walls, facing)
            share = _bands(images[k]) / n_leds / np.maximum(total, 1e-300)
            rows.append(f"| {wall.name} | the {facing_wall} wall's LED | " + " | ".join(f"{s:.2f}" for s in share) + " |")
        npz = build / "verify" / f"{wall.name}.npz"
        if npz.exists():
            arrays = np.load(npz)
            reference = _bands(arrays["led_reference"])
            made = _bands(arrays["led"] - arrays["ghosts"])
            ratio = (made / made.sum()) / np.maximum(reference / reference.sum(), 1e-300)
            cells = [f"{r:.2f}" if ref > 0.01 * reference.sum() else "—" for r, ref in zip(ratio, reference)]
            rows.append(f"| {wall.name} | light over a perfect design's | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def _facing_wall(walls: list[room.Wall], facing_deg: float) -> str:
    """The wall whose sector an LED facing ``facing_deg`` lights, or "back"."""
    for wall in walls:
        if abs((np.mean(wall.sector_deg()) - facing_deg + 180.0) % 360.0 - 180.0) < 1.0:
            return wall.name
    return "back"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("builds", nargs="+", type=Path)
    parser.add_argument("--photons", type=int, default=4_000_000)
    parser.add_argument("--record", action="store_true", help="append the tables to today's bench/log file")
    args = parser.parse_args()
    tables = []
    for build in args.builds:
        tables.append(table(build, args.photons))
        print(tables[-1] + "\n", flush=True)
    if args.record:
        import log_section

        log_section.record("## Which LED lights each part of a picture (bench/neighbour_light.py)\n\n"
                           + "\n\n".join(tables))


if __name__ == "__main__":
    main()
