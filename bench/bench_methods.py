#!/usr/bin/env python3
"""Time-to-quality: the source's method (``ptracer``: Mitsuba's ptracer from the plain cylinder,
cyclic views) against lampfab's default (transport init + ``splat`` refinement).

    make bench                      # budgets 30 60 120 180 240 300 450 600 900 s, the bundled apple
    .venv/bin/python bench/bench_methods.py --budgets 30 120 --image examples/star.png

Both run on the same scene (``--profile``, default: lens, room, grid, tessellation, slope
limit of the sla_resin profile) in this one process, one after the other.  The clock
of each method runs only while it computes (init included); measuring pauses it.  At
each wall-clock budget the current surface is made what the printer gets (projected
onto the fabrication limits, merged with the inner layer and the LED bore: the solid
whose triangles lens.stl holds) and traced with its true facets, as verify does (the
profile's ``[verify] photons``, stratified; 64 px wide) from the profile's LED, what a
person sees and what the default designs for, and from the ideal point light: Pearson r
and SSIM per wall, and the share of the emitted light on the walls.  The ratios compare
the LED's figures.  Prints a table and the ratios; --record appends them to
today's file in bench/log/ with the machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import metrics, optimize, pipeline, solid, trace  # noqa: E402
from lampfab.mi_env import mitsuba  # noqa: E402

VERIFY_PX = 64
GOAL_R = 0.9


def measure(build, inner, runner, heights, targets) -> dict:
    """verify's figures for the solid that would be exported from ``heights``: with the
    LED (``r``, ``ssim``, per wall and the least) and the point light (``point_...``)."""
    made = runner.makeable(heights)
    s = solid.build_solid(build.cylinder, made, build.design.optimize.tessellation, *inner, build.fab.mount_radius_mm)
    scene = trace.MeshScene(s.vertices, s.faces)
    out = {}
    for prefix, source in (("", build.source), ("point_", build.source.point())):
        images, info = trace.render_walls(scene, source, build.fab.ior, build.walls,
                                          [t.shape for t in targets], build.design.verify.photons, seed=99)
        figs = [metrics.compare(i, t) for i, t in zip(images, targets)]
        out.update({f"{prefix}r": min(f["pearson"] for f in figs), f"{prefix}ssim": min(f["ssim"] for f in figs),
                    f"{prefix}r_walls": [f["pearson"] for f in figs], f"{prefix}ssim_walls": [f["ssim"] for f in figs]})
        out.setdefault("share", sum(info["shares"]))  # the LED's, traced first
    return out


def optimizer(build, inner, opt, limits=None):
    """The refinement ``opt.method`` names for ``build``.  The source's method lights the
    lens with its own point light at the LED's place, as the source does: lampfab refuses
    that pairing for a maker's flat LEDs (they do not shine every way), but here it is
    the method being measured, and both methods are scored with the profile's LED."""
    targets = build.targets(opt.sensor_px)
    if opt.method != "ptracer":
        return build.optimizer(opt, inner, targets, limits)
    return optimize.PtracerOptimizer(build.cylinder, *inner, build.source.point(), build.fab.ior, build.walls,
                                     targets, opt, limits or build.limits)


def run_method(name, build, inner, targets, budgets, start_heights, opt, elapsed0, limits=None) -> list[dict]:
    """Optimize until each budget (seconds of computing since the method started,
    ``elapsed0`` of init included), under ``limits`` (default: the profiles'); stops
    early once the schedule is done."""
    rows = []
    state = optimize.State(start_heights.copy(), 0, 0)
    runner = optimizer(build, inner, opt, limits)
    spent = elapsed0
    last = None
    for budget in budgets:
        if spent < budget and state.step < opt.iterations:
            t0 = time.time()
            state = runner.run(state, lambda s: None, lambda s: None, lambda s, loss, msg: None,
                               deadline=t0 + budget - spent)
            spent += time.time() - t0
        if last is None or last["steps"] != state.step:
            last = measure(build, inner, runner, state.heights, targets)
            last["steps"] = state.step
        row = dict(last, method=name, budget_s=budget, spent_s=round(spent, 1))
        rows.append(row)
        print(f"{name:9s} {budget:6.0f} s  {row['steps']:5d} steps  {_figures(row)}", flush=True)
    return rows


