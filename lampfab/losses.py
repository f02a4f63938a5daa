"""The source's per-view losses and view schedules, and lampfab's SSIM term.

The source's losses are written with arithmetic and a ``mean`` function only, so the
same code runs on Dr.Jit tensors (for gradients) and on numpy arrays (tests, reports).
``view_loss_and_grad`` gives a loss and its gradient in numpy, for refinements that sum
in numpy so that a seed gives the same bits every time.

``si_mse_ssim`` adds ``SSIM_WEIGHT * (1 - SSIM)`` of the mean-normalized images to
``si_mse``, with verify's SSIM window and constants (``metrics``).  Squared errors
hardly notice a faint haze over a black background or a ripple over a flat bright area;
SSIM, which verify reports, counts both.

``multiscale`` adds to that the squared error of both images blurred at a few scales
(``BLUR_SIGMAS_PX``).  A photon only feels the pixels it lands near, so per-pixel terms
cannot pull light across a dark gap or into a dim area from afar; the blurred terms
give the whole neighbourhood a slope towards where light is missing.

Both are numpy only (images (rows, cols)), so only the ``splat`` refinement takes them.
"""

from __future__ import annotations

import numpy as np

from . import metrics
from .profile import NUMPY_ONLY_LOSSES

# Weight of (1 - SSIM) against si_mse.  Measured on the apple and the star (default
# profile, 40 steps, same transport design; bench/RESULTS.md): 0.5 and 1.0 both raise
# every wall's SSIM (apple by 0.01-0.03, star by 0.01) without lowering Pearson r; 1.0
# was a little better on both.
SSIM_WEIGHT = 1.0

# Blur scales (pixels) and the weight of their squared errors against si_mse.  Measured on
# the horse (default profile, same transport design; bench/RESULTS.md), min r 0.928 before:
# 2-8 px at weight 4 and 16 gave 0.935 and 0.937 (16 with learning rate 0.04: 0.941),
# 4-16 px at 10 gave 0.934, 2-4 px at 1 gave 0.930; 32 with the default profile's rates
# fell back to 0.930 from 0.940.  Blurring shrinks the errors, so the weight is large.
BLUR_SIGMAS_PX = (2.0, 4.0, 8.0)
BLUR_WEIGHT = 16.0

# Windows are truncated like scikit-image's (3.5 sigma) and padded with zeros, so that
# filtering is its own adjoint and the gradients are exact.
_TRUNCATE = 3.5


def _blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    return gaussian_filter(image, sigma_px, mode="constant", truncate=_TRUNCATE)


def si_mse(render, target, mean):
    """Scale-independent MSE: both images divided by their mean, then MSE (source 4.1)."""
    return mean(((render / mean(render)) - (target / mean(target))) ** 2)


def ssim_term(render: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray]:
    """Mean SSIM of two (rows, cols) images that are already mean-normalized, and its
    gradient with respect to ``render`` (same shape).  The data range is the target's
    (``metrics.ssim_data_range``).  Zero padding makes it differ from ``metrics.ssim``
    (which crops the border) near the edges only."""
    def window(a):
        return _blur(a, metrics.SSIM_SIGMA)

    data_range = metrics.ssim_data_range(target)
    c1, c2 = (metrics.SSIM_K1 * data_range) ** 2, (metrics.SSIM_K2 * data_range) ** 2
    x, y = render, target
    mx, my = window(x), window(y)
    sxx, syy, sxy = window(x * x) - mx * mx, window(y * y) - my * my, window(x * y) - mx * my
    a1, a2 = 2 * mx * my + c1, 2 * sxy + c2
    b1, b2 = mx * mx + my * my + c1, sxx + syy + c2
    s = a1 * a2 / (b1 * b2)
    per_pixel = s / s.size  # d(mean SSIM) / d(SSIM at a pixel), times that SSIM
    d_mean = per_pixel * (2 * my / a1 - 2 * mx / b1 - 2 * my / a2 + 2 * mx / b2)
    d_cross = per_pixel * 2 / a2  # with respect to window(x * y)
    d_square = -per_pixel / b2  # with respect to window(x * x)
    grad = window(d_mean) + y * window(d_cross) + 2 * x * window(d_square)
    return float(s.mean()), grad


def blurred_mse(render: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray]:
    """Sum over ``BLUR_SIGMAS_PX`` of the MSE between the two (rows, cols) images, both
    blurred by a Gaussian of that sigma, and its gradient with respect to ``render``."""
    total, grad = 0.0, np.zeros_like(render)
    for sigma in BLUR_SIGMAS_PX:
        err = _blur(render, sigma) - _blur(target, sigma)
        total += float(np.mean(err**2))
        grad += _blur(2.0 / render.size * err, sigma)
    return total, grad


def l1(render, target, mean):
    """Absolute error summed over pixels, as mean x count (the source's L_joint term)."""
    return mean(abs(render - target))


def view_loss(name: str, render, target, mean, weight: float = 1.0):
    """One view's contribution to the loss named ``name`` (see ``profile.LOSSES``)."""
    if name == "si_mse":
        return si_mse(render, target, mean)
    if name in NUMPY_ONLY_LOSSES:
        if not isinstance(render, np.ndarray):
            raise ValueError(f"{name} is computed in numpy only (the splat refinement)")
        return view_loss_and_grad(name, render, target, weight)[0]
    if name == "l1_joint":
        return l1(render, target, mean)
    if name == "l1_weighted":
        return weight * l1(render, target, mean)
    raise ValueError(f"unknown loss {name!r}")


def view_loss_and_grad(name: str, render: np.ndarray, target: np.ndarray,
                       weight: float = 1.0) -> tuple[float, np.ndarray]:
    """``view_loss`` and its gradient with respect to ``render``: (float, array shaped
    like ``render``), float64 numpy.  ``NUMPY_ONLY_LOSSES`` need (rows, cols) images."""
    render = np.asarray(render, np.float64)
    target = np.asarray(target, np.float64)
    if name in ("si_mse", *NUMPY_ONLY_LOSSES):
        scale = render.mean()
        a = render / scale
        t = target / target.mean()
        err = a - t
        loss, grad_a = float(np.mean(err**2)), 2.0 / render.size * err
        if name in NUMPY_ONLY_LOSSES:
            similarity, grad_similarity = ssim_term(a, t)
            loss += SSIM_WEIGHT * (1.0 - similarity)
            grad_a = grad_a - SSIM_WEIGHT * grad_similarity
        if name == "multiscale":
            blurred, grad_blurred = blurred_mse(a, t)
            loss += BLUR_WEIGHT * blurred
            grad_a = grad_a + BLUR_WEIGHT * grad_blurred
        # through a = render / mean(render)
        return loss, (grad_a - np.mean(grad_a * a)) / scale
    if name in ("l1_joint", "l1_weighted"):
        w = weight if name == "l1_weighted" else 1.0
        return float(w * np.mean(np.abs(render - target))), w * np.sign(render - target) / render.size
    raise ValueError(f"unknown loss {name!r}")


def views_for_step(schedule: str, step: int, n_views: int) -> list[int]:
    """Which views a step back-propagates: one, cycling (i_t = t mod n), or all."""
    if schedule == "cyclic":
        return [step % n_views]
    if schedule == "joint":
        return list(range(n_views))
    raise ValueError(f"unknown schedule {schedule!r}")
