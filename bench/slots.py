#!/usr/bin/env python3
"""What black-filled slots at the lens's sector edges would change, measured on made lenses.

    .venv/bin/python bench/slots.py build/apple [build/horse ...] [--floors 20,25,30] [--reach 30] [--photons 32000000]

About 4 % of the light is reflected back into the glass where it leaves the outer
surface.  Near the edge of a wall's sector part of it runs on through the glass as a
chord that never enters the hollow (where the post's fins stop what crosses), into
another wall's sector, and leaves there as a haze over that wall's picture
(``bench/light_in_black.py --sectors``: on the apple, the right sector's reflections are
0.9 % of the left wall's light).  A slot cut radially at every edge between two sectors,
from the outer surface in to some distance from the axis (its floor), its walls filled
or painted black, would stop those chords.

lampfab makes blind slots of this kind as an option (``[lens] slot_width_mm``,
``lampfab.slots``): open through the base, short of the outer surface, and known to the
refinement. This script measures the idealised ones on lenses made without them: it
traces each build's exported STL with its LED as verify does (stratified photons,
64 px), once as made and once for each floor radius with the slots modelled as black
half-planes at the sectors' edges (design.json's walls; the fins' azimuths), from the
floor outwards (to ``--reach`` mm from the axis: a slot open to the hollow instead,
which leaves the outer surface whole) and 5 mm short of the base and the top, that end
the light inside the lens (never the light on its way to a wall). They take no glass
away, so the light a real slot's width (about a millimetre) would take from the outer
surface beside each edge is not counted. Per wall: its share of the emitted light, the
light reflected inside the lens, and the LED render's r and SSIM against the target.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import fins, metrics, verify  # noqa: E402
from lampfab.source import Source  # noqa: E402

MARGIN_MM = 5.0  # glass left whole above the base and below the top, where the quarters join
_FINS_ONLY = fins.stops


def slot_stops(floor_mm: float, height_mm: float, reach_mm: float = float("inf")):
    """``fins.stops`` with black half-planes at the fins' azimuths added, from
    ``floor_mm`` out to ``reach_mm`` and ``MARGIN_MM`` inside the base and the top, for
    the rays that meet the lens again (``t_max`` finite: inside the glass or its hollow)."""
    def stops(mi, source, o, d, t_max=None):
        import drjit as dr

        stopped = _FINS_ONLY(mi, source, o, d, t_max)
        if t_max is None:  # the light leaving the LED, which no slot can meet
            return stopped
        for a in np.radians(source.fin_azimuths_deg()):
            along = mi.Vector3f(float(np.cos(a)), float(np.sin(a)), 0.0)
            across = mi.Vector3f(float(-np.sin(a)), float(np.cos(a)), 0.0)
            t = -dr.dot(o, across) / dr.dot(d, across)  # the half-plane through the lamp's axis
            hit = o + t * d
            reach = dr.dot(hit, along)
            stopped |= ((t > 0) & (t < t_max) & dr.isfinite(t_max) & (reach >= floor_mm) & (reach <= reach_mm)
                        & (hit.z >= MARGIN_MM) & (hit.z <= height_mm - MARGIN_MM))
        return stopped

    return stops


@contextlib.contextmanager
def slotted(floor_mm: float, height_mm: float, reach_mm: float = float("inf")):
    """Within it, every trace stops light at the slots (``slot_stops``) as well as at the fins."""
    fins.stops = slot_stops(floor_mm, height_mm, reach_mm)
    try:
        yield
    finally:
        fins.stops = _FINS_ONLY


def measure(loaded: verify.Loaded, photons: int, seed: int) -> list[dict]:
    """Per wall of the made lens traced with its LED: its share of the emitted light, the
    share of that reflected inside the lens, r and SSIM against the target."""
    images, info = verify.render_design(loaded, 64, photons, seed, 8)
    out = []
    for k, wall in enumerate(loaded.walls):
        target = loaded.target(k, images[k].shape)
        light = float(images[k].sum())
        out.append({"wall": wall.name, "share": light, "ghost": float(info["ghosts"][k].sum()) / light,
                    "r": metrics.pearson(images[k], target), "ssim": metrics.ssim(images[k], target)})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path)
    parser.add_argument("--floors", default="20,25,30", help="slot floors to try, mm from the axis (comma-separated)")
    parser.add_argument("--reach", type=float, default=float("inf"),
                        help="how far out the slots reach, mm from the axis (default: through the outer surface)")
    parser.add_argument("--photons", type=float, default=32e6)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    floors = [float(x) for x in args.floors.split(",")]
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        if not Source.from_json(loaded.design["light"]).fins:
            print(f"{build}: its LED has no fins to set the slots' azimuths by; skipped")
            continue
        height = float(loaded.vertices[:, 2].max())
        rows = [("as made", measure(loaded, int(args.photons), args.seed))]
        for floor in floors:
            span = f"from {floor:g} mm" + ("" if np.isinf(args.reach) else f" to {args.reach:g} mm")
            with slotted(floor, height, args.reach):
                rows.append((f"slots {span}", measure(loaded, int(args.photons), args.seed)))
        print(f"\n{build}: {args.photons / 1e6:.0f} M photons with its LED; per wall (front / left / right): "
              "share of the light, reflected inside the lens, r, SSIM")
        print("| lens | light on the walls | reflected inside | LED r | LED SSIM |")
        print("|---|---|---|---|---|")
        for name, walls in rows:
            cells = [" / ".join(f"{w[key] * scale:{fmt}}" for w in walls)
                     for key, scale, fmt in (("share", 100, ".1f"), ("ghost", 100, ".2f"), ("r", 1, ".3f"),
                                             ("ssim", 1, ".3f"))]
            print(f"| {name} | {cells[0]} % | {cells[1]} % | {cells[2]} | {cells[3]} |")


if __name__ == "__main__":
    main()
