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
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import artifacts, image, metrics, verify  # noqa: E402

PLACES = {1: "inner layer", 2: "outer surface", 3: "flat faces"}
BLACK = 0.05  # of the target's peak
FLAT_NZ = np.cos(np.radians(8.0))  # the outer surface tilts 60-75° at most (the profiles' slope limits)


def place(p, n):
    """Code of the facet at points ``p`` with outward normals ``n`` (Dr.Jit), see PLACES."""
    import drjit as dr

    from lampfab.mi_env import mitsuba

    mi = mitsuba()
    radial = (p.x * n.x + p.y * n.y) / dr.maximum(dr.sqrt(p.x * p.x + p.y * p.y), 1e-6)
    return dr.select(dr.abs(n.z) > FLAT_NZ, mi.UInt32(3), dr.select(radial < 0, mi.UInt32(1), mi.UInt32(2)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json (make lamp's)")
    parser.add_argument("--photons", type=float, default=16e6, help="photons traced (default: verify's 16 M)")
    args = parser.parse_args()
    for build in args.builds:
        design_path = build / "design.json"
        design = verify.read_design(design_path)
        walls, images, info = verify.render_design(design_path, 64, int(args.photons), 7, 8, 0.0, place)
        print(f"\n{build}: share of each wall's light / of it in the target's black / the wall's SSIM without it")
        print("| wall | SSIM | never reflected | " + " | ".join(f"off the {name}" for name in PLACES.values()) + " |")
        print("|---|---|" + "---|" * (1 + len(PLACES)))
        for k, wall in enumerate(walls):
            target = image.letterbox(artifacts.read_linear_png16(build / design["walls"][k]["target"]), *images[k].shape)
            black = target < BLACK * target.max()
            total = images[k]
            parts = {code: info["ghosts_by_place"].get(code, [np.zeros_like(total)] * len(walls))[k] for code in PLACES}
            parts[0] = total - sum(parts.values())
            cells = []
            for code in [0, *PLACES]:
                part = np.where(black, parts[code], 0.0) if code == 0 else parts[code]
                cells.append(f"{parts[code].sum() / total.sum():.1%} / {part[black].sum() / total.sum():.1%} / "
                             f"{metrics.ssim(total - part, target):.2f}")
            print(f"| {wall.name} | {metrics.ssim(total, target):.3f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
