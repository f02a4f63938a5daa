#!/usr/bin/env python3
"""How long the slope projection takes in a refinement, and with which solver.

    .venv/bin/python bench/slope_projection.py build/horse [--record]

Runs the optimize stage of a build that has its first design (``make init``), in a copy
of the build folder, keeping the surface each step hands ``limits.limit_slopes``.  Then
projects those surfaces again, as the stage did, twice: with the least-squares solve by
Fourier and cosine transforms (the projection's own) and with a sparse LU of the same
normal equations (the baseline, in the same run).  Prints the stage's time, the passes
per call, the projection's seconds per call (median, largest, sum) under each solver,
how far it moved the surface (RMS over the nodes) and how far the two solvers' results
differ.

The horse presses much of its surface against the 60° limit by the fine level's end;
its creased seams are where the spline's end condition bends past the limit.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from lampfab import limits, pipeline  # noqa: E402


class _Counted:
    """A solver that counts its solves: one a pass."""

    def __init__(self, solver):
        self.solver, self.solves = solver, 0

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        self.solves += 1
        return self.solver.solve(rhs)


class _SparseLU:
    def __init__(self, diff):
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        self.lu = splu((diff.T @ diff + sp.identity(diff.shape[1]) * 1e-9).tocsc())

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self.lu.solve(rhs)


def record(build: Path) -> tuple[list[tuple], float]:
    """The optimize stage's ``limit_slopes`` calls (their arguments) and its seconds."""
    settings = json.loads((build / "settings.json").read_text())
    calls = []
    project = limits.limit_slopes

    def keep(*args, **kwargs):
        calls.append((args, kwargs))
        return project(*args, **kwargs)

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / build.name
        shutil.copytree(build, copy)
        opened = pipeline.Build.open(copy, settings["design"]["name"], settings["fabrication"]["name"],
                                     settings["led"]["name"])
        limits.limit_slopes = keep
        try:
            t0 = time.perf_counter()
            pipeline.optimize(opened)
            seconds = time.perf_counter() - t0
        finally:
            limits.limit_slopes = project
    return calls, seconds


def replay(calls: list[tuple], solver_of) -> tuple[list[int], list[float], list[np.ndarray]]:
    """Passes, seconds and result of each call, with ``_edge_system``'s solver replaced
    by ``solver_of(diff, solver)``."""
    edge_system = limits._edge_system
    passes, seconds, results = [], [], []
    for args, kwargs in calls:
        a, b, diff, solver = edge_system(*args[1].shape)
        counted = _Counted(solver_of(diff, solver))
        limits._edge_system = lambda nu, nv: (a, b, diff, counted)
        try:
            t0 = time.perf_counter()
            heights, _ = limits.limit_slopes(*args, **kwargs)
            seconds.append(time.perf_counter() - t0)
        finally:
            limits._edge_system = edge_system
        passes.append(counted.solves)
        results.append(heights)
    return passes, seconds, results


def report(build: Path) -> str:
    calls, stage_s = record(build)
    own = replay(calls, lambda diff, solver: solver)
    lu = replay(calls, lambda diff, solver: _SparseLU(diff))
    moved = [float(np.sqrt(np.mean((out - args[1]) ** 2))) for out, (args, _) in zip(own[2], calls)]
    apart = max(float(np.abs(x - y).max()) for x, y in zip(own[2], lu[2]))
    passes = np.array(own[0])
    lines = [f"`{build.name}`: optimize stage {stage_s:.1f} s, {len(calls)} projections, "
             f"passes per call median {np.median(passes):g}, largest {passes.max()}, sum {passes.sum()}; "
             f"surface moved {1e3 * np.median(moved):.2f} µm RMS (median call)", "",
             "| solver | s per call, median | largest | sum |", "|---|---|---|---|"]
    for name, (_, seconds, _) in (("Fourier + cosine transforms", own), ("sparse LU (baseline)", lu)):
        lines.append(f"| {name} | {np.median(seconds):.3f} | {max(seconds):.3f} | {sum(seconds):.1f} |")
    lines += ["", f"sum, LU over transforms: {sum(lu[1]) / sum(own[1]):.2f}x; "
              f"results apart by {apart * 1e3:.2g} µm at most (passes alike: {own[0] == lu[0]})"]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("build", type=Path, help="a build folder with its first design (make init)")
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    text = report(args.build)
    print(text, flush=True)
    if args.record:
        import log_section

        log_section.record("## The slope projection in a refinement (bench/slope_projection.py)\n\n" + text)


if __name__ == "__main__":
    main()
