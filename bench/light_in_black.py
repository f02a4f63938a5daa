#!/usr/bin/env python3
"""Where a made lens's light in the target's black comes from.

    .venv/bin/python bench/light_in_black.py build/apple [build/horse ...]

Traces each build's exported STL as verify does (point light, 64 px, the photons given)
and splits every wall's light by where it was first reflected inside the lens: never
(the light the outer surface steers), off the inner layer, off the outer surface (back
into the glass), or off a flat face (the caps).  A facet is the inner layer's where its
outward normal points towards the axis, a flat face where it is within 8° of vertical.
For each part: its share of the wall's light, the share that lands in the target's
black (below 5 % of its peak), and the wall's SSIM without that part (for the light
never reflected: without its part in the black): what the made lamp would score were
that light gone.

With ``--sectors`` the outer surface's part is split by the 90° sector of the lens where
the reflection happened (right: u -45..45°, front, left, back), which tells which
sector's reflections reach which wall.

With ``--lens-cells`` it also says where on the lens the direct light in the black
leaves it: the exit points of the light never reflected, binned in 5° of u by 10 mm of
height, and the cells that send more than a quarter of their light into the black.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import metrics, verify  # noqa: E402
from lampfab.source import Source  # noqa: E402

PLACES = {1: "inner layer", 2: "outer surface", 3: "flat faces"}
SECTORS = ("right", "front", "left", "back")  # by u, from -45°, 90° each
PLACES_BY_SECTOR = {1: "inner layer", **{4 + k: f"outer surface, {name} sector" for k, name in enumerate(SECTORS)},
                    3: "flat faces"}
BLACK = 0.05  # of the target's peak
FLAT_NZ = np.cos(np.radians(8.0))  # the outer surface tilts 60-75° at most (the profiles' slope limits)
CELL_DEG, CELL_MM = 5.0, 10.0  # --lens-cells: the bins of exit points on the lens, in u and height
DARK_CELL = 0.25  # a lens cell listed: this share of its light or more lands in the black
LISTED_CELLS = 8  # per wall, those that put the most light into the black


def place(p, n):
    """Code of the facet at points ``p`` with outward normals ``n`` (Dr.Jit), see PLACES."""
    import drjit as dr

    from lampfab.mi_env import mitsuba

    mi = mitsuba()
    radial = (p.x * n.x + p.y * n.y) / dr.maximum(dr.sqrt(p.x * p.x + p.y * p.y), 1e-6)
    return dr.select(dr.abs(n.z) > FLAT_NZ, mi.UInt32(3), dr.select(radial < 0, mi.UInt32(1), mi.UInt32(2)))


def place_by_sector(p, n):
    """``place``, with the outer surface's code 2 split by sector: see PLACES_BY_SECTOR."""
    import drjit as dr

    from lampfab.mi_env import mitsuba

    mi = mitsuba()
    from_right_edge = dr.atan2(p.y, p.x) + np.pi / 4
    from_right_edge = dr.select(from_right_edge < 0, from_right_edge + 2 * np.pi, from_right_edge)
    sector = mi.UInt32(dr.minimum(dr.floor(from_right_edge / (np.pi / 2)), 3))
    code = place(p, n)
    return dr.select(code == 2, 4 + sector, code)


