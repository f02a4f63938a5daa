"""The source's method (``ptracer``): Mitsuba's ``ptracer`` + Dr.Jit gradients of the outer
vertices, a per-view loss, one view per step (cyclic) or all (joint), plain gradient
descent or Adam, coarse-to-fine x4.

The surface is always the full-resolution heightmap; the traced mesh is its spline
tessellated ``tessellation`` times finer with flat facets, i.e. the surface that is
exported.  Coarse-to-fine is in the steps: level k moves the surface by a spline on a
grid 4^(levels-1-k) times coarser, whose gradient is the vertex gradient pulled back
through the (linear) spline sampling.  Monte Carlo noise in per-vertex gradients
averages out over a coarse node's footprint, and the finest level adds detail last.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import time
from dataclasses import dataclass, field

import numpy as np

from . import lens, losses, scene, surface
from .concavity import hollow_penalty
from .errors import LampfabError
from .limits import Limits
from .profile import Optimize
from .room import Wall
from .source import Source

# Losses above this multiple of the best loss so far (same view, same level) count as
# an explosion (the source's GD diverges this way).
EXPLODE_FACTOR = 20.0
# After a numerical fault the run goes back to the last good checkpoint with the
# learning rate halved; after this many halvings in a row it stops with a message
# (1/1024 of the profile's rate: a step that still fails is not a step-size problem).
MAX_FALLBACKS = 10
# The slope and overhang penalty starts this far below the limits, so the projection
# after each step has little to do.  Without the overhang in it, 0.7 % of the horse's
# surface overhung the print's 45° by up to 10° (bench/RESULTS.md).
PENALTY_MARGIN_DEG = 2.0
# The hollow penalty (milled lenses) starts at this many times the tool's radius: the
# projection then rarely has to open a hollow after a step, and each time it does it
# widens the hollow's flanks too (bench/RESULTS.md, "Hollows opened no wider than the
# tool needs").
HOLLOW_PENALTY_MARGIN = 1.2
# With ``backtrack``, a step is taken again, half as long, when the loss after it is
# more than this fraction above the loss before it. Adam's first steps on a level move
# every node by the learning rate, whatever its gradient: from the transport design the
# first raised the loss on nine of ten images (not the horse's), by 10 % (coffee) to 13x
# (moon), and the clock's never came back down. Later rises of 2-8 % are Adam at work
# and come back down within a step or two (chelsea, apple). Measured with the
# optimizer's own renders on those ten transport designs (bench/RESULTS.md): 0.3 gave
# the same lenses as 0.1 on three of four images; 0.01 (three times the photons'
# step-to-step spread of 0.1-0.4 %) cost chelsea r 0.98 -> 0.92 and slowed the astronaut,
# coffee and camera.
RISE_TOLERANCE = 0.1
# After each step kept, the learning rate grows back by this factor towards the
# profile's, so one overshoot does not slow the rest of the level (without regrowth,
# chelsea's r fell from 0.981 to 0.915).
REGROWTH = 1.2
# The source's ptracer gradient can be NaN at a few vertices of a step (a photon path
# whose derivative is undefined; the loss itself finite); the spline's adjoint would
# spread them to every node.  Up to this share of the vertices they are dropped from
# that step; more is a real fault.  The full `make bench` on a slow machine stopped at the
# source's method at its step 449 this way (bench/RESULTS.md).
MAX_NONFINITE_VERTEX_SHARE = 1e-3


@dataclass
class State:
    """Everything needed to resume: the heightmap, the step rule's moments, the log."""
    heights: np.ndarray  # (grid_u, grid_v) mm: the full-resolution surface
    level: int
    step: int
    lr_scale: float = 1.0
    m: np.ndarray | None = None
    v: np.ndarray | None = None
    adam_t: int = 0
    log: list = field(default_factory=list)  # rows: (step, level, view, loss, seconds)
    faults: list = field(default_factory=list)  # rows: (step, learning-rate scale after falling back)
    backtracks: list = field(default_factory=list)  # rows: (step, learning-rate scale after backtracking)

    def to_arrays(self) -> dict:
        return {"heights": self.heights, "level": self.level, "step": self.step,
                "lr_scale": self.lr_scale, "m": np.zeros(0) if self.m is None else self.m,
                "v": np.zeros(0) if self.v is None else self.v, "adam_t": self.adam_t,
                "log": np.asarray(self.log, np.float64).reshape(-1, 5),
                "faults": np.asarray(self.faults, np.float64).reshape(-1, 2),
                "backtracks": np.asarray(self.backtracks, np.float64).reshape(-1, 2)}

    @staticmethod
    def from_arrays(a: dict) -> "State":
        moments = (a["m"], a["v"]) if a["m"].size else (None, None)
        return State(heights=a["heights"], level=int(a["level"]), step=int(a["step"]),
                     lr_scale=float(a["lr_scale"]), m=moments[0], v=moments[1], adam_t=int(a["adam_t"]),
                     log=[tuple(r) for r in a["log"]], faults=[tuple(r) for r in a.get("faults", [])],
                     backtracks=[tuple(r) for r in a.get("backtracks", [])])

    def copy(self) -> "State":
        return dataclasses.replace(self, heights=self.heights.copy(),
                                   m=None if self.m is None else self.m.copy(),
                                   v=None if self.v is None else self.v.copy(),
                                   log=list(self.log), faults=list(self.faults),
                                   backtracks=list(self.backtracks))


