#!/usr/bin/env python3
"""What blur text survives: the text targets blurred by Gaussians whose 4 sigma is a
fraction f of the font's size (its em), read back by ``lampfab.ocr`` (Tesseract).

    .venv/bin/python bench/text_blur.py [--spacing] [--record]

The answer sets ``pipeline.budget.TEXT_BLUR_EM``, the blur beyond which plan warns that
words will not read.  ``--spacing`` instead sets four-word phrases with other gaps
between their lines and blurs them by the default LED's measured blur, and 1.25-2 times
it, with photon noise: the answer sets ``targets.LINE_SPACING_EM``.  With ``--record``
the table is appended to today's bench/log file.
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

# --spacing: four-word phrases (the first two are the text and words cases of
# examples/results.py), line gaps in em, and blurs as multiples of the default LED's
# on the four-word lamps: 61 x 86 mm (4 sigma, across x up; docs/results.md) on the
# 1800 mm wide wall's 64 px.
SPACING_PHRASES = ("Sweet dreams little one", "Welcome home dear friend", "Good night my darling",
                   "Happy birthday to you", "You are my sunshine", "Home is where the heart is")
SPACINGS_EM = (0.1, 0.2, 0.25, 0.3, 0.35, 0.4)
LED_SIGMA_PX = (86 / 4 / (1800 / 64), 61 / 4 / (1800 / 64))  # (up, across)
BLUR_FACTORS = (1.0, 1.25, 1.5, 1.75, 2.0)
# Photons per unit of a letter's light, and independent draws of them per picture.
NOISE_PHOTONS, NOISE_DRAWS = 400.0, 2


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


def spacing_table() -> str:
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(1)
    rows = ["| gap between lines | em at 64 px | " + " | ".join(f"{f:g} x the LED's blur" for f in BLUR_FACTORS) + " |",
            "|---|---|" + "---|" * len(BLUR_FACTORS)]
    for spacing in SPACINGS_EM:
        read, total, ems = np.zeros(len(BLUR_FACTORS), int), 0, []
        for phrase in SPACING_PHRASES:
            picture = targets.text_image(phrase, *SHAPE, line_spacing_em=spacing)
            ems.append(targets.text_layout(phrase, *SHAPE, line_spacing_em=spacing)[0])
            total += NOISE_DRAWS * len(ocr.words(phrase))
            for i, f in enumerate(BLUR_FACTORS):
                blurred = gaussian_filter(picture, (LED_SIGMA_PX[0] * f, LED_SIGMA_PX[1] * f))
                for _ in range(NOISE_DRAWS):
                    read[i] += ocr.words_read(rng.poisson(blurred * NOISE_PHOTONS) / NOISE_PHOTONS, phrase)
        rows.append(f"| {spacing:g} em | {min(ems):.1f}-{max(ems):.1f} px | " + " | ".join(f"{k}/{total}" for k in read) + " |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spacing", action="store_true", help="the gap between lines instead (sets LINE_SPACING_EM)")
    parser.add_argument("--record", action="store_true", help="append the table to today's bench/log file")
    args = parser.parse_args()
    if args.spacing:
        title, text = "The gap between a text's lines (bench/text_blur.py --spacing)", spacing_table()
    else:
        title, text = "What blur text survives (bench/text_blur.py)", table()
    if args.record:
        import log_section

        print("recorded in", log_section.append(f"## {title}\n\n" + text))


if __name__ == "__main__":
    main()
