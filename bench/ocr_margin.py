#!/usr/bin/env python3
"""How surely a text lamp's words read: each wall's LED render traced again with other
photons, then blurred a little more, read back by ``lampfab.ocr`` (Tesseract).

    .venv/bin/python bench/ocr_margin.py build/text [build/words ...] [--seeds 4] [--record]

verify reads one render per wall; a word at the edge of legibility can read in one
render and not in the next.  Per build this counts the words read over the walls for
``--seeds`` renders of 16 M photons (verify's count), and with a Gaussian blur of
sigma 0.35 and 0.7 px added (a tenth and a fifth of the default LED's blur at 64 px):
a lens whose words survive the extra blur reads with a margin.  With ``--record`` the
table is appended to today's bench/log file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from lampfab import artifacts, ocr, verify  # noqa: E402

PHOTONS = 16_000_000
EXTRA_BLUR_PX = (0.0, 0.35, 0.7)


def row(build: Path, seeds: int) -> str:
    from scipy.ndimage import gaussian_filter

    loaded = verify.load(build / "design.json")
    phrase = _phrase(build)
    n = len(ocr.words(phrase)) * len(loaded.walls)
    read = {blur: [] for blur in EXTRA_BLUR_PX}
    for seed in range(seeds):
        images, _ = verify.render_design(loaded, 64, PHOTONS, 1000 + seed, 8)
        for blur in EXTRA_BLUR_PX:
            read[blur].append(sum(ocr.words_read(gaussian_filter(im, blur) if blur else im, phrase) for im in images))
    cells = [", ".join(f"{k}" for k in read[blur]) + f" of {n}" for blur in EXTRA_BLUR_PX]
    return f"| {build.name} | {phrase} | " + " | ".join(cells) + " |"


def _phrase(build: Path) -> str:
    settings = artifacts.read_json(build / "settings.json")
    if not settings.get("text"):
        sys.exit(f"{build}: not a text lamp (its settings.json has no text)")
    return settings["text"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="text lamps' build folders")
    parser.add_argument("--seeds", type=int, default=4, help="renders per build (default 4)")
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    rows = ["| build | phrase | " + " | ".join(f"words read, extra blur {b:g} px" for b in EXTRA_BLUR_PX) + " |",
            "|---|---|" + "---|" * len(EXTRA_BLUR_PX)]
    for build in args.builds:
        rows.append(row(build, args.seeds))
        print(rows[-1], flush=True)
    if args.record:
        import log_section

        log_section.record(f"## How surely the words read (bench/ocr_margin.py, {args.seeds} renders per build)\n\n"
                           + "\n".join(rows))


if __name__ == "__main__":
    main()
