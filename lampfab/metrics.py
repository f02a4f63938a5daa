"""How much a render looks like its target.

Both images are divided by their own mean before comparing, so the figures measure
the *pattern* of light, not its brightness: a render with 3x the flux scores the same.
(The amount of light reaching the wall is a separate figure, ``share``.)

* ``pearson``: Pearson correlation coefficient r in [-1, 1] of the two images.
* ``ssim``: structural similarity (Wang et al. 2004: Gaussian window sigma 1.5,
  population covariances, K1 = 0.01, K2 = 0.03) from scikit-image.  After mean
  normalization the values have mean 1 but no fixed maximum (a silhouette covering
  a quarter of the wall peaks at 4), so ``data_range`` is the range (max - min) of the
  normalized *target*: the same as scaling both images so the target spans [0, 1]
  and the render carries the same total flux, i.e. SSIM on the target's own scale.
  That keeps the stabilising constants C1, C2 proportional to the target's contrast
  for sparse and dense images alike.

Degenerate inputs give 0.0, never NaN: a render (or target) without light or without
any variation has no resemblance to measure.  Shape mismatches and non-finite values
are programming errors and raise ValueError.
"""

from __future__ import annotations

import numpy as np

# Wang et al.'s SSIM: a Gaussian window of sigma 1.5 px, and the stabilising constants
# C1 = (K1 * data_range)^2, C2 = (K2 * data_range)^2.  losses.ssim_term uses the same.
SSIM_SIGMA = 1.5
SSIM_K1, SSIM_K2 = 0.01, 0.03
# That window needs 11x11 pixels (scikit-image truncates it at 3.5 sigma).
_GAUSS_MIN = 11


def _pair(render, target) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(render, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    if r.shape != t.shape or r.ndim != 2:
        raise ValueError(f"render and target must be 2-D images of the same shape, "
                         f"got {r.shape} and {t.shape}")
    if not (np.isfinite(r).all() and np.isfinite(t).all()):
        raise ValueError("render or target contains NaN or infinite values")
    return r, t


def _normalized(img: np.ndarray) -> np.ndarray | None:
    """``img`` divided by its mean, or None when it has no (positive) light."""
    mean = float(img.mean())
    if not mean > 0.0:
        return None
    return img / mean


def pearson(render, target) -> float:
    """Pearson r of the mean-normalized images; 0.0 if either is constant or dark."""
    r, t = _pair(render, target)
    rn, tn = _normalized(r), _normalized(t)
    if rn is None or tn is None:
        return 0.0
    rc, tc = rn - rn.mean(), tn - tn.mean()
    denom = float(np.sqrt((rc * rc).sum() * (tc * tc).sum()))
    if not denom > 1e-12 * rc.size:
        return 0.0
    return float(np.clip((rc * tc).sum() / denom, -1.0, 1.0))


def ssim(render, target) -> float:
    """SSIM of the mean-normalized images (see module docstring for data_range)."""
    local = ssim_map(render, target)
    value = float(local.mean()) if local is not None else 0.0
    return value if np.isfinite(value) else 0.0


def ssim_map(render, target) -> np.ndarray | None:
    """The local SSIM that ``ssim`` averages, per pixel: (rows - 2p, cols - 2p) float64,
    the border p of half the window cropped as scikit-image crops it; None where either
    image has no light."""
    from skimage.metrics import structural_similarity

    r, t = _pair(render, target)
    rn, tn = _normalized(r), _normalized(t)
    if rn is None or tn is None:
        return None
    data_range = ssim_data_range(tn)
    small = min(r.shape)
    if small >= _GAUSS_MIN:
        kw = dict(gaussian_weights=True, sigma=SSIM_SIGMA, use_sample_covariance=False)
        pad = (_GAUSS_MIN - 1) // 2
    elif small >= 3:
        # Too small for Wang's window: the largest odd uniform window that fits.
        win = small if small % 2 else small - 1
        kw = dict(win_size=win, use_sample_covariance=False)
        pad = (win - 1) // 2
    else:
        raise ValueError(f"images of shape {r.shape} are too small for SSIM (need 3x3)")
    _, local = structural_similarity(rn, tn, data_range=data_range, K1=SSIM_K1, K2=SSIM_K2, full=True, **kw)
    return local[pad:local.shape[0] - pad, pad:local.shape[1] - pad]


def ssim_data_range(normalized_target: np.ndarray) -> float:
    """The range of the mean-normalized target (see the module docstring); 1.0 for a
    constant target, whose normalized value is 1 everywhere."""
    data_range = float(normalized_target.max() - normalized_target.min())
    return data_range if data_range > 0.0 else 1.0


def compare(render, target) -> dict:
    """{"pearson": r, "ssim": s} of a render against its target."""
    return {"pearson": pearson(render, target), "ssim": ssim(render, target)}


# The target's "black" and "bright" for ``contrast``: under 5 % of its peak (the
# silhouettes' backgrounds, the letterbox bars; a photograph's shadows rarely go that
# dark) and over half of it.  A target with less than 5 % of its pixels black has no
# background to keep dark, and gets no contrast figure.
BLACK_OF_PEAK, BRIGHT_OF_PEAK = 0.05, 0.5
MIN_BLACK_SHARE = 0.05


def contrast(render, target) -> dict | None:
    """How dark the render keeps the target's black: {"ratio": mean light on the target's
    bright pixels over mean light on its black ones, "black_share": the share of the
    render's light that falls on the black}; None where the target has no black.  The
    ratio is None where no light at all falls on the black."""
    r, t = _pair(render, target)
    peak = float(t.max())
    black, bright = t < BLACK_OF_PEAK * peak, t > BRIGHT_OF_PEAK * peak
    total = float(r.sum())
    if peak <= 0 or black.mean() < MIN_BLACK_SHARE or not bright.any() or total <= 0:
        return None
    dark = float(r[black].mean())
    return {"ratio": float(r[bright].mean()) / dark if dark > 0 else None,
            "black_share": float(r[black].sum()) / total}
