#!/usr/bin/env python3
"""Time-to-quality: the source's method (``seed``: ptracer from the plain cylinder,
cyclic views) against lampfab's default (transport init + ``splat`` refinement).

    make bench                      # budgets 30 s and 120 s, the bundled apple
    .venv/bin/python bench/bench_methods.py --budgets 30 120 600 --image examples/star.png

Both run on the same scene (default profile: lens, room, grid, tessellation) in this
one process, one after the other.  At each wall-clock budget the current surface is
rendered with the photon tracer through its true facets (4M photons, 64 px wide),
the same measure verify applies to the exported STL (verify also has the LED bore),
and compared with the targets: Pearson r and SSIM per wall, and the share of the
light on the walls.  Prints a table and the ratios; --record appends to
bench/RESULTS.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import lens, metrics, optimize, pipeline, splat, trace, transport  # noqa: E402


def measure(build, inner, heights, targets):
    verts, faces = lens.optical_mesh(build.cylinder, heights, build.design.optimize.tessellation, *inner)
    images, info = trace.render_walls(trace.MeshScene(verts, faces), build.light, 0.0, build.fab.ior, build.walls,
                                      [t.shape for t in targets], 4_000_000, seed=99)
    figs = [metrics.compare(i, t) for i, t in zip(images, targets)]
    return {"r": min(f["pearson"] for f in figs), "ssim": min(f["ssim"] for f in figs),
            "share": sum(info["shares"])}


def run_method(name, build, inner, targets, budgets, start_heights, opt, cls, elapsed0):
    """Optimize until each budget (seconds since the method started, init included)."""
    results = []
    state = optimize.State(start_heights.copy(), 0, 0)
    runner = cls(build.cylinder, *inner, build.light, build.fab.ior, build.walls, build.targets(opt.sensor_px), opt,
                 build.design.lens.max_offset_mm, build.fab.max_slope_deg)
    t0 = time.time() - elapsed0
    for budget in budgets:
        while time.time() - t0 < budget:
            runner.opt = dataclasses.replace(opt, iterations=state.step + 1)
            state = runner.run(state, lambda s: None, lambda s: None, lambda s, loss, msg: None)
        row = measure(build, inner, state.heights, targets)
        row.update(method=name, budget_s=budget, steps=state.step)
        results.append(row)
        print(f"{name:9s} {budget:6.0f} s  {state.step:5d} steps  r {row['r']:.3f}  SSIM {row['ssim']:.3f}  "
              f"light on walls {row['share']:.1%}", flush=True)
    return results


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--image", default=str(ROOT / "examples" / "apple.png"))
    ap.add_argument("--budgets", type=float, nargs="+", default=[30, 120])
    ap.add_argument("--record", action="store_true", help="append the table to bench/RESULTS.md")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        build = pipeline.Build.open(tmp, "default", "sla_resin")
        pipeline.prepare(build, args.image, {})
        inner = build.inner()
        targets = build.targets(64)
        d = build.design
        grid = (d.optimize.grid_u, d.optimize.grid_v)

        # The source's method: plain cylinder, ptracer, cyclic views, coarse-to-fine.
        seed_opt = dataclasses.replace(d.optimize, method="seed", schedule="cyclic", levels=2, spp=64,
                                       iterations=10**9, preview_every=10**9, checkpoint_every=10**9)
        seed_rows = run_method("seed", build, inner, targets, args.budgets, np.zeros(grid), seed_opt,
                               optimize.SeedOptimizer, 0.0)

        # lampfab's default: transport init (timed), then splat.
        t0 = time.time()
        heights, _ = transport.design(build.cylinder, build.walls, build.targets(64), *inner, build.light,
                                      build.fab.ior, grid, d.optimize.tessellation, d.optimize.transport_rounds,
                                      d.optimize.transport_photons, d.optimize.smoothness, d.lens.max_offset_mm,
                                      build.fab.max_slope_deg, d.optimize.seed,
                                      corrections=d.optimize.transport_corrections,
                                      dump_share=d.optimize.dump_share, log=lambda m: None)
        init_s = time.time() - t0
        init_row = measure(build, inner, heights, targets)
        print(f"{'transport':9s} {init_s:6.1f} s  {0:5d} steps  r {init_row['r']:.3f}  SSIM {init_row['ssim']:.3f}  "
              f"light on walls {init_row['share']:.1%}  (before any gradient step)", flush=True)
        splat_opt = dataclasses.replace(d.optimize, iterations=10**9, preview_every=10**9, checkpoint_every=10**9)
        splat_rows = run_method("lampfab", build, inner, targets, args.budgets, heights, splat_opt,
                                splat.SplatOptimizer, init_s)

    best_seed = max(r["r"] for r in seed_rows)
    reach = next((r["budget_s"] for r in splat_rows if r["r"] >= best_seed), None)
    if init_row["r"] >= best_seed:
        reach = init_s
    lines = ["", f"## {time.strftime('%Y-%m-%d')} on {platform.machine()}, {platform.processor() or 'CPU'}, "
             f"{__import__('os').cpu_count()} cores; image {Path(args.image).name}", "",
             "| method | budget s | steps | min r | min SSIM | light on walls |", "|---|---|---|---|---|---|"]
    for r in seed_rows + [dict(method="transport only", budget_s=round(init_s, 1), steps=0, **init_row)] + splat_rows:
        lines.append(f"| {r['method']} | {r['budget_s']} | {r['steps']} | {r['r']:.3f} | {r['ssim']:.3f} | "
                     f"{r['share']:.1%} |")
    lines.append("")
    lines.append(f"seed's best r within {max(args.budgets):.0f} s: {best_seed:.3f}; lampfab reaches it after "
                 f"{'%.0f s' % reach if reach else 'more than the budget'}"
                 + (f" ({max(args.budgets) / reach:.1f}x sooner at least)" if reach else ""))
    print("\n".join(lines))
    if args.record:
        with open(ROOT / "bench" / "RESULTS.md", "a") as fh:
            fh.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
