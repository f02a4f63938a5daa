#!/usr/bin/env python3
"""What blur text survives: the text targets blurred by Gaussians whose 4 sigma is a
fraction f of the font's size (its em), read back by ``lampfab.ocr`` (Tesseract).

    .venv/bin/python bench/text_blur.py [--record]

The answer sets ``pipeline.budget.TEXT_BLUR_EM``, the blur beyond which plan warns that
words will not read.  With ``--record`` the table is appended to today's bench/log file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from lampfab import ocr, targets  # noqa: E402

PHRASES = ("Happy birthday", "Sweet dreams little one", "The quick brown fox jumps over the lazy dog")
FRACTIONS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
SHAPE = (48, 64)  # a 4:3 wall at the default profile's 64 px


def table() -> str:
    from scipy.ndimage import gaussian_filter

    rows = [f"| text | em at {SHAPE[1]} px | " + " | ".join(f"f = {f:g}" for f in FRACTIONS) + " |",
            "|---|---|" + "---|" * len(FRACTIONS)]
    for phrase in PHRASES:
        picture = targets.text_image(phrase, *SHAPE)
        em = targets.text_layout(phrase, *SHAPE)[0]
        n = len(ocr.words(phrase))
        read = [ocr.words_read(gaussian_filter(picture, f * em / 4) if f else picture, phrase) for f in FRACTIONS]
        rows.append(f"| {phrase} | {em:.1f} px | " + " | ".join(f"{k}/{n}" for k in read) + " |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    text = table()
    if args.record:
        import log_section

        print("recorded in", log_section.append("## What blur text survives (bench/text_blur.py)\n\n" + text))


if __name__ == "__main__":
    main()
