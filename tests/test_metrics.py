"""lampfab.metrics: figures of resemblance between a render and its target."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lampfab import metrics
from lampfab.metrics import compare, pearson, ssim


@pytest.fixture
def target():
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:48, 0:64]
    img = ((x - 32) ** 2 + (y - 24) ** 2 < 15 ** 2).astype(float)  # a disc
    return 0.8 * img + 0.1 * rng.random(img.shape)


def test_identical_images(target):
    assert pearson(target, target) == pytest.approx(1.0)
    assert ssim(target, target) == pytest.approx(1.0)
    assert compare(target, target) == pytest.approx({"pearson": 1.0, "ssim": 1.0})


def test_figures_match_numpy_and_scikit_image(target):
    """Pearson r is numpy's; SSIM is scikit-image's on the mean-normalized images with the
    normalized target's range as data_range (the module docstring's definition)."""
    from skimage.metrics import structural_similarity

    render = np.roll(target, 3, axis=1) + 0.2 * np.random.default_rng(5).random(target.shape)
    assert pearson(render, target) == pytest.approx(np.corrcoef(render.ravel(), target.ravel())[0, 1], abs=1e-12)
    rn, tn = render / render.mean(), target / target.mean()
    expected = structural_similarity(rn, tn, data_range=np.ptp(tn), gaussian_weights=True, sigma=1.5,
                                     use_sample_covariance=False)
    assert ssim(render, target) == pytest.approx(expected, abs=1e-12) and 0.1 < expected < 0.9
    # The local map ssim averages: the image less scikit-image's 5 px border, lowest where
    # the render was shifted against the disc's edge.
    local = metrics.ssim_map(render, target)
    assert local.shape == (38, 54) and local.mean() == pytest.approx(expected, abs=1e-12)
    assert local.min() < expected < local.max()


def test_negative_image_anticorrelates(target):
    negative = 1.0 - target
    assert pearson(negative, target) < -0.9
    assert ssim(negative, target) < 0.0


def test_scale_invariance(target):
    render = target + 0.05 * np.random.default_rng(3).random(target.shape)
    a, b = compare(render, target), compare(3.0 * render, target)
    assert b["pearson"] == pytest.approx(a["pearson"], abs=1e-12)
    assert b["ssim"] == pytest.approx(a["ssim"], abs=1e-12)
    c = compare(render, 0.25 * target)  # the target's brightness does not matter either
    assert c["ssim"] == pytest.approx(a["ssim"], abs=1e-12)
    assert 0.5 < a["pearson"] < 1.0 and 0.0 < a["ssim"] < 1.0


def test_all_zero_render_gives_zero_not_nan(target):
    dark = np.zeros_like(target)
    figures = compare(dark, target)
    assert figures == {"pearson": 0.0, "ssim": 0.0}
    assert not any(math.isnan(v) for v in figures.values())


def test_constant_render_gives_zero_pearson(target):
    flat = np.full_like(target, 0.3)
    assert pearson(flat, target) == 0.0
    assert math.isfinite(ssim(flat, target))


def test_blur_lowers_figures(target):
    from scipy.ndimage import gaussian_filter

    blurred = gaussian_filter(target, 3.0)
    assert ssim(blurred, target) < 0.95
    assert 0.0 < pearson(blurred, target) < 1.0


def test_small_images_use_a_smaller_window():
    rng = np.random.default_rng(0)
    img = rng.random((5, 9))
    assert ssim(img, img) == pytest.approx(1.0) and metrics.ssim_map(img, img).shape == (1, 5)
    with pytest.raises(ValueError):
        ssim(rng.random((2, 9)), rng.random((2, 9)))


def test_shape_mismatch_and_nan_raise(target):
    with pytest.raises(ValueError):
        pearson(target, target[:-1])
    bad = target.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError):
        ssim(bad, target)


def test_contrast_is_bright_light_over_the_light_left_on_the_black():
    target = np.zeros((20, 20))
    target[5:15, 5:15] = 1.0  # a quarter of the wall bright, the rest black
    render = target * 9.0 + 1.0  # every pixel gets 1 of haze
    c = metrics.contrast(render, target)
    assert c["ratio"] == pytest.approx(10.0)
    assert c["black_share"] == pytest.approx(300 / (100 * 10 + 300))
    # All the light on the picture: nothing on the black.
    assert metrics.contrast(target, target) == {"ratio": None, "black_share": 0.0}
    # A picture without a black background (a photograph's range) has no such figure.
    assert metrics.contrast(render, np.linspace(0.2, 1.0, 400).reshape(20, 20)) is None
