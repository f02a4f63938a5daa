"""Reading the user's target image and fitting it onto a wall.

Rules (each one is what a user would reasonably expect of a projector):

* Formats: PNG and JPEG only (JPEG includes the MPO variant some cameras write; the
  first picture is used).  Other formats Pillow could read (GIF, BMP, TIFF, WebP...)
  are refused with a message saying to convert to PNG, so that the colour and alpha
  rules below hold for every accepted file.
* Encoding: every pixel value is sRGB-encoded, whatever the mode.  Integer modes are
  scaled by their full-scale value (8 bit: 255; 16 bit, mode ``I;16``/``I``: 65535),
  mode ``F`` is taken as already in [0, 1]; then the sRGB curve is undone and the
  linear Rec.709 luminance 0.2126 R + 0.7152 G + 0.0722 B is taken.  Embedded ICC
  profiles and PNG gAMA chunks are ignored (sRGB assumed).
* Alpha: the image is composited over black in linear light (luminance x alpha):
  transparent means no light.  Palette images with a transparent colour count as alpha.
* EXIF orientation is honoured (a phone photo is projected the way it is viewed).
* Size: at most ``MAX_PIXELS`` (50 megapixels), checked from the header before any
  pixel is decoded, so decompression bombs are refused cheaply.
* A target whose luminance range is below ``tolerances.CONSTANT_TARGET_RANGE`` is
  refused: a uniform image has nothing to project.

Every user error is a ``LampfabError`` whose one-line message names the file, what is
wrong and what is accepted.
"""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import numpy as np

from .errors import LampfabError
from .tolerances import CONSTANT_TARGET_RANGE

# Largest accepted image, in pixels.  50 MP is more than any phone camera (48 MP
# sensors) and ~1000x what a lens needs (targets are a few hundred pixels across);
# a 50 MP RGBA image decodes to 200 MB, which every supported machine has.
MAX_PIXELS = 50_000_000

ACCEPTED = "PNG or JPEG"
_FORMATS = {"PNG": "PNG", "JPEG": "JPEG", "MPO": "JPEG"}

# Rec.709 / sRGB primaries: linear luminance weights.
REC709 = np.array([0.2126, 0.7152, 0.0722])


def _pil():
    from PIL import Image

    # Pillow warns above MAX_IMAGE_PIXELS and refuses above twice that; lower its own
    # limit to ours (never raise it) so every Pillow reader in the process is protected.
    if Image.MAX_IMAGE_PIXELS is None or Image.MAX_IMAGE_PIXELS > MAX_PIXELS:
        Image.MAX_IMAGE_PIXELS = MAX_PIXELS
    return Image


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """Undo the sRGB transfer curve (IEC 61966-2-1); input and output in [0, 1]."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def load_target(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG or JPEG target: (rows, cols) float64 linear luminance in [0, 1].

    See the module docstring for the rules (formats, sRGB, alpha over black, EXIF
    orientation, size limit, constant images).  Raises ``LampfabError``.
    """
    Image = _pil()
    from PIL import ImageOps, UnidentifiedImageError

    path = Path(path)
    where = str(path)
    accepted = f"lampfab accepts {ACCEPTED} images up to {MAX_PIXELS // 1_000_000} megapixels"

    try:
        size = path.stat().st_size
    except FileNotFoundError:
        raise LampfabError(f"{where}: file not found; give the path of a {ACCEPTED} image") from None
    except OSError as exc:
        raise LampfabError(f"{where}: cannot read ({_one_line(exc.strerror or exc)}); "
                           f"give the path of a readable {ACCEPTED} image") from None
    if path.is_dir():
        raise LampfabError(f"{where}: is a folder, not an image file; give the path of a {ACCEPTED} image")
    if size == 0:
        raise LampfabError(f"{where}: the file is empty (0 bytes); {accepted}")

    try:
        with warnings.catch_warnings():
            # Pillow's DecompressionBombWarning (above MAX_IMAGE_PIXELS) becomes an error.
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                fmt = im.format or "unknown"
                if fmt not in _FORMATS:
                    raise LampfabError(f"{where}: is a {fmt} image, which lampfab does not read; "
                                       f"convert it to PNG ({accepted})")
                w, h = im.size
                if w * h > MAX_PIXELS:
                    raise _too_large(where, w * h, accepted, f"{w}x{h} = ")
                if w < 1 or h < 1:
                    raise LampfabError(f"{where}: the image has no pixels ({w}x{h}); {accepted}")
                im.load()
                im = ImageOps.exif_transpose(im)
                has_alpha = "A" in im.mode or "a" in im.mode or "transparency" in im.info
                lum = _luminance(im)
    except LampfabError:
        raise
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise _too_large(where, _bomb_pixels(exc), accepted) from None
    except UnidentifiedImageError:
        raise LampfabError(f"{where}: not an image (its contents are not a format Pillow "
                           f"recognises); {accepted}") from None
    except PermissionError:
        raise LampfabError(f"{where}: permission denied; give the path of a readable "
                           f"{ACCEPTED} image") from None
    except (OSError, SyntaxError, ValueError, EOFError, MemoryError) as exc:
        raise LampfabError(f"{where}: the image is truncated or corrupt "
                           f"({_one_line(exc) or type(exc).__name__}); re-export it as "
                           f"{ACCEPTED}") from None

    lo, hi = float(lum.min()), float(lum.max())
    if hi - lo < CONSTANT_TARGET_RANGE:
        alpha = " after compositing its transparency over black (transparent is dark)" if has_alpha else ""
        raise LampfabError(f"{where}: the image is uniform (luminance {lo:.4g} to {hi:.4g}){alpha}, "
                           f"nothing to project; use an image with light and dark areas "
                           f"(white shapes on black work best)")
    return lum


