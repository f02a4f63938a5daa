"""Targets that are not one picture: a line of text, and a 360° panorama around the room.

Both return what ``image.load_target`` + ``image.letterbox`` return for a picture:
(rows, cols) float64 linear luminance in [0, 1], one array per wall.

* Text is set in the bundled DejaVu Sans Bold (``data/DejaVuSans-Bold.ttf``, Bitstream
  Vera licence beside it), white on black, centred, on the number of lines that
  makes the letters largest on the wall, or nearly as large on a much narrower
  picture (``LAYOUT_EM_TOLERANCE``), each line break placed where the widest line is
  narrowest.
* A panorama is a 360° cylindrical (or equirectangular) image: its width spans all
  azimuths, its centre column is the front wall, the left wall is a quarter to the
  left, the right wall a quarter to the right.  Each wall pixel takes the panorama
  pixel seen from the light in that direction, on a cylinder of radius
  ``wall_distance_mm`` with square pixels, so straight horizons stay level and the
  seams between walls line up.  The panorama's middle row is at the walls' image
  centre.  The floor, which the wrap does not reach, shows the back quarter.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from .errors import LampfabError
from .room import Wall

FONT = Path(__file__).resolve().parent / "data" / "DejaVuSans-Bold.ttf"
TEXT_MARGIN = 0.08   # blank border, as a share of the wall image on each side
_SUPERSAMPLE = 4     # glyphs drawn 4x larger and box-averaged: anti-aliased edges
_MAX_TEXT = 200      # characters; more would be unreadable on a wall at any size
# Of the layouts whose letters are at most LAYOUT_EM_TOLERANCE smaller than the largest,
# the one whose widest line is narrowest, when it is narrower than the largest letters'
# by LAYOUT_NARROWER_SHARE of the picture's width at least.  The LED's blur grows toward
# a picture's sides (a third wider in its outer eighths than in its middle, measured),
# so a line reaching them smears its outer letters: "Dream big little star" on three
# lines (the middle one edge to edge) read 7 of 12 words over three walls, on four
# lines with letters 2 % smaller 12 of 12.  A line narrower by less still reaches the
# sides: "Happy birthday my love" on four lines instead of three (its widest line 2 %
# narrower) read the same 10 of 12 (bench/log/2026-12-06.md).
LAYOUT_EM_TOLERANCE = 0.05
LAYOUT_NARROWER_SHARE = 0.125


def text_image(text: str, rows: int, cols: int) -> np.ndarray:
    """``text`` set as large as fits into (rows, cols): (rows, cols) float64 in [0, 1].

    Newlines in ``text`` are kept; otherwise words are spread over 1..n lines,
    whichever gives the largest letters.
    """
    em_px, layout = text_layout(text, rows, cols)
    # Glyph coverage is the share of a pixel lit, so it is linear luminance as is.
    return np.asarray(_drawn(layout, em_px, rows, cols).reduce(_SUPERSAMPLE), np.float64) / 255.0


def text_lines(text: str, rows: int, cols: int) -> list[tuple[int, int, str]]:
    """The rows each line of ``text_image(text, rows, cols)`` occupies, and the line:
    [(first row, end row, its words)] top to bottom, lines with no ink left out, each
    band cut midway between its ink and its neighbours' (bands of adjacent lines may
    share a row)."""
    em_px, layout = text_layout(text, rows, cols)
    lines = layout.split("\n")
    inked = []  # (first, end) in rows, the line
    for i in range(len(lines)):
        # The other lines blanked, not removed, keep this one where the layout puts it.
        alone = "\n".join(line if j == i else " " for j, line in enumerate(lines))
        ink = np.flatnonzero(np.asarray(_drawn(alone, em_px, rows, cols)).any(axis=1))
        if len(ink):
            inked.append(((ink[0] / _SUPERSAMPLE, (ink[-1] + 1) / _SUPERSAMPLE), lines[i]))
    cuts = [0.0] + [(a[0][1] + b[0][0]) / 2 for a, b in zip(inked, inked[1:])] + [float(rows)]
    return [(int(np.floor(cuts[i])), int(np.ceil(cuts[i + 1])), line) for i, (_, line) in enumerate(inked)]


def _drawn(layout: str, em_px: float, rows: int, cols: int):
    """``layout`` (lines joined by newlines) drawn white on black, centred, at
    ``_SUPERSAMPLE`` times (rows, cols): a Pillow "L" image."""
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.truetype(str(FONT), max(1, int(em_px * _SUPERSAMPLE)))
    big = Image.new("L", (cols * _SUPERSAMPLE, rows * _SUPERSAMPLE), 0)
    centre = (big.width / 2, big.height / 2)
    ImageDraw.Draw(big).multiline_text(centre, layout, fill=255, font=font, anchor="mm", align="center")
    return big


# Pure, and asked again for every reading of a wall (``text_lines``) and every picture of
# the phrase: a phrase of 40 words takes half a second to lay out.
@functools.lru_cache(maxsize=64)
def text_layout(text: str, rows: int, cols: int) -> tuple[float, str]:
    """How ``text_image`` sets ``text`` in (rows, cols): (the font's size, its em, in
    pixels; the lines joined by newlines).  The user's own line breaks are kept;
    otherwise the words go on as many lines as make the letters largest, or on those of
    the layouts within ``LAYOUT_EM_TOLERANCE`` of that which make the picture narrowest
    (of equally narrow, the largest letters) when it is ``LAYOUT_NARROWER_SHARE`` of the
    width narrower; each line break placed so that the widest line is as narrow as it
    can be."""
    from PIL import Image, ImageDraw, ImageFont

    words_by_line = [ln.split() for ln in str(text).splitlines()]
    if not any(words_by_line):
        raise LampfabError("TEXT is empty: give the words to project, e.g. TEXT=\"Happy birthday\"")
    if len(text) > _MAX_TEXT:
        raise LampfabError(f"TEXT has {len(text)} characters; at most {_MAX_TEXT} fit legibly on a wall")
    probe = 100
    font = ImageFont.truetype(str(FONT), probe)
    missing = _missing_glyphs(text, font)
    if missing:
        raise LampfabError(f"TEXT has characters the bundled font (DejaVu Sans Bold) cannot draw: "
                           f"{' '.join(missing)}; they would show as empty boxes. Give the words in "
                           f"Latin, Greek or Cyrillic letters, or make a picture of them and use TARGET=")
    box_w, box_h = cols * (1 - 2 * TEXT_MARGIN), rows * (1 - 2 * TEXT_MARGIN)
    draw = ImageDraw.Draw(Image.new("L", (1, 1)))
    candidates = []  # (scale, width on the wall in px, layout), fewer lines first
    for lines in _layouts(words_by_line, font):
        layout = "\n".join(lines)
        left, top, right, bottom = draw.multiline_textbbox((0, 0), layout, font=font, align="center")
        scale = min(box_w / (right - left), box_h / (bottom - top))
        candidates.append((scale, scale * (right - left), layout))
    largest = max(candidates, key=lambda c: c[0])  # of equals, the fewer lines
    near = [c for c in candidates if c[0] >= (1 - LAYOUT_EM_TOLERANCE) * largest[0]]
    # A width within a hundredth of a pixel of the narrowest is as narrow (layouts that
    # fill the box's width meet it to rounding).
    narrowest = min(width for _, width, _ in near) + 0.01
    narrow = max((c for c in near if c[1] <= narrowest), key=lambda c: c[0])
    scale, _, layout = narrow if largest[1] - narrow[1] >= LAYOUT_NARROWER_SHARE * cols else largest
    return probe * scale, layout


def _missing_glyphs(text: str, font) -> list[str]:
    """The characters of ``text`` that ``font`` has no glyph for: FreeType draws each as
    the font's .notdef box, the glyph of a code point no font has."""
    notdef = bytes(font.getmask("\U0010FFFD"))
    return sorted({ch for ch in text if not ch.isspace() and bytes(font.getmask(ch)) == notdef})