def level_grids(opt: Optimize) -> list[tuple[int, int]]:
    """Node grids from coarse to fine, x4 in u and v between levels."""
    grids = []
    for k in range(opt.levels):
        f = 4 ** (opt.levels - 1 - k)
        grids.append((opt.grid_u // f, (opt.grid_v - 1) // f + 1))
    return grids


def level_steps(opt: Optimize) -> list[int]:
    """Steps per level: split evenly."""
    base = [opt.iterations // opt.levels] * opt.levels
    base[-1] += opt.iterations - sum(base)
    return base


def anneal_factor(opt: Optimize, step: int) -> float:
    """How much of its step the finest level takes at ``step`` (0-based) under
    ``fine_level_anneal``: whole steps for the first half of the level, then falling
    linearly to 2/n at its last of n steps; 1 at every other step, and always without
    the option."""
    steps = level_steps(opt)
    start = sum(steps[:-1])
    if not opt.fine_level_anneal or step < start:
        return 1.0
    return min(1.0, 2.0 * (1.0 - (step - start) / steps[-1]))


class Interrupted(Exception):
    """SIGINT/SIGTERM arrived; the state at ``step`` was checkpointed."""

    def __init__(self, signum: int, step: int):
        super().__init__(signum, step)
        self.step = step


class NumericalFault(LampfabError):
    """Steps keep failing (NaN, Inf, an exploding loss) even with a much smaller step."""


class Optimizer:
    """The loop every method shares; a method supplies ``gradient`` and ``render``."""

    def __init__(self, cyl: surface.Cylinder, inner_vertices: np.ndarray, inner_faces: np.ndarray,
                 source: Source, ior: float, walls: list[Wall], targets: list[np.ndarray],
                 opt: Optimize, limits: Limits, slots=None):
        if opt.backtrack and opt.schedule != "joint":
            # One view per step: consecutive losses are of different walls, and every
            # step would look like a rise (the profile loader refuses this too).
            raise ValueError("backtrack needs schedule 'joint'")
        self.cyl, self.inner_v, self.inner_f = cyl, inner_vertices, inner_faces
        self.ior, self.walls, self.opt = ior, walls, opt
        self.targets = [np.asarray(t, np.float64) for t in targets]
        self.shapes = [t.shape for t in self.targets]
        self.limits = limits
        # The light whose pictures the loss compares with the targets: the LED, or its
        # beam from the ideal point.
        self.source = source
        # The black-filled slots (``slots.Slots``) that will end the light entering them
        # in the glass: the splat stops its photons there (the source's method ignores them).
        self.slots = slots
        self._scene_grid = None

    def gradient(self, heights: np.ndarray, views: list[int], seed: int, level: int = -1) -> tuple[float, np.ndarray]:
        """Loss over ``views`` and its gradient on the full-resolution nodes (nu, nv), for a
        step of ``level`` (-1: the finest)."""
        raise NotImplementedError

    def render(self, heights: np.ndarray, view: int, seed: int) -> np.ndarray:
        """A (rows, cols) preview of one wall."""
        raise NotImplementedError

    def render_all(self, heights: np.ndarray, seed: int) -> list[np.ndarray]:
        """``render`` of every wall: the optimizer's final picture."""
        return [self.render(heights, k, seed) for k in range(len(self.walls))]

    def preview_all(self, heights: np.ndarray, seed: int) -> list[np.ndarray]:
        """Pictures of every wall for the previews every few steps: ``render_all``
        unless a method can make them cheaper."""
        return self.render_all(heights, seed)

    def makeable(self, heights: np.ndarray) -> np.ndarray:
        """Project into what the fabrication profile allows (slopes, overhangs, hollows a
        ball-end tool reaches, offsets).

        Every step is projected exactly, so the steps that follow shape the image around
        what will be made.  Letting them exceed the slopes by 10° and projecting only the
        result undid much of the refinement: the horse's r 0.966-0.970 exact against
        0.946-0.958, the 3-axis milled apple's 0.920-0.938 against 0.855-0.873
        (bench/RESULTS.md)."""
        return self.limits.project(self.cyl, heights)

    # -- loop ---------------------------------------------------------------------
    def step_delta(self, state: State, grad: np.ndarray) -> np.ndarray:
        """The step on the level's grid (mm), by plain gradient descent or Adam.

        ``learning_rate`` is for the coarsest level; finer levels step in proportion to
        their node spacing times ``fine_level_rate``, so they tilt the surface by that
        fraction of the coarsest level's tilt per step, scaled down towards the end by
        ``anneal_factor``."""
        spacing = grad.shape[0] / (self.opt.grid_u // 4 ** (self.opt.levels - 1))
        level_rate = self.opt.fine_level_rate if spacing > 1 else 1.0
        lr = (self.opt.learning_rate * state.lr_scale * level_rate / spacing
              * anneal_factor(self.opt, state.step))
        if self.opt.update_rule == "gd":
            return -lr * grad
        b1, b2, eps = 0.9, 0.999, 1e-12
        state.adam_t += 1
        state.m = b1 * state.m + (1 - b1) * grad
        state.v = b2 * state.v + (1 - b2) * grad**2
        m_hat = state.m / (1 - b1**state.adam_t)
        v_hat = state.v / (1 - b2**state.adam_t)
        return -lr * m_hat / (np.sqrt(v_hat) + eps)

    def run(self, state: State, on_checkpoint, on_preview, progress, deadline: float | None = None) -> State:
        """Optimize from ``state`` to the end, calling ``on_checkpoint(state)`` every
        ``checkpoint_every`` steps and on SIGINT/SIGTERM (then raising Interrupted).
        With a ``deadline`` (time.time() seconds) it returns at the first step that
        ends past it (the benchmark's time budgets).

        A numerical fault (a NaN or Inf in the loss, the gradient or the new heights,
        or an exploding loss) is reported through ``progress`` with its step, and the
        run goes back to the last good checkpoint with the learning rate halved;
        NumericalFault after ``MAX_FALLBACKS`` halvings in a row.  With ``backtrack``, a
        step after which the loss rose by over ``RISE_TOLERANCE`` is taken again from
        the state before it with half the learning rate; each step kept grows the rate
        back by ``REGROWTH``, up to the profile's, and each level starts at it.  The
        heights stay a radial graph clipped to +-max_offset_mm, which the inner layer
        clears by ``tolerances.MIN_GAP_MM`` (checked when it is loaded), so a step cannot
        make the surface cross itself or the inner layer; the fabcheck stage measures the
        walls.
        """
        opt = self.opt
        grids = level_grids(opt)
        ends = np.cumsum(level_steps(opt))
        stop = {"signal": None}

        def handler(signum, _frame):
            stop["signal"] = signum

        old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
        good = state.copy()
        fallbacks = 0
        best: dict = {}
        level = None
        before = None  # with backtrack: (the state before the last step, its loss, its gradient)
        try:
            while state.step < opt.iterations:
                if stop["signal"] is not None:
                    on_checkpoint(state)
                    raise Interrupted(stop["signal"], state.step)
                if level != int(np.searchsorted(ends, state.step, side="right")):
                    level = int(np.searchsorted(ends, state.step, side="right"))
                    best = _best_losses(state.log, level)
                    if opt.backtrack and level > state.level:
                        state.lr_scale = 1.0  # a new grid: its own step length, found again
                grid = grids[level]
                _fit_moments(state, grid)
                state.level = level
                t0 = time.time()
                views = losses.views_for_step(opt.schedule, state.step, len(self.walls))
                key = views[0] if len(views) == 1 else -1
                loss, grad_full = self.gradient(state.heights, views, seed=opt.seed * 100_003 + state.step * 17,
                                                level=level)
                limits = self.limits
                penalty, penalty_grad = surface.slope_penalty(
                    self.cyl, state.heights, limits.max_slope_deg - PENALTY_MARGIN_DEG,
                    None if limits.max_overhang_deg is None else limits.max_overhang_deg - PENALTY_MARGIN_DEG)
                loss += opt.slope_weight * penalty
                grad_full = grad_full + opt.slope_weight * penalty_grad
                if limits.tool_radius_mm > 0:
                    penalty, penalty_grad = hollow_penalty(self.cyl, state.heights,
                                                           1.0 / (HOLLOW_PENALTY_MARGIN * limits.tool_radius_mm))
                    loss += opt.hollow_weight * penalty
                    grad_full = grad_full + opt.hollow_weight * penalty_grad
                grad = surface.sample_adjoint(self.cyl, grad_full, *grid)
                fault = _fault(loss, grad, best.get(key, math.inf))
                if fault is None and opt.backtrack:
                    if before is not None and loss > before[1] * (1.0 + RISE_TOLERANCE):
                        state = _step_back(state, before[0])
                        _fit_moments(state, grid)
                        grad = surface.sample_adjoint(self.cyl, before[2], *grid)
                    else:
                        before = (state.copy(), loss, grad_full)
                        state.lr_scale = min(1.0, state.lr_scale * REGROWTH)
                if fault is None:  # on a fault the state is replaced, moments included
                    delta = surface.sample(self.cyl, self.step_delta(state, grad), *grids[-1])
                    heights = self.makeable(state.heights + delta)
                    fault = None if np.all(np.isfinite(heights)) else "the new heights are not finite"
                if fault is not None:
                    fallbacks += 1
                    if fallbacks > MAX_FALLBACKS:
                        raise NumericalFault(
                            f"optimize: step {state.step}: {fault}, even after halving the learning rate "
                            f"{MAX_FALLBACKS} times from the checkpoint at step {good.step}; lower [optimize] "
                            f"learning_rate or check the target image")
                    lr_scale = state.lr_scale * 0.5
                    message = (f"{fault}; back to the last good checkpoint (step {good.step}) with the "
                               f"learning rate x{lr_scale:g}")
                    at = state.step
                    state = good.copy()
                    state.lr_scale = lr_scale
                    state.faults.append((at, lr_scale))
                    level, before = None, None
                    progress(state, loss, f"step {at}: {message}")
                    continue
                state.heights = heights
                best[key] = min(best.get(key, math.inf), loss)
                state.log.append((state.step, level, key, loss, time.time() - t0))
                state.step += 1
                progress(state, loss, "")
                if state.step % opt.preview_every == 0 or state.step == opt.iterations:
                    on_preview(state)
                if state.step % opt.checkpoint_every == 0:
                    on_checkpoint(state)
                    good = state.copy()
                    fallbacks = 0
                if deadline is not None and time.time() >= deadline:
                    return state
        finally:
            for s, h in old.items():
                signal.signal(s, h)
        return state


def _fit_moments(state: State, grid: tuple[int, int]) -> None:
    """Zero Adam's moments when they are not on ``grid`` (a new level starts afresh)."""
    if state.m is None or state.m.shape != grid:
        state.m, state.v, state.adam_t = np.zeros(grid), np.zeros(grid), 0


def _step_back(state: State, before: State) -> State:
    """``state``'s step overshot: the state ``before`` it (heights and moments), to step
    from again with half the learning rate, keeping ``state``'s step count and records."""
    back = before.copy()
    back.step, back.level, back.lr_scale = state.step, state.level, state.lr_scale * 0.5
    back.log, back.faults = list(state.log), list(state.faults)
    back.backtracks = state.backtracks + [(state.step, back.lr_scale)]
    return back


def _best_losses(log: list, level: int) -> dict:
    """The lowest loss per view key among the logged steps of ``level``."""
    best: dict = {}
    for row in log:
        if row[1] == level:
            best[row[2]] = min(best.get(row[2], math.inf), row[3])
    return best


def finite_vertex_gradient(grad: np.ndarray) -> np.ndarray:
    """(n, 3) per-vertex gradient with non-finite rows set to 0 when they are at most
    ``MAX_NONFINITE_VERTEX_SHARE`` of the vertices; otherwise unchanged (a fault)."""
    bad = ~np.isfinite(grad).all(axis=1)
    if not bad.any() or bad.mean() > MAX_NONFINITE_VERTEX_SHARE:
        return grad
    return np.where(bad[:, None], 0.0, grad)


def _fault(loss: float, grad: np.ndarray, best: float) -> str | None:
    """What is numerically wrong with a step's loss and gradient, or None."""
    if not np.isfinite(loss):
        return f"the loss is {loss}"
    if not np.all(np.isfinite(grad)):
        return f"the gradient has {int(np.sum(~np.isfinite(grad)))} NaN or Inf values"
    if loss > EXPLODE_FACTOR * best:
        return f"the loss exploded ({loss:.4g}, over {EXPLODE_FACTOR:g}x the best so far, {best:.4g})"
    return None


class PtracerOptimizer(Optimizer):
    """The source's method: Mitsuba ``ptracer`` renders one sensor per wall, Dr.Jit
    differentiates the loss with respect to the outer vertices."""

    # -- scene --------------------------------------------------------------------
    def _mesh(self, heights):
        return lens.optical_mesh(self.cyl, heights, self.opt.tessellation, self.inner_v, self.inner_f)

    def _ensure_scene(self, heights: np.ndarray) -> None:
        if self._scene_grid == heights.shape:
            return
        verts, faces = self._mesh(heights)
        self.scene, self.params, self.key = scene.build(verts, faces, self.source.position, self.ior, self.walls,
                                                        self.shapes, self.opt.spp)
        self.static = verts  # inner layer and cap centres never move
        self.fine = surface.fine_shape(*heights.shape, self.opt.tessellation)
        self.radial = surface.radial_dirs(*self.fine)
        self._scene_grid = heights.shape

    def _set_heights(self, heights: np.ndarray) -> None:
        mi = scene.mitsuba()
        verts, _ = self._mesh(heights)
        self.params[self.key] = mi.Float(verts.astype(np.float32).ravel())
        self.params.update()

    def render(self, heights: np.ndarray, view: int, seed: int, spp: int | None = None) -> np.ndarray:
        """A (rows, cols) float64 ptracer image of one wall, no gradient."""
        mi = scene.mitsuba()
        self._ensure_scene(heights)
        self._set_heights(heights)
        img = mi.render(self.scene, self.params, sensor=view, spp=spp or self.opt.spp, seed=seed)
        return np.array(img, dtype=np.float64)[..., 0]

    def gradient(self, heights: np.ndarray, views: list[int], seed: int, level: int = -1) -> tuple[float, np.ndarray]:
        """Loss over ``views`` and its gradient on the heightmap nodes (nu, nv); every
        level renders ``spp`` samples per pixel."""
        import drjit as dr

        mi = scene.mitsuba()
        self._ensure_scene(heights)
        self._set_heights(heights)
        positions = self.params[self.key]
        dr.enable_grad(positions)
        self.params.update()
        total = 0.0
        grad_vertices = np.zeros(dr.width(positions))
        weights = self.opt.loss_weights or (1.0,) * len(self.walls)
        for view in views:
            img = mi.render(self.scene, self.params, sensor=view, spp=self.opt.spp, seed=seed + view,
                            seed_grad=seed + view + 7919)
            target = mi.TensorXf(self.targets[view][..., None].astype(np.float32))
            loss = losses.view_loss(self.opt.loss, img, target, dr.mean, weights[view])
            dr.backward(loss)
            total += float(np.asarray(loss).ravel()[0])
            grad_vertices += dr.grad(positions).numpy()
            dr.clear_grad(positions)
        dr.disable_grad(positions)
        mu, mv = self.fine
        g = finite_vertex_gradient(grad_vertices.reshape(-1, 3))[: mu * mv]
        g_fine = np.einsum("ij,ij->i", g, self.radial).reshape(mu, mv)
        return total, surface.sample_adjoint(self.cyl, g_fine, *heights.shape)
