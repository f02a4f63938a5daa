#!/usr/bin/env python3
"""The refinement's search for each photon's facet: the facet walk against Mitsuba's BVH.

    .venv/bin/python bench/facet_walk.py build/apple [--repeats 5] [--record]

On the build's lens (its ``heightmap.npz``, or ``init.npz`` before optimize) one fine
step's photons (the profile's count, from the build's LED) are traced into the glass;
then, ``--repeats`` times each: Mitsuba builds its BVH of the outer mesh and
intersects the photons with it (what every refinement step would need, as every step
moves every vertex), and ``facetwalk.first_hits`` walks to their facets.  Printed:
median seconds of each, their ratio, and how many photons the two give the same facet
(of those with flux that Mitsuba finds a facet for), how many the walk leaves
unsettled, and how many it gives another facet to.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import facetwalk, pipeline, surface  # noqa: E402
from lampfab.trace import MeshScene  # noqa: E402


def heights_of(build: Path) -> np.ndarray:
    """(nu, nv) mm: the refined lens, or the first design before optimize."""
    path = build / "heightmap.npz"
    return np.load(path if path.exists() else build / "init.npz")["heights"]


def measure(build: Path, repeats: int) -> dict:
    import drjit as dr

    settings = json.loads((build / "settings.json").read_text())
    opened = pipeline.Build.open(build, *(settings[k]["path"] for k in ("design", "fabrication", "led")))
    opt = opened.design.optimize
    optimizer = opened.optimizer(opt, opened.inner(), opened.targets(opt.sensor_px))
    heights = heights_of(build)
    optimizer._ensure_scene(heights)
    optimizer._photons(seed=1, level=-1)
    mi, o, d = optimizer.mi, optimizer.o_glass, optimizer.d_glass
    verts, faces = surface.closed_outer_mesh(optimizer.cyl, heights, opt.tessellation)
    bvh_s, walk_s = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        outer = MeshScene(verts, faces)
        si = outer.scene.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
        dr.eval(si.prim_index, si.t)
        dr.sync_thread()
        bvh_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        hit, settled = facetwalk.first_hits(mi, o, d, dr.unravel(mi.Point3f, optimizer.positions), *optimizer.fine,
                                            optimizer.cyl.height_mm, optimizer.walk_radius_mm)
        dr.eval(hit, settled)
        dr.sync_thread()
        walk_s.append(time.perf_counter() - t0)
    found = si.is_valid().numpy() & (optimizer.w_glass.numpy() > 0)
    same = hit.numpy() == si.prim_index.numpy()
    settled = settled.numpy()
    return {"build": build.name, "photons": int(dr.width(d)), "with flux": int(found.sum()),
            "facets": len(faces), "bvh_s": float(np.median(bvh_s)), "walk_s": float(np.median(walk_s)),
            "same": int((same & found).sum()), "unsettled": int((~settled & found).sum()),
            "other": int((~same & settled & found).sum())}


def report(rows: list[dict], repeats: int) -> str:
    lines = [f"Median of {repeats} runs each, one fine step's photons on each lens:", "",
             "| build | photons (with flux) | facets | BVH build + intersection (s) | facet walk (s) | ratio "
             "| same facet | unsettled | another facet |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        n = r["with flux"]
        lines.append(f"| {r['build']} | {r['photons']:,} ({n:,}) | {r['facets']:,} | {r['bvh_s']:.3f} | "
                     f"{r['walk_s']:.3f} | {r['bvh_s'] / r['walk_s']:.1f}x | {100 * r['same'] / n:.3f} % | "
                     f"{r['unsettled']:,} | {r['other']:,} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("builds", type=Path, nargs="+", help="build folders (make init or later)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    text = report([measure(b, args.repeats) for b in args.builds], args.repeats)
    print(text, flush=True)
    if args.record:
        import log_section

        log_section.record("## The facet walk against Mitsuba's BVH (bench/facet_walk.py)\n\n" + text)


if __name__ == "__main__":
    main()