def _layouts(words_by_line: list[list[str]], font) -> list[list[str]]:
    """Candidate line breaks: the user's lines as they are, or else for each number of
    lines k the words cut into k lines whose widest (in ``font``) is narrowest."""
    if len(words_by_line) > 1:
        return [[" ".join(w) for w in words_by_line]]
    return _narrowest(words_by_line[0], font)


def _narrowest(words: list[str], font) -> list[list[str]]:
    """For k = 1 .. len(words): ``words`` cut into k lines so that the widest line (in
    ``font``) is as narrow as it can be.  One dynamic programme over the cuts serves
    every k: O(n^3) for n words, cheap for the 200 characters a wall takes."""
    n = len(words)
    width = [[0.0] * (n + 1) for _ in range(n + 1)]
    for i in range(n):
        for j in range(i + 1, n + 1):
            left, _, right, _ = font.getbbox(" ".join(words[i:j]))
            width[i][j] = right - left
    # widest[m][j]: the narrowest widest line setting words[:j] on m lines; cut[m][j]:
    # where its last line starts.
    widest = [[float("inf")] * (n + 1) for _ in range(n + 1)]
    cut = [[0] * (n + 1) for _ in range(n + 1)]
    widest[0][0] = 0.0
    for m in range(1, n + 1):
        for j in range(m, n + 1):
            for i in range(m - 1, j):
                candidate = max(widest[m - 1][i], width[i][j])
                if candidate < widest[m][j]:
                    widest[m][j], cut[m][j] = candidate, i
    out = []
    for k in range(1, n + 1):
        lines, j = [], n
        for m in range(k, 0, -1):
            lines.append(" ".join(words[cut[m][j]:j]))
            j = cut[m][j]
        out.append(lines[::-1])
    return out