def lens_cells(loaded: verify.Loaded, blacks: list[np.ndarray], photons: int, seed: int) -> None:
    """Print, per wall, the lens cells whose direct light lands in ``blacks`` ((rows,
    cols) bool per wall) most: traced with a point light as verify does."""
    from lampfab import trace
    from lampfab.mi_env import mitsuba

    mi = mitsuba()
    design, walls = loaded.design, loaded.walls
    shapes = [b.shape for b in blacks]
    exits, pixels = [], []

    def on_escape(o, d, reflected):
        direct = reflected.numpy() == 0
        exits.append(trace.to_numpy(o)[direct])
        pixels.append(trace.pixel_hits(mi, walls, shapes, o, d)[direct])

    o, d = trace.emit(mi, Source.from_json(design["light"]).point(), photons, seed)
    trace.propagate(mi, loaded.scene.scene, o, d, float(design["material"]["ior"]), seed, 8, on_escape,
                    painted=loaded.scene.painted)
    points, pixel = np.concatenate(exits), np.concatenate(pixels)
    u = np.degrees(np.arctan2(points[:, 1], points[:, 0])) % 360.0
    bins = [np.arange(0.0, 360.0 + CELL_DEG, CELL_DEG), np.arange(0.0, points[:, 2].max() + CELL_MM, CELL_MM)]
    offset = 0
    for wall, black in zip(walls, blacks):
        local = pixel - offset
        on_wall = (local >= 0) & (local < black.size)
        offset += black.size
        dark = on_wall & black.ravel()[np.where(on_wall, local, 0)]
        every, _, _ = np.histogram2d(u[on_wall], points[on_wall, 2], bins)
        in_black, _, _ = np.histogram2d(u[dark], points[dark, 2], bins)
        share = in_black / np.maximum(every, 1)
        listed = share > DARK_CELL
        print(f"\n{wall.name}: {dark.sum() / max(on_wall.sum(), 1):.1%} of the direct light lands in the black; "
              f"lens cells that send more than {DARK_CELL:.0%} of theirs there carry "
              f"{in_black[listed].sum() / max(in_black.sum(), 1):.0%} of it and "
              f"{every[listed].sum() / max(every.sum(), 1):.1%} of the wall's direct light")
        for i, j in sorted(zip(*np.nonzero(listed)), key=lambda c: -in_black[c])[:LISTED_CELLS]:
            print(f"  u {bins[0][i]:.0f}-{bins[0][i + 1]:.0f} deg, z {bins[1][j]:.0f}-{bins[1][j + 1]:.0f} mm: "
                  f"{share[i, j]:.0%} of its light in the black, "
                  f"{in_black[i, j] / in_black.sum():.1%} of the wall's there")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json (make lamp's)")
    parser.add_argument("--photons", type=float, default=16e6, help="photons traced (default: verify's 16 M)")
    parser.add_argument("--sectors", action="store_true",
                        help="split the outer surface's reflections by the sector they happen in")
    parser.add_argument("--lens-cells", action="store_true",
                        help="also list the lens cells whose direct light lands in the black (4 M more photons)")
    args = parser.parse_args()
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        walls = loaded.walls
        places = PLACES_BY_SECTOR if args.sectors else PLACES
        images, info = verify.render_design(loaded, 64, int(args.photons), 7, 8, True,
                                            place_by_sector if args.sectors else place)
        print(f"\n{build}: share of each wall's light / of it in the target's black / the wall's SSIM without it")
        print("| wall | SSIM | never reflected | " + " | ".join(f"off the {name}" for name in places.values()) + " |")
        print("|---|---|" + "---|" * (1 + len(places)))
        blacks = []
        for k, wall in enumerate(walls):
            target = loaded.target(k, images[k].shape)
            black = target < BLACK * target.max()
            blacks.append(black)
            total = images[k]
            parts = {code: info["ghosts_by_place"].get(code, [np.zeros_like(total)] * len(walls))[k] for code in places}
            parts[0] = total - sum(parts.values())
            cells = []
            for code in [0, *places]:
                part = np.where(black, parts[code], 0.0) if code == 0 else parts[code]
                cells.append(f"{parts[code].sum() / total.sum():.1%} / {part[black].sum() / total.sum():.1%} / "
                             f"{metrics.ssim(total - part, target):.2f}")
            print(f"| {wall.name} | {metrics.ssim(total, target):.3f} | " + " | ".join(cells) + " |")
        if args.lens_cells:
            lens_cells(loaded, blacks, 4_000_000, 3)


if __name__ == "__main__":
    main()
