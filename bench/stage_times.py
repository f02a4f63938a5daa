#!/usr/bin/env python3
"""Stage wall times of two revisions of lampfab, on one image, in one run.

    .venv/bin/python bench/stage_times.py --base 5dd632b                # init, optimize; 3 rounds
    .venv/bin/python bench/stage_times.py --base v1 --head v2 --stages init optimize verify --rounds 5

Each revision is checked out in a temporary git worktree (the working tree itself for
``--head`` unset) and runs with this checkout's virtual environment, its own ``stages/``
and its own ``lampfab`` first on PYTHONPATH.  After the prepare stage (and the stages
between it and the first timed one) each timed stage runs ``--rounds`` times,
alternating base and head, so both see the same machine; a stage's time is the
``wall_time_s`` of its report.  Prints the medians and head/base ratios; --record
appends them to today's file in bench/log/ with the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
PIPELINE = ("prepare", "plan", "init", "optimize", "solid", "fabcheck", "export", "verify")
# The fabrication check writes checks.json; revisions before it was named fabcheck call
# its script 50_check.py.
REPORTS = {"fabcheck": "checks"}
OLD_SCRIPTS = {"fabcheck": "check"}


def _script(tree: Path, stage: str) -> Path:
    found = sorted((tree / "stages").glob(f"*_{stage}.py")) or \
        sorted((tree / "stages").glob(f"*_{OLD_SCRIPTS.get(stage, stage)}.py"))
    if len(found) != 1:
        sys.exit(f"stage_times: {tree}/stages has no single script for the stage {stage!r}")
    return found[0]


def _run(tree: Path, args: list[str]) -> None:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    done = subprocess.run(args, cwd=tree, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode:
        sys.exit(f"stage_times: {' '.join(args)} failed in {tree}:\n{done.stderr[-2000:]}")


def _stage(tree: Path, build: Path, stage: str, profile: str, fab: str, *extra: str) -> float:
    _run(tree, [str(ROOT / ".venv/bin/python"), str(_script(tree, stage)), "--out", str(build),
                "--profile", profile, "--fab", fab, *extra])
    return float(json.loads((build / f"{REPORTS.get(stage, stage)}.json").read_text())["wall_time_s"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="git revision to compare against")
    ap.add_argument("--head", default=None, help="git revision (default: the working tree)")
    ap.add_argument("--image", default="examples/apple.png")
    ap.add_argument("--profile", default="default")
    ap.add_argument("--fab", default="sla_resin")
    ap.add_argument("--stages", nargs="+", default=["init", "optimize"], choices=PIPELINE[1:])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--record", action="store_true", help="append the table to today's file in bench/log/")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="lampfab-stage-times-") as tmp:
        tmp = Path(tmp)
        trees = {}
        for label, rev in (("base", args.base), ("head", args.head)):
            if rev is None:
                trees[label] = ROOT
                continue
            trees[label] = tmp / label
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(trees[label]), rev],
                           check=True)
        try:
            builds = {label: tmp / f"build-{label}" for label in trees}
            image = str(Path(args.image).resolve())
            first = min(PIPELINE.index(s) for s in args.stages)
            for label, tree in trees.items():
                # Not through make: its setup rule would reinstall the environment from the worktree.
                _stage(tree, builds[label], "prepare", args.profile, args.fab, "--target", image)
                for stage in PIPELINE[1:first]:
                    _stage(tree, builds[label], stage, args.profile, args.fab)
            times = {label: {s: [] for s in args.stages} for label in trees}
            for k in range(args.rounds):
                for stage in args.stages:
                    for label, tree in trees.items():
                        seconds = _stage(tree, builds[label], stage, args.profile, args.fab)
                        times[label][stage].append(seconds)
                        print(f"round {k + 1}: {label} {stage} {seconds:.1f} s", flush=True)
        finally:
            for label, tree in trees.items():
                if tree != ROOT:
                    subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)

    head_name = args.head or "working tree"
    lines = [f"| stage | base {args.base} (s) | head {head_name} (s) | head / base |", "|---|---|---|---|"]
    for stage in args.stages:
        b, h = np.median(times["base"][stage]), np.median(times["head"][stage])
        lines.append(f"| {stage} | {b:.1f} | {h:.1f} | {h / b:.2f} |")
        times_text = ", ".join(f"{x:.1f}" for x in times["base"][stage]) + " / " + \
            ", ".join(f"{x:.1f}" for x in times["head"][stage])
        print(f"{stage}: base {b:.1f} s, head {h:.1f} s, ratio {h / b:.2f}  ({times_text})")
    table = "\n".join(lines)
    print(table)
    if args.record:
        from log_section import append

        header = (f"## Stage times: {args.base} against {head_name} ({Path(args.image).name}, profile "
                  f"{args.profile}, {args.fab}; {platform.machine()}, {os.cpu_count()} cores; median of "
                  f"{args.rounds} alternating rounds)\n\n")
        print(f"recorded in {append(header + table)}")


if __name__ == "__main__":
    main()