def panorama_slice(panorama: np.ndarray, wall: Wall, light_mm: np.ndarray, radius_mm: float,
                   centre_height_mm: float, rows: int, cols: int) -> np.ndarray:
    """The part of a 360° ``panorama`` ((H, W) float64 linear, W spans 360°) that
    ``wall`` shows, seen from ``light_mm`` ((3,) mm): (rows, cols) float64.

    ``radius_mm``: the cylinder the panorama is wrapped on; ``centre_height_mm``: the
    height above the light of the panorama's middle row.  Outside the panorama's
    height the wall stays dark.
    """
    from scipy import ndimage

    if wall.name == "floor":
        return _back_quarter(panorama, rows, cols)
    pano = _resized(panorama, 4 * cols)
    h, w = pano.shape
    cc, rr = np.meshgrid((np.arange(cols) + 0.5) / cols, (np.arange(rows) + 0.5) / rows)
    points = wall.origin + cc[..., None] * wall.right + rr[..., None] * wall.down
    d = points - light_mm
    azimuth = np.degrees(np.arctan2(d[..., 1], d[..., 0]))
    height = d[..., 2] * radius_mm / np.hypot(d[..., 0], d[..., 1])
    pixel_mm = 2 * np.pi * radius_mm / w
    col = (w / 2 - 0.5 + (90.0 - azimuth) / 360.0 * w) % w
    row = (h - 1) / 2 - (height - centre_height_mm) / pixel_mm
    out = ndimage.map_coordinates(pano, [row, col], order=1, mode="grid-wrap")
    out[(row < -0.5) | (row > h - 0.5)] = 0.0
    return np.clip(out, 0.0, 1.0)


def _back_quarter(panorama: np.ndarray, rows: int, cols: int) -> np.ndarray:
    from .image import letterbox

    w = panorama.shape[1]
    back = np.roll(panorama, w // 2, axis=1)[:, 3 * w // 8: 5 * w // 8]  # azimuth 225°..315°
    return letterbox(back, rows, cols)


def _resized(image: np.ndarray, width: int) -> np.ndarray:
    """Box-averaged to ``width`` columns when wider (no aliasing when sampling)."""
    from PIL import Image

    h, w = image.shape
    if w <= width:
        return image
    rows = max(1, int(round(h * width / w)))
    return np.asarray(Image.fromarray(image.astype(np.float32)).resize(
        (width, rows), Image.Resampling.BOX), np.float64)


def check_panorama(panorama: np.ndarray, path) -> None:
    """A panorama must be wider than tall (it spans 360°); else it is likely a photo."""
    h, w = panorama.shape
    if w < 2 * h:
        raise LampfabError(f"{path}: {w}x{h} px is not a 360° panorama (expected at least twice as wide as "
                           f"tall); use TARGET= for an ordinary picture")
