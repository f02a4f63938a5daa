"""``lampfab``: the stages as commands, for people who don't use Make.

    lampfab lamp IMAGE              every stage, into build/<image stem>/
    lampfab <stage> --out DIR ...   one stage (prepare, plan, init, optimize, solid,
                                    fabcheck, export, verify)
    lampfab profiles                the design and fabrication profiles

User errors print one line and exit 2; a failed fabrication check exits 3.
Heavy libraries load inside the stages, so ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

STAGE_HELP = {
    "prepare": "read the image(s) and write one linear target per wall (targets/)",
    "plan": "render the plain lens in the room: where its light falls (plan.json, plan/)",
    "init": "transport-based first lens: each photon's goal by optimal transport, then the surface "
            "that lands it there (init.npz)",
    "optimize": "refine by differentiable photon splatting (Mitsuba + Dr.Jit), or the source's ptracer "
                "method with [optimize] method = \"ptracer\" (heightmap.npz)",
    "solid": "merge outer shell, inner layer and LED bore into one solid (solid.npz)",
    "fabcheck": "manufacturability against the fabrication profile (checks.json, checks.png)",
    "export": "lens.stl, lens.step, lens.glb and design.json, each read back and checked",
    "verify": "render the exported STL with its true facets; report.html",
}
WALLS = ("front", "left", "right", "floor")


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, help="build folder, e.g. build/apple")
    p.add_argument("--profile", default="default", help="design profile name or .toml path (default: default)")
    p.add_argument("--fab", default="sla_resin", help="fabrication profile name or .toml path (default: sla_resin)")
    _led(p)


def _led(p: argparse.ArgumentParser) -> None:
    # The literal, not profile.DEFAULT_LED: --help must not import the profiles' module.
    p.add_argument("--led", default="post3535", help="LED profile name or .toml path (default: post3535)")


def _targets(p: argparse.ArgumentParser, with_image: bool = True) -> None:
    if with_image:
        # dest "image", as lamp's positional argument: the stages read one name for it
        p.add_argument("--target", dest="image", default="", help="image projected on every wall (PNG or JPEG)")
    for wall in WALLS:
        p.add_argument(f"--target-{wall}", default="", help=f"image for the {wall} only")
    p.add_argument("--text", default="", type=_line_breaks,
                   help='words to project instead of an image, e.g. "Happy birthday" ("\\n" breaks a line: '
                        '"Sleep well\\nmy darling")')
    p.add_argument("--panorama", default="", help="a 360° panorama (PNG or JPEG) wrapped around the room")


def _line_breaks(text: str) -> str:
    """``text`` with each two-character "\\n" made a line break: Make cannot pass a real
    one from ``TEXT=`` into its recipes' shell."""
    return text.replace("\\n", "\n")


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(prog="lampfab", description="Design a caustic projection lamp from an image.")
    sub = top.add_subparsers(dest="command", required=True)
    lamp = sub.add_parser("lamp", help="run every stage for one image")
    lamp.add_argument("image", nargs="?", default="", help="the target image (PNG or JPEG)")
    lamp.add_argument("--out", default="", help="build folder (default: build/<image stem>, build/text, "
                                                "build/<panorama stem>)")
    lamp.add_argument("--profile", default="default")
    lamp.add_argument("--fab", default="sla_resin")
    _led(lamp)
    lamp.add_argument("--allow-fail", action="store_true", help="go on after a failed fabrication check")
    _targets(lamp, with_image=False)
    for name, text in STAGE_HELP.items():
        p = sub.add_parser(name, help=text, description=text)
        _common(p)
        if name == "prepare":
            _targets(p)
        if name == "fabcheck":
            p.add_argument("--allow-fail", action="store_true", help="write checks.json even if a check fails")
    snap = sub.add_parser("settings", help="write resolved profiles and input hashes to OUT/settings.json "
                                           "if they changed (Make's prerequisite for every stage)")
    _common(snap)
    _targets(snap)
    summary = sub.add_parser("summary", help="one line per stage: its time and key figure")
    _common(summary)
    sub.add_parser("profiles", help="list the design and fabrication profiles")
    return top


def _per_wall(args: argparse.Namespace) -> dict[str, str]:
    return {w: getattr(args, f"target_{w}") for w in WALLS if getattr(args, f"target_{w}")}


def _images(args: argparse.Namespace) -> dict[str, str]:
    """Every input image by role, as ``pipeline.snapshot`` records them."""
    return {**_per_wall(args), "all": args.image, "panorama": args.panorama}


def run_stage(name: str, args: argparse.Namespace) -> None:
    from . import pipeline

    build = pipeline.Build.open(args.out, args.profile, args.fab, args.led)
    if name == "settings":
        pipeline.snapshot(build, _images(args), args.text)
    elif name == "summary":
        pipeline.summary(build)
    else:
        _pipeline_stage(build, name, args)


def _pipeline_stage(build, name: str, args: argparse.Namespace) -> None:
    """One of ``pipeline.STAGES`` on ``build`` (prepare reads ``args.image`` and the
    other images, fabcheck ``args.allow_fail``)."""
    from . import pipeline

    if name == "prepare":
        pipeline.prepare(build, args.image, _per_wall(args), args.text, args.panorama)
    elif name == "fabcheck":
        pipeline.fabcheck(build, args.allow_fail)
    else:
        getattr(pipeline, name)(build)


def _profiles() -> None:
    from .profile import PROFILE_DIR

    for folder, label in ((PROFILE_DIR, "design"), (PROFILE_DIR / "fab", "fabrication"), (PROFILE_DIR / "led", "LED")):
        for p in sorted(folder.glob("*.toml")):
            first = next((ln.lstrip("# ").strip() for ln in p.read_text().splitlines() if ln.startswith("#")), "")
            print(f"{label:12s} {p.stem:14s} {first}")


def _lamp(args: argparse.Namespace) -> None:
    from . import pipeline
    from .errors import LampfabError

    if not (args.image or args.text or args.panorama):
        raise LampfabError('nothing to project: give an image (lampfab lamp photo.png), --text "..." '
                           "or --panorama pano.png")
    stem = "text" if args.text else Path(args.panorama or args.image).stem
    out = Path(args.out or Path("build") / stem)
    build = pipeline.Build.open(out, args.profile, args.fab, args.led)
    # Reads every input first: a bad one stops here, before any stage writes a file.
    pipeline.snapshot(build, _images(args), args.text)
    for name in pipeline.STAGES:
        t0 = time.time()
        _pipeline_stage(build, name, args)
        print(f"== {name} done in {time.time() - t0:.1f} s", flush=True)


def main(argv: list[str] | None = None, stage: str | None = None) -> int:
    from .errors import CheckFailed, LampfabError

    argv = list(sys.argv[1:] if argv is None else argv)
    if stage is not None:
        argv = [stage, *argv]
    args = parser().parse_args(argv)
    try:
        if args.command == "profiles":
            _profiles()
        elif args.command == "lamp":
            _lamp(args)
        else:
            run_stage(args.command, args)
    except CheckFailed as exc:
        print(f"lampfab: {exc}", file=sys.stderr)
        return 3
    except LampfabError as exc:
        print(f"lampfab: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("lampfab: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader stopped early (`lampfab profiles | head`): say nothing more, and keep
        # Python's flush at exit from failing on the closed pipe again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    return 0


if __name__ == "__main__":
    sys.exit(main())
