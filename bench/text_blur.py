#!/usr/bin/env python3
"""What blur text survives: 16 phrases' text targets at 64 px blurred by Gaussians whose
4 sigma is a fraction f of the font's size (its em), read back by ``lampfab.ocr``
(Tesseract: as a block and line by line; the block alone for comparison).

    .venv/bin/python bench/text_blur.py [--record]

The answer sets ``pipeline.budget.TEXT_BLUR_EM``, the blur beyond which plan warns that
words will not read.  With ``--record`` the table is appended to today's bench/log file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from lampfab import ocr, targets  # noqa: E402

# Four- and five-word phrases (and one of three), the kind a lamp shows; none tuned on.
PHRASES = ("Sweet dreams little one", "Dream big little star", "Welcome home dear friend", "Good night sweet pea",
           "Happy birthday my love", "You are my sunshine", "Home is where love is", "Follow your own star",
           "Stay wild moon child", "Love you to the moon", "Make today a good day", "Let the light in",
           "All you need is love", "Shine bright like diamonds", "Hello little dreamer", "Keep calm and carry on")
# Read in every picture instead of its own phrase: words no phrase above has, laid out
# in four lines as they are; any of its words read is a false reading.
WRONG = "Quick brown fox jumps"
FRACTIONS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
SHAPE = (48, 64)  # a 4:3 wall at the default profile's 64 px


def table() -> str:
    from collections import Counter

    from scipy.ndimage import gaussian_filter

    n = sum(len(ocr.words(p)) for p in PHRASES)
    rows = [f"| blur (4 sigma, in em) | words read ({n}) | phrases read whole ({len(PHRASES)}) "
            f"| words read as one block only | words of a wrong phrase read |", "|---|---|---|---|---|"]
    for f in FRACTIONS:
        read = whole = block = wrong = 0
        for phrase in PHRASES:
            picture = targets.text_image(phrase, *SHAPE)
            em = targets.text_layout(phrase, *SHAPE)[0]
            blurred = gaussian_filter(picture, f * em / 4) if f else picture
            k = ocr.words_read(blurred, phrase)
            read, whole = read + k, whole + (k == len(ocr.words(phrase)))
            block += sum((Counter(ocr.words(phrase)) & Counter(ocr.read(blurred))).values())
            wrong += ocr.words_read(blurred, WRONG)
        rows.append(f"| {f:g} | {read} | {whole} | {block} | {wrong} |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    text = table()
    if args.record:
        import log_section

        log_section.record("## What blur text survives (bench/text_blur.py)\n\n" + text)


if __name__ == "__main__":
    main()
