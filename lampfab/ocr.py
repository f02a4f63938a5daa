"""Reading a text lamp's walls back: Tesseract OCR (Debian's ``tesseract-ocr``) on a
render, counting the words of the phrase it finds.

Tesseract reads the render's linear light (the wall's physical contrast between strokes
and gaps), as dark letters on white, the way its models were trained.  It does not read
the display's sRGB encoding of a soft picture: that encoding lifts the dim light between
blurred strokes, and there Tesseract read none of four words even of the sharp target
blurred by a fifth of an em, which a person reads easily.

A wall is read twice: as one block of text, and line by line (the rows of each line of
the phrase's layout, ``targets.text_lines``), and a word counts when either reading finds
it.  Either reading alone sometimes loses a word a person reads at once, or a whole
wall: Tesseract's page analysis misplaces a short line set alone ("big" read as "rh"),
or gives up on a block.  Together they read every word of 16 sharp four- and five-word
targets at 64 px, and their limit matches a person's: words read up to a blur of 0.3 em
and mostly not at 0.5 em, where the blur leaves too little contrast at two cycles per
letter, below which people stop reading (Legge, Pelli, Rubin & Schleske, "Psychophysics
of reading I", Vision Research 25, 1985).  bench/text_blur.py measures it.

A wall rendered at the design's resolution (64 px across: an em of about 11 px) is far
below the 20-30 px letters Tesseract reads best, so the render is scaled up first.  A
phrase's word counts once for each time it appears.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import unicodedata
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

# Scale-up before reading: 8 x puts the 64 px walls' letters at 80-90 px, inside the
# size range Tesseract reads best; 4 x lost words on the four-word phrase's targets.
UPSCALE = 8

# The brightest light counted as white: a few hot pixels of a photon render (where
# strokes cross) would otherwise push every stroke to grey.
WHITE_PERCENTILE = 99.5

# Dark rows of the wall's image above and below a line read alone: a third of a line's
# height at 64 px, about the block's own margin, with no part of the neighbouring lines.
LINE_MARGIN_PX = 4


def available() -> bool:
    """Whether the ``tesseract`` program is installed."""
    return shutil.which("tesseract") is not None


def words(text: str) -> list[str]:
    """``text``'s words, lower case, letters and digits only, accents dropped (Tesseract's
    English model reads "café" as "cafe" as often as not)."""
    plain = unicodedata.normalize("NFKD", text.lower()).encode("ascii", "ignore").decode()
    return [w for w in re.sub(r"[^0-9a-z]+", " ", plain).split() if w]


def read(image: np.ndarray, psm: int = 6) -> list[str]:
    """The words Tesseract reads in ``image`` ((h, w) float, linear light, any scale),
    as one block of text (``psm`` 6) or one line (7)."""
    from PIL import Image

    white = float(np.percentile(image, WHITE_PERCENTILE))
    light = np.clip(image / white, 0.0, 1.0) if white > 0 else np.zeros_like(image)
    page = Image.fromarray(np.uint8(np.round(255 * (1.0 - light))))  # dark letters on white
    page = page.resize((page.width * UPSCALE, page.height * UPSCALE), Image.Resampling.BICUBIC)
    return words(_tesseract(page, psm))


def words_read(image: np.ndarray, phrase: str) -> int:
    """How many of ``phrase``'s words Tesseract reads in ``image``, a wall showing it as
    ``targets.text_image`` sets it at ``image``'s size: read as a block and line by line."""
    from .targets import text_lines

    pages = [(image, 6)] + [(np.pad(image[first:end], ((LINE_MARGIN_PX, LINE_MARGIN_PX), (0, 0))), 7)
                            for first, end, _ in text_lines(phrase, *image.shape)]
    found = Counter()
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        for read_words in pool.map(lambda page: read(*page), pages):
            found |= Counter(read_words)
    return sum((Counter(words(phrase)) & found).values())


def _tesseract(page, psm: int) -> str:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "wall.png"
        page.save(path)
        # One thread each: on a wall-sized page Tesseract's OpenMP threads cost more
        # than they give (0.23 s against 0.16 s a page on 2 cores), and words_read runs
        # its pages side by side.
        done = subprocess.run(["tesseract", str(path), "-", "--psm", str(psm)], capture_output=True, text=True,
                              env={**os.environ, "OMP_THREAD_LIMIT": "1"})
    if done.returncode:
        raise RuntimeError(f"tesseract failed: {done.stderr.strip()[-300:]}")
    return done.stdout