def _too_large(where: str, pixels: int, accepted: str, dims: str = "") -> LampfabError:
    size = f"{dims}{pixels / 1e6:.0f} megapixels" if pixels else f"over {MAX_PIXELS // 1_000_000} megapixels"
    return LampfabError(f"{where}: the image is too large ({size}); {accepted} "
                        f"(scale it down; a few hundred pixels across is plenty)")


def _bomb_pixels(exc: BaseException) -> int:
    """The pixel count in Pillow's decompression-bomb message (0 if not found)."""
    m = re.search(r"\((\d+) pixels\)", str(exc))
    return int(m.group(1)) if m else 0


def _luminance(im) -> np.ndarray:
    """Linear Rec.709 luminance, alpha composited over black, of a Pillow image."""
    mode = im.mode
    alpha = None
    if mode == "L" and "transparency" in im.info:  # grey PNG with a transparent level (tRNS)
        im, mode = im.convert("LA"), "LA"
    if mode in ("I;16", "I;16L", "I;16B", "I;16N", "I"):
        enc = np.asarray(im, dtype=np.float64) / 65535.0
    elif mode == "F":
        enc = np.asarray(im, dtype=np.float64)
    elif mode in ("1", "L"):
        enc = np.asarray(im.convert("L"), dtype=np.float64) / 255.0
    elif mode == "LA" or mode == "La":
        arr = np.asarray(im.convert("LA"), dtype=np.float64) / 255.0
        enc, alpha = arr[..., 0], arr[..., 1]
    else:
        has_alpha = "A" in mode or "a" in mode or "transparency" in im.info
        arr = np.asarray(im.convert("RGBA" if has_alpha else "RGB"), dtype=np.float64) / 255.0
        if has_alpha:
            arr, alpha = arr[..., :3], arr[..., 3]
        lum = srgb_to_linear(np.clip(arr, 0.0, 1.0)) @ REC709
        lum = np.clip(lum, 0.0, 1.0)
        return lum * alpha if alpha is not None else lum
    if enc.ndim != 2:
        raise ValueError(f"unexpected {mode} image shape {enc.shape}")
    lum = srgb_to_linear(np.clip(np.nan_to_num(enc, nan=0.0), 0.0, 1.0))
    return lum * alpha if alpha is not None else lum


def letterbox(image: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Fit ``image`` into (rows, cols) without distortion, centred, padded with 0.

    Aspect ratio is preserved; the image is scaled to touch two opposite sides.
    Downscaling averages over areas (Pillow BOX filter, exact area weights);
    upscaling interpolates bilinearly.  Both are convex combinations, so values stay
    within the input's range (and [0, 1] for a target).  Returns float64.
    """
    from PIL import Image

    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2 or img.size == 0:
        raise ValueError(f"letterbox needs a non-empty 2-D image, got shape {img.shape}")
    rows, cols = int(rows), int(cols)
    if rows < 1 or cols < 1:
        raise ValueError(f"letterbox needs a positive size, got {rows}x{cols}")
    h, w = img.shape
    scale = min(rows / h, cols / w)
    nh = min(rows, max(1, int(round(h * scale))))
    nw = min(cols, max(1, int(round(w * scale))))
    if (nh, nw) == (h, w):
        fitted = img
    else:
        resample = Image.Resampling.BOX if scale <= 1.0 else Image.Resampling.BILINEAR
        pil = Image.fromarray(img.astype(np.float32))  # mode "F"
        fitted = np.asarray(pil.resize((nw, nh), resample=resample), dtype=np.float64)
        fitted = np.clip(fitted, img.min(), img.max())
    out = np.zeros((rows, cols), dtype=np.float64)
    top, left = (rows - nh) // 2, (cols - nw) // 2
    out[top:top + nh, left:left + nw] = fitted
    return out
