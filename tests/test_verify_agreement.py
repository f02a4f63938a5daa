"""lampfab.verify.optimizer_agreement: the exported lens's render against the
optimizer's own noisy renders, with their noise taken out of r and a different lens
still caught."""

from __future__ import annotations

import numpy as np
import pytest

from lampfab import artifacts, metrics
from lampfab.tolerances import OPTIMIZER_MATCH_R
from lampfab.verify import SECOND_RENDER, optimizer_agreement, wall_files


def _picture(rng) -> np.ndarray:
    """(48, 64) float64: a low-contrast photograph-like picture (its light varies by about
    a third of its mean), what photon noise costs r most on."""
    from scipy.ndimage import gaussian_filter

    field = gaussian_filter(rng.standard_normal((48, 64)), 2.0)
    return np.clip(1.0 + 0.3 * field / field.std(), 0.05, None)


def _photons(picture: np.ndarray, per_pixel: float, rng) -> np.ndarray:
    """``picture`` counted with about ``per_pixel`` photons a pixel (Poisson noise)."""
    return rng.poisson(picture * per_pixel) / per_pixel


def _agreement(tmp_path, verify_render: np.ndarray, optimizer_renders: list[np.ndarray]) -> dict:
    out = tmp_path / "verify"
    out.mkdir()
    artifacts.write_npz(wall_files(out, "front")[2], led=verify_render, point=verify_render)
    named = {"front": optimizer_renders[0]}
    if len(optimizer_renders) > 1:
        named["front" + SECOND_RENDER] = optimizer_renders[1]
    artifacts.write_npz(tmp_path / "optimize_render.npz", light="led", **named)
    return optimizer_agreement(out, tmp_path / "optimize_render.npz", ["front"])["front"]


def test_the_same_lens_passes_through_the_optimizers_photon_noise(tmp_path):
    rng = np.random.default_rng(3)
    lens = _picture(rng)
    theirs = [_photons(lens, 60.0, rng) for _ in range(2)]
    agree = _agreement(tmp_path, lens, theirs)
    assert agree["raw_r"] == pytest.approx(metrics.pearson(lens, theirs[0]))
    assert agree["raw_r"] < OPTIMIZER_MATCH_R < agree["r"]          # the noise alone failed the raw figure
    assert 0.9 < agree["reliability"] < 0.99
    assert agree["r"] == pytest.approx(1.0, abs=0.01)


@pytest.mark.parametrize("other", ["shifted one pixel", "upside down"])
def test_a_different_lens_still_fails(tmp_path, other):
    rng = np.random.default_rng(4)
    lens = _picture(rng)
    theirs = [_photons(lens, 60.0, rng) for _ in range(2)]
    exported = np.roll(lens, 1, axis=1) if other == "shifted one pixel" else lens[::-1]
    assert _agreement(tmp_path, exported, theirs)["r"] < OPTIMIZER_MATCH_R


def test_a_single_optimizer_render_is_taken_as_it_is(tmp_path):
    rng = np.random.default_rng(5)
    lens = _picture(rng)
    theirs = _photons(lens, 60.0, rng)
    agree = _agreement(tmp_path, lens, [theirs])
    assert agree["reliability"] == 1.0 and agree["r"] == agree["raw_r"] == pytest.approx(metrics.pearson(lens, theirs))