def _figures(row) -> str:
    return (f"LED r {row['r']:.3f}  SSIM {row['ssim']:.3f}  point r {row['point_r']:.3f}  "
            f"SSIM {row['point_ssim']:.3f}  light on walls {row['share']:.1%}")


def _first(rows, r_min):
    """Budget (s) of the first row with min r >= r_min, or None."""
    return next((r["budget_s"] for r in rows if r["r"] >= r_min), None)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--image", default=str(ROOT / "examples" / "apple.png"))
    ap.add_argument("--budgets", type=float, nargs="+", default=[30, 60, 120, 180, 240, 300, 450, 600, 900])
    ap.add_argument("--profile", default="default", help="design profile (the scene and lampfab's schedule)")
    ap.add_argument("--ptracer-steps", type=int, default=0,
                    help="the ptracer method's schedule length (default: what fits the largest budget, from its "
                         "first step)")
    ap.add_argument("--record", action="store_true", help="append the table to today's file in bench/log/")
    args = ap.parse_args()
    budgets = sorted(args.budgets)

    with tempfile.TemporaryDirectory() as tmp:
        build = pipeline.Build.open(tmp, args.profile, "sla_resin")
        pipeline.prepare(build, args.image, {})
        inner = build.inner()
        targets = build.targets(VERIFY_PX)
        d = build.design
        grid = (d.optimize.grid_u, d.optimize.grid_v)

        # The source's method: plain cylinder, ptracer, its scale-independent MSE, cyclic
        # views, coarse-to-fine (half the schedule on the coarse grid, as the profile's
        # levels split it), every step kept.
        ptracer_opt = dataclasses.replace(d.optimize, method="ptracer", loss="si_mse", schedule="cyclic", spp=64,
                                          backtrack=False, preview_every=10**9, checkpoint_every=10**9)
        steps = args.ptracer_steps
        if not steps:
            probe = optimizer(build, inner, ptracer_opt)
            probe.gradient(np.zeros(grid), [0], seed=1)  # the first step compiles the kernels
            t0 = time.time()
            probe.gradient(np.zeros(grid), [0], seed=2)
            steps = max(2, int(budgets[-1] / (time.time() - t0)))
        ptracer_rows = run_method("ptracer", build, inner, targets, budgets, np.zeros(grid),
                                  dataclasses.replace(ptracer_opt, iterations=steps), 0.0)

        # lampfab's default: transport init, each of its fitting passes timed (measuring
        # happens afterwards, off the clock), then the profile's splat schedule.
        passes = []
        t0 = time.time()
        heights, init_figures = build.transport_design(d.optimize, inner, log=lambda m: None,
                                            on_pass=lambda h: passes.append((time.time() - t0, h.copy())))
        init_s = time.time() - t0
        splat_opt = dataclasses.replace(d.optimize, preview_every=10**9, checkpoint_every=10**9)
        probe = optimizer(build, inner, splat_opt)
        pass_rows = []
        for k, (at, h) in enumerate(passes):
            row = dict(measure(build, inner, probe, h, targets), method=f"transport pass {k + 1}",
                       budget_s=round(at, 1), spent_s=round(at, 1), steps=0)
            pass_rows.append(row)
            print(f"{'transport':9s} {at:6.1f} s  pass {k + 1}  {_figures(row)}", flush=True)
        init_row = dict(measure(build, inner, probe, heights, targets), method="transport only",
                        budget_s=round(init_s, 1), spent_s=round(init_s, 1), steps=0)
        print(f"{'transport':9s} {init_s:6.1f} s  {0:5d} steps  {_figures(init_row)}  (before any gradient step)",
              flush=True)
        splat_rows = run_method("lampfab", build, inner, targets, [b for b in budgets if b >= init_s], heights,
                                splat_opt, init_s, build.limits.with_slope(init_figures["slope_limit_deg"]))

        led = f"{build.led.name} ({build.led.shape}, {build.led.radius_mm:g} mm radius)"
    report(args, budgets, ptracer_rows, pass_rows + [init_row], splat_rows, steps, d.verify.photons, led)


