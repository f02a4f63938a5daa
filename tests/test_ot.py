import warnings

import numpy as np
import pytest

from lampfab import losses, ot


def test_transport_map_pushes_uniform_light_onto_a_disc():
    n, m = 32, 24
    yy, xx = np.meshgrid((np.arange(m) + 0.5) / m, (np.arange(n) + 0.5) / n)
    target = (((xx - 0.5) ** 2 + (yy - 0.5) ** 2) < 0.09).astype(float)
    grid_n = (np.arange(n) + 0.5) / n
    grid_m = (np.arange(m) + 0.5) / m
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        y1, y2, err = ot.barycentric_map(np.ones((n, n)), target, grid_n, grid_n, grid_n, grid_m, (1 / n) ** 2)
    pushed, _, _ = np.histogram2d(y1.ravel(), y2.ravel(), bins=[n, m], range=[[0, 1], [0, 1]])
    assert err < 0.02
    assert np.corrcoef(pushed.ravel(), target.ravel())[0, 1] > 0.9
    assert pushed[target == 0].sum() < 0.05 * pushed.sum()  # dark stays dark
    # An OT map of a uniform source is monotone along each axis.
    assert np.all(np.diff(y1, axis=0) > -1e-6) and np.all(np.diff(y2, axis=1) > -1e-6)


def test_marginal_error_measures_the_light_an_unconverged_transport_misplaces():
    n = 32
    grid = (np.arange(n) + 0.5) / n + 1.0  # positive: the maps take logs of coordinates
    target = np.zeros((n, n))
    target[20:28, 4:12] = 1.0  # a square far from the source's middle
    eps = (1 / n) ** 2
    cost = (grid[:, None] - grid[None, :]) ** 2
    source = np.ones((n, n))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        converged = ot.barycentric_map(source, target, grid, grid, grid, grid, eps)
        # A zero target potential: the plan of a transport that has not started.
        stopped = ot.maps_of(source / source.sum(), target / target.sum(), cost, cost, grid, grid,
                             np.zeros((n, n)), eps)
    for y1, y2, err in (converged, stopped):
        pushed, _, _ = np.histogram2d(y1.ravel(), y2.ravel(), bins=[n, n], range=[[1, 2], [1, 2]])
        misplaced = np.abs(pushed / pushed.sum() - target / target.sum()).sum()  # L1, as the error
        assert err == pytest.approx(misplaced, abs=0.05)
    assert converged[2] < 0.05 < 0.5 < stopped[2]


def test_scale_independent_loss_ignores_brightness(rng):
    render, target = rng.random((8, 8)), rng.random((8, 8))
    a = losses.si_mse(render, target, np.mean)
    assert np.isclose(a, losses.si_mse(5.0 * render, 0.1 * target, np.mean))
    assert losses.si_mse(target, target, np.mean) == 0.0


@pytest.mark.parametrize("name", ["si_mse", "si_mse_ssim", "multiscale", "l1_weighted"])
def test_numpy_loss_gradients_match_finite_differences(rng, name):
    render, target = rng.random((6, 7)) + 0.05, rng.random((6, 7))
    target[:2] = 0.0  # dark rows, as in a silhouette
    loss, grad = losses.view_loss_and_grad(name, render, target)
    assert loss == pytest.approx(losses.view_loss(name, render, target, np.mean))
    step = 1e-6
    numeric = np.zeros_like(render)
    for index in np.ndindex(render.shape):
        bumped = render.copy()
        bumped[index] += step
        numeric[index] = (losses.view_loss(name, bumped, target, np.mean) - loss) / step
    assert np.allclose(grad, numeric, atol=1e-4 * np.abs(grad).max())


def test_ssim_term_counts_haze_that_squared_errors_barely_see():
    target = np.zeros((24, 32))
    target[6:18, 10:22] = 1.0  # a bright square on black
    t = target / target.mean()
    similarity, grad = losses.ssim_term(t, t)
    assert similarity == pytest.approx(1.0) and np.abs(grad).max() < 1e-9  # a maximum
    hazy = target + 0.02  # a faint haze: 2 % of the square's brightness everywhere
    h = hazy / hazy.mean()
    no_image = losses.si_mse(np.ones_like(target), target, np.mean)
    assert losses.si_mse(hazy, target, np.mean) < 0.02 * no_image
    assert losses.ssim_term(h, t)[0] < 0.7


def test_multiscale_loss_pulls_light_across_a_dark_gap():
    """A spot lit 8 px from where the target wants it: the per-pixel losses are flat in
    the dark between the two (moving light there changes nothing), the blurred terms
    slope down towards the target all the way."""
    target, render = np.zeros((16, 32)), np.full((16, 32), 1e-3)
    target[6:10, 20:24] = 1.0
    render[6:10, 8:12] = 1.0
    row = 8
    for name in ("si_mse", "si_mse_ssim"):
        grad = losses.view_loss_and_grad(name, render, target)[1]
        assert np.ptp(grad[row, 13:19]) < 0.01 * np.abs(grad).max()
    grad = losses.view_loss_and_grad("multiscale", render, target)[1]
    assert np.all(np.diff(grad[row, 12:20]) < 0)
    assert grad[row, 12] - grad[row, 19] > 0.3 * np.abs(grad).max()


def test_cyclic_schedule_visits_one_view_per_step():
    assert [losses.views_for_step("cyclic", t, 3) for t in range(4)] == [[0], [1], [2], [0]]
    assert losses.views_for_step("joint", 5, 3) == [0, 1, 2]
