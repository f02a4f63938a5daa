"""The density flow the transport's correction passes move the landed light with."""

import numpy as np
import pytest

from lampfab import flow


def _square(w, h):
    target = np.zeros((w, h))
    target[w // 4:w // 2, h // 3:2 * h // 3] = 1.0  # off centre: light must travel
    return target


def test_no_move_where_the_density_is_already_the_target(rng):
    target = rng.random((12, 9)) + 0.1
    ux, uy = flow.poisson_displacement(3.0 * target, target)  # scale does not matter
    assert np.abs(ux).max() < 1e-9 and np.abs(uy).max() < 1e-9


def test_light_spreads_out_of_a_bright_spot():
    density = np.ones((16, 16))
    density[7:9, 7:9] = 5.0
    ux, uy = flow.poisson_displacement(density, np.ones((16, 16)))
    assert ux[4, 8] < 0 < ux[11, 8] and uy[8, 4] < 0 < uy[8, 11]  # away from the spot
    # A gradient field: no curl.
    curl = np.gradient(uy, axis=0) - np.gradient(ux, axis=1)
    assert np.abs(curl).max() < 1e-9 * np.abs(ux).max() + 1e-12


@pytest.mark.parametrize("gain, substeps", [(1.0, 8), (0.5, 4)])
def test_flow_moves_uniform_points_towards_the_target(rng, gain, substeps):
    w, h = 32, 24
    target = _square(w, h)
    x, y = rng.random(40_000) * w, rng.random(40_000) * h
    inside = lambda px, py: np.mean(target[px.astype(int), py.astype(int)] > 0)  # noqa: E731
    to_x, to_y = flow.flow(x, y, target, gain, substeps)
    assert inside(x, y) == pytest.approx(1 / 12, abs=0.01)
    assert inside(to_x, to_y) > 0.4 * gain + 1 / 12
    assert to_x.min() >= 0 and to_x.max() < w and to_y.min() >= 0 and to_y.max() < h
    # Nearby points move alike: a smooth surface can follow.
    order = np.lexsort((np.round(y, 1), np.round(x, 1)))
    step = np.hypot(to_x - x, to_y - y)
    jump = np.hypot(np.diff((to_x - x)[order]), np.diff((to_y - y)[order]))
    close = np.hypot(np.diff(x[order]), np.diff(y[order])) < 0.1
    assert np.median(jump[close]) < 0.05 * np.median(step)


def test_more_flow_comes_closer():
    w, h = 32, 24
    target = _square(w, h)
    g = (np.arange(64) + 0.5) / 64
    x, y = (a.ravel() for a in np.meshgrid(g * w, g * h, indexing="ij"))
    errors = []
    for gain in (0.0, 0.5, 1.0):
        to_x, to_y = flow.flow(x, y, target, gain, 8)
        density, _, _ = np.histogram2d(to_x, to_y, bins=[w, h], range=[[0, w], [0, h]])
        errors.append(np.abs(density / density.sum() - target / target.sum()).sum())
    assert errors[0] > errors[1] > errors[2]