def report(args, budgets, ptracer_rows, init_rows, splat_rows, ptracer_steps, photons, led) -> None:
    best_ptracer = max(r["r"] for r in ptracer_rows)
    ptracer_at = _first(ptracer_rows, best_ptracer)
    # ptracer got there after the budget before (a lower bound on its time) ...
    ptracer_low = max([b for b in budgets if b < ptracer_at], default=0.0)
    # ... lampfab at latest by the first pass or budget that shows it (an upper bound).
    lampfab_rows = init_rows + splat_rows
    lampfab_at = _first(lampfab_rows, best_ptracer)
    lampfab_goal = _first(lampfab_rows, GOAL_R)
    ptracer_goal = _first(ptracer_rows, GOAL_R)
    mi = mitsuba()
    lines = ["", f"## {time.strftime('%Y-%m-%d')}: {Path(args.image).name}, {platform.machine()} "
             f"{platform.processor() or 'CPU'}, {os.cpu_count()} cores, Mitsuba {mi.__version__} {mi.variant()}", "",
             f"ptracer: {ptracer_steps} steps planned (as many as fit the largest budget); lampfab: the {args.profile} "
             f"profile, its transport passes timed as they end, then its gradient steps at the budgets. "
             f"Each measured on the solid lens.stl would hold, {photons:,} stratified photons, {VERIFY_PX} px, "
             f"from the {led} LED and from the point light; the ratios compare the LED's figures.", "",
             "| method | at s | steps | min r | min SSIM | r per wall | SSIM per wall | point: min r / SSIM "
             "| light on walls |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in ptracer_rows + lampfab_rows:
        lines.append(f"| {r['method']} | {r['budget_s']} | {r['steps']} | {r['r']:.3f} | {r['ssim']:.3f} | "
                     f"{' / '.join(f'{x:.3f}' for x in r['r_walls'])} | "
                     f"{' / '.join(f'{x:.3f}' for x in r['ssim_walls'])} | {r['point_r']:.3f} / "
                     f"{r['point_ssim']:.3f} | {r['share']:.1%} |")
    lines.append("")
    lines.append(f"- ptracer's best min r within {budgets[-1]:.0f} s: {best_ptracer:.3f}, seen at the "
                 f"{ptracer_at:.0f} s budget (reached after more than {ptracer_low:.0f} s).")
    if lampfab_at:
        ratio = (f"{ptracer_low / lampfab_at:.1f}x sooner at least" if ptracer_low
                 else "sooner (no lower bound for ptracer)")
        lines.append(f"- lampfab reaches it within {lampfab_at:.0f} s: {ratio}.")
    else:
        lines.append("- lampfab does not reach it within the budgets.")

    def within(t):
        return f"within {t:.0f} s" if t else f"not within {budgets[-1]:.0f} s"

    lines.append(f"- time to min r >= {GOAL_R}: lampfab {within(lampfab_goal)}, ptracer {within(ptracer_goal)}"
                 + (f" (at least {budgets[-1] / lampfab_goal:.1f}x longer)" if lampfab_goal and not ptracer_goal else "")
                 + ".")
    text = "\n".join(lines)
    print(text)
    if args.record:
        from log_section import append

        print(f"recorded in {append(text)}")


if __name__ == "__main__":
    main()
