"""The refinements on tiny scenes: gradients, steps, checkpoints."""

import dataclasses

import numpy as np
import pytest

from lampfab import optimize, room, splat, surface
from lampfab.limits import Limits
from lampfab.source import Source


@pytest.fixture(scope="module")
def tiny_setup(tiny_design, inner_layer):
    lens = tiny_design.lens
    cyl = surface.Cylinder(lens.outer_radius_mm, lens.height_mm)
    walls = room.walls(tiny_design)
    rng = np.random.default_rng(7)
    targets = [rng.random(room.image_shape(w, 16)) for w in walls]
    return cyl, walls, targets


def _optimizer(cls, tiny_design, inner_layer, tiny_setup, slots=None, **changes):
    cyl, walls, targets = tiny_setup
    opt = dataclasses.replace(tiny_design.optimize, **changes)
    return cls(cyl, *inner_layer, Source(room.light_position(tiny_design)), 1.49, walls, targets, opt, Limits(20.0, 45.0),
               slots)


def test_splat_gradient_matches_finite_differences(mi, tiny_design, inner_layer, tiny_setup):
    from lampfab import losses

    opt = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, splat_photons=200_000)
    h = np.random.default_rng(3).normal(scale=0.5, size=(tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    loss, grad = opt.gradient(h, [0, 1, 2], seed=5)

    def loss_at(heights):
        return sum(losses.si_mse(opt.render(heights, k, seed=5), opt.targets[k], np.mean) for k in range(3))

    assert loss == pytest.approx(loss_at(h), rel=1e-4)
    direction = grad / np.abs(grad).max()
    eps = 0.01
    measured = loss_at(h + eps * direction) - loss_at(h - eps * direction)
    predicted = 2 * eps * np.sum(grad * direction)
    assert predicted > 0 and measured == pytest.approx(predicted, rel=0.1)


def test_splat_photons_are_stratified_so_steps_agree_closely(mi, tiny_design, inner_layer, tiny_setup):
    """Two steps' photon sets (different seeds) render the same lens nearly alike: far
    closer than independent photons, whose per-pixel counts differ by sqrt(2 N)."""
    opt = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, splat_photons=200_000)
    h = np.random.default_rng(3).normal(scale=0.5, size=(tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    a, b = opt.render(h, 0, seed=1), opt.render(h, 0, seed=2)
    assert not np.array_equal(a, b)
    counts = a * opt.n_photons
    lit = counts > 100
    assert lit.sum() > 50
    independent = np.sqrt(2 * counts[lit])
    assert np.sqrt(np.mean(((a - b)[lit] * opt.n_photons) ** 2)) < 0.5 * np.sqrt(np.mean(independent**2))


def test_finer_levels_trace_fine_level_photons_times_as_many(mi, tiny_design, inner_layer, tiny_setup):
    opt = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, splat_photons=100_000,
                     levels=2, fine_level_photons=2.0)
    h = np.zeros((tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    counts = {}
    for level in (0, 1, -1):
        opt.gradient(h, [0], seed=3, level=level)
        counts[level] = opt.n_photons
    assert counts[1] == counts[-1]
    assert counts[1] / counts[0] == pytest.approx(2.0, rel=0.02)
    # The previews every few steps take the coarse level's photons, the final picture the
    # fine level's.
    opt.preview_all(h, seed=4)
    assert opt.n_photons == counts[0]
    opt.render_all(h, seed=4)
    assert opt.n_photons == counts[-1]
    single = dataclasses.replace(opt.opt, levels=1)
    assert splat.photons_per_step(single, -1) == splat.photons_per_step(single, 0) == 100_000


def test_splat_photons_headed_into_a_slot_carry_no_light(mi, tiny_design, inner_layer, tiny_setup):
    """The refinement sees the shadow of the black-filled slots: the photons whose way
    through the glass enters one end there, and only those."""
    from lampfab.slots import Slot, Slots

    cut = Slots(3.0, tiny_design.lens.height_mm - 5.0, tuple(Slot(a, 18.0, 30.0) for a in (45.0, 135.0, 225.0, 315.0)))
    plain = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, splat_photons=100_000)
    slotted = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, slots=cut, splat_photons=100_000)
    h = np.zeros((tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    light = [sum(o.render(h, k, seed=2).sum() for k in range(3)) for o in (plain, slotted)]
    stopped = cut.stops(mi, plain.o_glass, plain.d_glass).numpy()
    weights = plain.w_glass.numpy()
    assert 0.01 < stopped.mean() < 0.2 and (weights[stopped] > 0).all()
    assert np.array_equal(slotted.w_glass.numpy(), np.where(stopped, 0.0, weights))
    assert light[1] < light[0] * (1 - 0.3 * weights[stopped].sum() / weights.sum())


def test_splat_image_is_the_photon_count_per_pixel(tiny_design, inner_layer, tiny_setup):
    """A pattern that alternates pixel by pixel survives the splat (verify bins photons
    per pixel, so the loss must see what verify will); a tent one pixel wide would
    blur it to a third of its contrast."""
    opt = _optimizer(splat.SplatOptimizer, tiny_design, inner_layer, tiny_setup, splat_photons=400_000)
    rows, cols = opt.shapes[0]
    rng = np.random.default_rng(11)
    py, px = rng.integers(0, rows, 400_000), rng.integers(0, cols, 400_000)
    lit = (px + py) % 2 == 0
    x, y = px[lit] + rng.uniform(-0.5, 0.5, lit.sum()), py[lit] + rng.uniform(-0.5, 0.5, lit.sum())
    image = opt._image(opt._landed(x, y, 0, 1.0 / 400_000)).reshape(rows, cols)
    binned = np.zeros((rows, cols))
    np.add.at(binned, (py[lit], px[lit]), 1.0 / 400_000)
    inner = (slice(1, -1), slice(1, -1))  # border pixels lose their outer sub-pixels' spill
    assert image.sum() == pytest.approx(binned.sum(), rel=0.01)
    dark = (np.add.outer(np.arange(rows), np.arange(cols)) % 2 == 1)[inner]
    contrast = 1 - image[inner][dark].mean() / image[inner][~dark].mean()
    assert contrast > 0.8


def test_splat_steps_reduce_the_loss_and_respect_the_slope_limit(mi, tiny_design, inner_layer, tiny_setup):
    cyl, walls, targets = tiny_setup
    settings = dataclasses.replace(tiny_design.optimize, splat_photons=100_000, iterations=6, levels=1,
                                   learning_rate=0.1)
    max_tilt_deg = 10.0  # the steps tilt the tiny lens 15° when free
    opt = splat.SplatOptimizer(cyl, *inner_layer, Source(room.light_position(tiny_design)), 1.49, walls, targets, settings,
                               Limits(20.0, max_tilt_deg))
    state = optimize.State(np.zeros((tiny_design.optimize.grid_u, tiny_design.optimize.grid_v)), 0, 0)
    first, _ = opt.gradient(state.heights, [0, 1, 2], seed=0)
    tilts = []  # every step's surface is one the printer could make, not only the last

    def progress(s, loss, message):
        tilts.append(surface.slopes_deg(opt.cyl, s.heights, 64, 17)[0].max())

    state = opt.run(state, lambda s: None, lambda s: None, progress)
    last, _ = opt.gradient(state.heights, [0, 1, 2], seed=0)
    assert state.step == 6 and last < first
    assert len(tilts) == 6 and max_tilt_deg - 1.0 < max(tilts) <= max_tilt_deg + 1e-6


def test_ptracer_method_gives_a_finite_nonzero_gradient(mi, tiny_design, inner_layer, tiny_setup):
    opt = _optimizer(optimize.PtracerOptimizer, tiny_design, inner_layer, tiny_setup, spp=8)
    h = np.zeros((tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    loss, grad = opt.gradient(h, [0], seed=1)
    assert np.isfinite(loss) and np.all(np.isfinite(grad)) and np.abs(grad).max() > 0


def test_a_few_nan_vertex_gradients_are_dropped_many_are_a_fault():
    rng = np.random.default_rng(3)
    grad = rng.standard_normal((10_000, 3))
    few = grad.copy()
    few[[5, 7000]] = np.nan
    kept = optimize.finite_vertex_gradient(few)
    assert np.isfinite(kept).all()
    assert (kept[[5, 7000]] == 0).all() and np.array_equal(np.delete(kept, [5, 7000], 0), np.delete(grad, [5, 7000], 0))
    many = grad.copy()
    many[:100, 1] = np.inf
    assert not np.isfinite(optimize.finite_vertex_gradient(many)).all()  # left for the fault check


def test_state_round_trips_through_arrays():
    state = optimize.State(np.arange(12.0).reshape(4, 3), level=1, step=7, lr_scale=0.5,
                           m=np.ones((4, 3)), v=np.full((4, 3), 2.0), adam_t=3, log=[(0, 0, 1, 0.5, 0.1)],
                           backtracks=[(5, 0.5)])
    back = optimize.State.from_arrays(state.to_arrays())
    assert back.step == 7 and back.level == 1 and back.adam_t == 3 and back.lr_scale == 0.5
    assert back.backtracks == [(5.0, 0.5)]
    assert np.array_equal(back.heights, state.heights) and np.array_equal(back.v, state.v)
    assert back.log == [(0.0, 0.0, 1.0, 0.5, 0.1)]


def test_levels_are_four_times_finer_each():
    from lampfab.profile import Optimize

    opt = Optimize(grid_u=256, grid_v=65, levels=3, iterations=10)
    assert optimize.level_grids(opt) == [(16, 5), (64, 17), (256, 65)]
    assert sum(optimize.level_steps(opt)) == 10


def test_splat_steps_keep_hollows_open_for_a_ball_end_tool(mi, tiny_design, inner_layer, tiny_setup):
    from lampfab import curvature

    cyl, walls, targets = tiny_setup
    opt = dataclasses.replace(tiny_design.optimize, splat_photons=100_000, iterations=6, levels=1, learning_rate=0.2)
    tool_mm = 40.0  # wider than the hollows these steps dig on the tiny lens

    def run(tool_radius_mm):
        method = splat.SplatOptimizer(cyl, *inner_layer, Source(room.light_position(tiny_design)), 1.49, walls, targets,
                                      opt, Limits(20.0, 45.0, tool_radius_mm=tool_radius_mm))
        state = optimize.State(np.zeros((opt.grid_u, opt.grid_v)), 0, 0)
        return method.run(state, lambda s: None, lambda s: None, lambda s, loss, msg: None).heights

    assert curvature.concave_radius(cyl, run(0.0)).min() < tool_mm
    assert curvature.concave_radius(cyl, run(tool_mm)).min() >= tool_mm
