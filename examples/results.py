#!/usr/bin/env python3
"""Regenerate every result picture and table of README.md, docs/ and bench/RESULTS.md
from the current code, in one run.

    .venv/bin/python examples/results.py             # every case: about 1.5 hours on 2 cores
    .venv/bin/python examples/results.py apple text  # only these cases
    .venv/bin/python examples/results.py --reports   # plan, export and verify again on every build there is

Each case is one fresh `make lamp` into build/results/<name> (its wall time measured
around make), then examples/figures.py's pictures, then the tables between the
`<!-- results:NAME -->` and `<!-- /results:NAME -->` markers of README.md,
docs/results.md, docs/fabrication.md and bench/RESULTS.md, rewritten from every case's
reports (a case not run this time keeps the figures its last build left, and one with
no build here the row the page has).  scikit-image's
samples are written to build/results/inputs.  The ``*_point_design`` cases design the
same lamps for the ideal point light (a copy of the default profile), for the
before-and-after picture examples/results/led_design.png and its table; the
``*_slotted`` cases make them with black-filled slots, for examples/results/slots.png and
its table.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import figures  # noqa: E402 - examples/figures.py, beside this script

ROOT = Path(__file__).resolve().parent.parent
BUILDS = ROOT / "build" / "results"
INPUTS = BUILDS / "inputs"


@dataclass(frozen=True)
class Case:
    name: str
    kind: str
    make: tuple[str, ...]       # make's variables
    sample: str = ""            # a scikit-image sample the case reads from INPUTS
    tables: tuple[str, ...] = ("summary", "full", "times", "reflections")  # the tables it is a row of
    variant_of: str = ""        # the default case this one changes one thing of (a before-and-after table's pair)
    edit: tuple[str, str, str] = ()  # (section, key, TOML value): the default profile with that one setting


# The default profile designing for the ideal point light, with slots, and a flat LED facing up where it
# serves best.
POINT_DESIGN = ("optimize", "design_light", '"point"')
SLOTTED = ("lens", "slot_width_mm", "1.0")
LOW_LIGHT = ("lens", "light_height_mm", "15.0")


CASES = (
    Case("apple", "silhouette (the bundled example)", ("TARGET=examples/apple.png",)),
    Case("star", "silhouette", ("TARGET=examples/star.png",)),
    Case("portrait", "continuous-tone picture", ("TARGET=examples/portrait.png",)),
    Case("astronaut", "photograph (scikit-image's, NASA)", ("TARGET=examples/astronaut.png",)),
    Case("horse", "silhouette with thin legs (scikit-image's)", ("TARGET=examples/horse.png",)),
    Case("camera", "photograph (scikit-image's cameraman)", (f"TARGET={INPUTS / 'camera.png'}",), "camera"),
    Case("rocket", "photograph (scikit-image's launch pad at dusk)", (f"TARGET={INPUTS / 'rocket.png'}",), "rocket"),
    Case("text", "four words: \"Sweet dreams little one\"", ("TEXT=Sweet dreams little one",)),
    Case("text_post1616", "the four words with 1.6 mm LEDs (LED=post1616), half the blur",
         ("TEXT=Sweet dreams little one", "LED=post1616")),
    Case("words", "four other words: \"Welcome home dear friend\"", ("TEXT=Welcome home dear friend",)),
    Case("panorama", "360° panorama", ("PANORAMA=examples/panorama.png",)),
    Case("apple_star3535", "the apple with one package facing up, 15 mm up the lens (LED=star3535)",
         ("TARGET=examples/apple.png", "LED=star3535"), edit=LOW_LIGHT),
    Case("apple_floor", "the apple on three walls and the floor, four LEDs on the post (PROFILE=floor)",
         ("TARGET=examples/apple.png", "PROFILE=floor"), tables=("full", "times")),
    Case("apple_hires", "the apple at 128 px with 1.6 mm LEDs (PROFILE=hires LED=post1616)",
         ("TARGET=examples/apple.png", "PROFILE=hires", "LED=post1616"), tables=("full", "times")),
    Case("apple_fine", "the apple refined four times as long (PROFILE=fine)",
         ("TARGET=examples/apple.png", "PROFILE=fine"), tables=("full", "times", "reflections")),
    Case("horse_fine", "the horse refined four times as long (PROFILE=fine)",
         ("TARGET=examples/horse.png", "PROFILE=fine"), tables=("full", "times", "reflections")),
    Case("panorama_fine", "the panorama refined four times as long (PROFILE=fine)",
         ("PANORAMA=examples/panorama.png", "PROFILE=fine"), tables=("full", "times", "reflections")),
    Case("panel", "the source's prior-work panel (PROFILE=panel)", ("PROFILE=panel",), tables=("full", "times")),
    Case("apple_cnc4", "the apple milled on 4 axes (FAB=acrylic_cnc4)", ("TARGET=examples/apple.png",
                                                                         "FAB=acrylic_cnc4"), tables=("milled", "times")),
    Case("apple_cnc3", "the apple milled on 3 axes (FAB=acrylic_cnc3)", ("TARGET=examples/apple.png",
                                                                         "FAB=acrylic_cnc3"), tables=("milled", "times")),
    # The same lamps designed for the ideal point light, as before the design knew the LED.
    Case("apple_point_design", "", ("TARGET=examples/apple.png",), tables=("led_design",), variant_of="apple",
         edit=POINT_DESIGN),
    Case("text_point_design", "", ("TEXT=Sweet dreams little one",), tables=("led_design",), variant_of="text",
         edit=POINT_DESIGN),
    Case("camera_point_design", "", (f"TARGET={INPUTS / 'camera.png'}",), "camera", tables=("led_design",),
         variant_of="camera", edit=POINT_DESIGN),
    # The same lamps with black-filled slots at the sectors' edges (slot_width_mm 1).
    *(Case(f"{name}_slotted", "", make, sample, tables=("slots",), variant_of=name, edit=SLOTTED)
      for name, make, sample in (("apple", ("TARGET=examples/apple.png",), ""),
                                 ("star", ("TARGET=examples/star.png",), ""),
                                 ("horse", ("TARGET=examples/horse.png",), ""),
                                 ("text", ("TEXT=Sweet dreams little one",), ""),
                                 ("camera", (f"TARGET={INPUTS / 'camera.png'}",), "camera"),
                                 ("portrait", ("TARGET=examples/portrait.png",), ""),
                                 ("words", ("TEXT=Welcome home dear friend",), ""),
                                 ("panorama", ("PANORAMA=examples/panorama.png",), ""))),
)

def _edited_profile(case: Case) -> Path:
    """A profile on the default's base with ``case.edit``'s one setting, written for the case."""
    section, key, value = case.edit
    INPUTS.mkdir(parents=True, exist_ok=True)
    path = INPUTS / f"{case.name}.toml"
    path.write_text(f'base = "default"\n\n[{section}]\n{key} = {value}\n')
    return path


# The stages that only measure or write out a design: run again after a change to them
# alone, they leave every build's heightmap as it is.
REPORT_STAGES = ("20_plan", "60_export", "70_verify")


def run(case: Case, reports: bool = False) -> float:
    """A fresh make lamp of ``case`` (or, ``reports``, its ``REPORT_STAGES`` again on the
    build there is); its wall time in seconds, kept for the tables only for a fresh one."""
    if case.sample:
        from skimage import data, io

        INPUTS.mkdir(parents=True, exist_ok=True)
        io.imsave(INPUTS / f"{case.sample}.png", getattr(data, case.sample)(), check_contrast=False)
    profile = (f"PROFILE={_edited_profile(case)}",) if case.edit else ()
    if reports:
        # The stages themselves, not make: make would redo the whole build when the
        # resolved profiles changed since it was made.
        given = dict(v.split("=", 1) for v in (*case.make, *profile))
        options = [f"--{key.lower()}={given[key]}" for key in ("PROFILE", "FAB", "LED") if key in given]
        commands = [[sys.executable, f"stages/{stage}.py", "--out", str(BUILDS / case.name), *options]
                    for stage in REPORT_STAGES]
    else:
        shutil.rmtree(BUILDS / case.name, ignore_errors=True)
        commands = [["make", "--no-print-directory", "lamp", f"BUILD={BUILDS}", f"NAME={case.name}", *case.make,
                     *profile]]
    t0 = time.monotonic()
    for command in commands:
        done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True)
        if done.returncode:
            sys.exit(f"{command[1]} for {case.name} failed:\n{done.stdout[-3000:]}{done.stderr[-3000:]}")
    seconds = time.monotonic() - t0
    if not reports:
        (BUILDS / case.name / "make_seconds.txt").write_text(f"{seconds:.1f}\n")
    return seconds


def _reports(name: str) -> dict:
    folder = BUILDS / name
    out = {}
    for stage, file in (("plan", "plan"), ("fabcheck", "checks"), ("verify", "verify"), ("export", "export")):
        path = folder / f"{file}.json"
        if path.exists():
            out[stage] = json.loads(path.read_text())
    names = {"fabcheck": "checks"}
    out["stage_times"] = {stage: json.loads((folder / f"{names.get(stage, stage)}.json").read_text())["wall_time_s"]
                          for stage in STAGES if (folder / f"{names.get(stage, stage)}.json").exists()}
    out["stage_seconds"] = sum(out["stage_times"].values())
    made = folder / "make_seconds.txt"
    out["make_seconds"] = float(made.read_text()) if made.exists() else None
    return out


def _span(values, digits=3) -> str:
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return lo if lo == hi else f"{lo}-{hi}"


STAGES = ("prepare", "plan", "init", "optimize", "solid", "fabcheck", "export", "verify")


def _row(case: Case, table: str) -> str | None:
    r = _reports(case.name)
    if "verify" not in r:
        return None
    if table == "times":
        seconds = [r["stage_times"].get(stage) for stage in STAGES]
        return (f"| {case.name} | " + " | ".join("—" if t is None else f"{t:.1f}" for t in seconds)
                + f" | {r['stage_seconds']:.0f} | {(r['make_seconds'] or 0) / 60:.1f} min |")
    walls = list(r["verify"]["figures"]["walls"].values())
    if table == "led_design":
        return _before_after_row(case, walls)
    if table == "slots":
        return _slots_row(case, walls, r["make_seconds"])
    if table == "reflections":
        if not all("led_ssim_ceiling" in w for w in walls):
            return None
        return (f"| {case.name} | {_span([w['led_ssim'] for w in walls], 2)} | "
                f"{_span([w['led_ssim_ceiling'] for w in walls], 2)} | "
                f"{_span([w['led_ssim'] / w['led_ssim_ceiling'] for w in walls], 2)} | "
                f"{_span([w['led_reference_ssim'] for w in walls], 2)} | "
                f"{_span([max(w.get('led_ssim_photon_noise', 0.0), 0.0) for w in walls], 3)} | "  # a few 1e-4 under 0: no noise
                f"{_span([100 * w['ghost_share'] for w in walls], 1)} % |")
    failed = [c["name"] for c in r["fabcheck"]["figures"]["checks"] if c["applies"] and not c["passed"]]
    checks = "pass" if not failed else "fails " + ", ".join(failed)
    minutes = f"{(r['make_seconds'] or r['stage_seconds']) / 60:.1f} min"
    led = f"{_span([w['led_pearson'] for w in walls])} / {_span([w['led_ssim'] for w in walls], 2)}"
    point = f"{_span([w['pearson'] for w in walls])} / {_span([w['ssim'] for w in walls], 2)}"
    blur = [w["led_blur_mm"] for w in walls if "led_blur_mm" in w]
    blur_text = (f"{_span([b['horizontal'] for b in blur], 0)} x {_span([b['vertical'] for b in blur], 0)} mm"
                 if blur else "—")
    mitsuba = [w["mitsuba_pearson"] for w in walls if "mitsuba_pearson" in w]
    read = [f"{w['led_words_read']}/{w['words']}" for w in walls if "words" in w]
    kind = case.kind + (f"; OCR reads {', '.join(read)} words with the LED" if read else "")
    if table in ("summary", "milled"):
        return f"| {case.name} | {kind} | {led} | {point} | {blur_text} | {checks} | {minutes} |"
    ceiling = [w["led_ssim_ceiling"] for w in walls if "led_ssim_ceiling" in w]
    reference = [w["led_reference_ssim"] for w in walls if "led_reference_ssim" in w]
    share = sum(w["led_share"] for w in walls)
    dark = [w["led_contrast_ratio"] for w in walls if w.get("led_contrast_ratio")]
    return (f"| {case.name} | {led} | {point} | {_span(reference, 2) if reference else '—'} | "
            f"{_span(ceiling, 2) if ceiling else '—'} | {blur_text} | {_span(mitsuba) if mitsuba else '—'} | "
            f"{share:.0%} | {_span(dark, 0) + ':1' if dark else '—'} | {checks} | "
            f"{r['stage_seconds']:.0f} s / {minutes} |")


def _walls_of(name: str) -> list[dict] | None:
    r = _reports(name)
    return list(r["verify"]["figures"]["walls"].values()) if "verify" in r else None


def _figures(walls: list[dict], prefix: str) -> str:
    return f"{_span([w[prefix + 'pearson'] for w in walls])} / {_span([w[prefix + 'ssim'] for w in walls], 2)}"


def _read(walls: list[dict]) -> str:
    return ", ".join(f"{w['led_words_read']}/{w['words']}" for w in walls if "words" in w) or "—"


def _before_after_row(case: Case, before: list[dict]) -> str | None:
    """A row of the led_design table: ``case`` (the point-light design) against the
    LED-aware design it is the "before" of."""
    after = _walls_of(case.variant_of)
    if after is None:
        return None
    return (f"| {case.variant_of} | {_figures(before, 'led_')} | {_figures(after, 'led_')} | {_read(before)} | "
            f"{_read(after)} | {_figures(before, '')} | {_figures(after, '')} |")


def _slots_row(case: Case, after: list[dict], make_seconds: float | None) -> str | None:
    """A row of the slots table: the default case ``case`` is a variant of, then ``case``
    (the same image with black-filled slots, made in ``make_seconds``), each with the LED."""
    before = _walls_of(case.variant_of)
    if before is None:
        return None

    def each(walls, key, digits=3):
        return " / ".join(f"{w[key]:.{digits}f}" for w in walls)

    empty = each(after, 'led_ssim_slots_empty') if all("led_ssim_slots_empty" in w for w in after) else "—"
    return (f"| {case.variant_of} | {each(before, 'led_ssim')} | {each(after, 'led_ssim')} | {empty} | "
            f"{each(after, 'led_reference_ssim')} | {_span([w['led_pearson'] for w in before])} → "
            f"{_span([w['led_pearson'] for w in after])} | {_span([100 * w['ghost_share'] for w in before], 1)} → "
            f"{_span([100 * w['ghost_share'] for w in after], 1)} % | {sum(w['led_share'] for w in before):.0%} → "
            f"{sum(w['led_share'] for w in after):.0%} | {_read(before)} → {_read(after)} | "
            f"{(make_seconds or 0) / 60:.1f} min |")


_SHORT = ("| {first} | what it is | with the LED: r / SSIM | ideal point light: r / SSIM | LED blur (across x up) "
          "| checks | `make lamp` |\n|---|---|---|---|---|---|---|")
TABLES = {
    "summary": _SHORT.format(first="image"),
    "milled": _SHORT.format(first="case"),
    "times": ("| case | " + " | ".join(STAGES) + " | by stage (s) | `make lamp` |\n|" + "---|" * (len(STAGES) + 3)),
    "full": ("| case | with the LED: r / SSIM | point light: r / SSIM | SSIM of the target blurred by the LED "
             "| ... with the lens's reflections | LED blur | Mitsuba vs verify (r) | light on the walls "
             "| contrast on black (LED) | checks | by stage / `make lamp` |\n|---|---|---|---|---|---|---|---|---|---|---|"),
    "reflections": ("| case | SSIM with the LED | a perfect outer surface, with this lens's reflections and verify's "
                    "photon noise | the first over the second | a perfect point-light design, no reflections, no noise "
                    "| SSIM that verify's photon noise takes off | light reflected inside the lens |\n"
                    "|---|---|---|---|---|---|---|"),
    "led_design": ("| image | with the LED, lens designed for a point: r / SSIM | ... designed for the LED | OCR with the LED, "
                   "designed for a point | ... for the LED | ideal point light, designed for a point | ... for the LED |\n"
                   "|---|---|---|---|---|---|---|"),
    "slots": ("| image | SSIM with the LED, front / left / right: no slots | with slots | ... the slots left empty "
              "| the target blurred by the LED (with slots) | r with the LED | light reflected inside the lens | light "
              "on the walls | OCR with the LED | `make lamp` with slots |\n|---|---|---|---|---|---|---|---|---|---|"),
}


PAGES = (ROOT / "README.md", ROOT / "docs" / "results.md", ROOT / "docs" / "fabrication.md", ROOT / "bench" / "RESULTS.md")


def write_tables(paths=PAGES) -> None:
    """Rewrite every ``<!-- results:NAME -->`` block of ``paths`` from the builds."""
    for path in paths:
        text = path.read_text()
        for name, head in TABLES.items():
            on_page = re.search(rf"<!-- results:{name} -->\n(.*?)<!-- /results:{name} -->", text, flags=re.S)
            kept = {line.split("|")[1].strip(): line for line in (on_page.group(1) if on_page else "").splitlines()
                    if line.startswith("| ")}
            rows = [row for row in (_row(c, name) or kept.get(c.variant_of or c.name)
                                    for c in CASES if name in c.tables) if row]
            block = "\n".join([head, *rows])
            text = re.sub(rf"(<!-- results:{name} -->\n).*?(<!-- /results:{name} -->)",
                          lambda m: m.group(1) + block + "\n" + m.group(2), text, flags=re.S)
        path.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help=f"cases to run (default: all of {', '.join(c.name for c in CASES)})")
    parser.add_argument("--tables-only", action="store_true", help="rewrite the tables from the builds there are")
    parser.add_argument("--reports", action="store_true",
                        help="run only plan, export and verify again on the builds there are (after a change to "
                             "those stages alone: the designs stay the same); the tables keep each build's make time")
    args = parser.parse_args()
    unknown = set(args.names) - {c.name for c in CASES}
    if unknown:
        parser.error(f"unknown case {sorted(unknown)[0]}; choose from {', '.join(c.name for c in CASES)}")
    if not args.tables_only:
        for case in CASES:
            if args.names and case.name not in args.names:
                continue
            seconds = run(case, args.reports)
            # A variant is pictured only beside its default case, below.
            made = "" if case.variant_of else f" -> {figures.figure(case.name, BUILDS)}"
            stages = "plan, export and verify" if args.reports else "make lamp"
            print(f"{case.name}: {stages} {seconds / 60:.1f} min{made}",
                  flush=True)
    for table, labels in (("led_design", ("point design", "LED design")), ("slots", ("no slots", "slots"))):
        # Each picture's rows: (before, after) builds.
        pairs = [(c.name, c.variant_of) if table == "led_design" else (c.variant_of, c.name)
                 for c in CASES if table in c.tables]
        if all((BUILDS / n / "verify.json").exists() for pair in pairs for n in pair):
            print(f"before and after: {figures.before_after(pairs, BUILDS, labels=labels, name=table)}")
        else:
            print(f"before and after: examples/results/{table}.png kept (it needs every case of its table "
                  "and its default case built here)")
    write_tables()


if __name__ == "__main__":
    main()
