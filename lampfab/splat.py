"""The fast refinement (``splat``): differentiable photon splatting onto the walls.

The light inside the glass does not depend on the outer surface: each step's photons
leave the LED stratified over the sphere and are traced through the fixed inner layer
once.  The step then needs the facet each photon crosses on the outer mesh (found by
``facetwalk``, with no BVH to build again as the surface moves), Snell's law there, the
wall plane, and a splat into each wall's image (bilinear on a finer grid, summed per
pixel).  Every photon counts (no camera connection), and the photon set
is fixed for a step, so the objective has no Monte Carlo noise within a step.  Of the
Fresnel reflections only the cavity's are traced (``trace.into_glass``), since the outer
surface steers them onto the walls; verify traces them all.

Bit-reproducible: Dr.Jit computes only per-photon quantities (where a photon lands, and
its derivative with respect to the three corners of the facet it crossed).  Every sum
over photons, into pixels and into vertices, runs in numpy (``np.bincount``) in a fixed
order.  Dr.Jit's own ``scatter_add`` and the backward pass of a gather are atomic
float additions on many threads: their order, and so the last bits, change from run
to run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import facetwalk, losses, surface
from .optimize import Optimizer

# Photons are splatted bilinearly onto a grid this many times finer than the wall's image,
# then summed per pixel: nearly the photon count per pixel area, which is what verify
# bins.  A bilinear splat on the image's own pixels is a tent two pixels wide that hides
# pixel-scale ripple from the loss: on the apple (64 px) the optimizer's own render scored
# SSIM 0.75 where binning the same photons per pixel gave 0.65; at 4x the two agree to
# 0.01, and the refined lens gains SSIM 0.025 in verify at the same cost per step.
SUPERSAMPLE = 4

# One photon in this many also follows the light the cavity's wall reflects (about 4 %
# of it, see ``trace.into_glass``).  A quarter more photons: a step on the clock's fine
# grid took 1.0-1.1 s instead of 0.86 s, and its flat grey stays as smooth (SSIM 0.85
# on two walls).
CAVITY_REFLECTIONS_EVERY = 4


def photons_per_step(opt, level: int) -> int:
    """Photons a step of ``level`` (0: the coarsest, -1: the finest) traces:
    ``splat_photons``, times ``fine_level_photons`` above the coarsest level.

    The coarse level sets where the light goes and its grid averages the photons'
    noise over many of them; a fine node feels few, so each fine step writes their
    noise into the surface as ripple, which SSIM counts on flat areas and as haze on
    black.  Twice the photons on the fine level only lifted the silhouettes as much as
    twice on both levels, at about half the extra time (bench/RESULTS.md)."""
    finer = opt.levels > 1 and level != 0
    return round(opt.splat_photons * opt.fine_level_photons) if finer else opt.splat_photons


class SplatOptimizer(Optimizer):
    def _ensure_scene(self, heights: np.ndarray) -> None:
        if self._scene_grid == heights.shape:
            return
        from .mi_env import mitsuba
        from .trace import MeshScene

        self.mi = mitsuba()
        self.fine = surface.fine_shape(*heights.shape, self.opt.tessellation)
        self.faces = self.mi.UInt32(np.ascontiguousarray(surface.closed_outer_faces(*self.fine), np.uint32).ravel())
        self.radial = surface.radial_dirs(*self.fine)
        self.inner = MeshScene(self.inner_v, self.inner_f[:, ::-1])  # normals into the cavity
        self._photon_key = None
        self._scene_grid = heights.shape
        self._heights_set = None
        self._set_heights(heights)

    def _photons(self, seed: int, level: int) -> None:
        """Photons in the glass, after the inner layer, with their flux
        (``trace.into_glass``: refracted, and some reflected across the cavity); those
        headed into a black-filled slot carry none.

        They leave the ``source``: the ideal point, or the LED's emitting surface, so that
        the loss sees the blurred pictures the walls will really get.  Designing for the
        LED traded the point light's pictures for the LED's on every image measured
        (bench/RESULTS.md, "Designing for the LED").

        One per cell of an equal-area grid of directions, jittered afresh each step: a
        fixed set would let fine levels fit its noise.  Stratified, a pixel's photon count
        varies only through the cells its border cuts, not with the square root of the
        count as with independent directions, so each step writes less noise into the
        surface: the apple's pixel-to-pixel ripple fell from 5.4 % to 3.1 % and its SSIM
        from 0.53 to 0.55, and the coherent rays trace faster (bench/RESULTS.md)."""
        import drjit as dr

        from .fins import stopper
        from .trace import emit, into_glass

        count = photons_per_step(self.opt, level)
        if (seed, count) == self._photon_key:
            return
        mi = self.mi
        o, d = emit(mi, self.source, count, seed)
        self.n_photons = dr.width(d)
        self.o_glass, self.d_glass, self.w_glass = into_glass(mi, self.inner.scene, o, d, self.ior,
                                                              CAVITY_REFLECTIONS_EVERY, stopper(mi, self.source))
        if self.slots is not None:
            self.w_glass = dr.select(self.slots.stops(mi, self.o_glass, self.d_glass), 0.0, self.w_glass)
        dr.eval(self.o_glass, self.d_glass, self.w_glass)
        self._photon_key = (seed, count)

    def _set_heights(self, heights: np.ndarray) -> None:
        # A preview after a step traces the heights the next step starts from.
        if self._heights_set is not None and np.array_equal(heights, self._heights_set):
            return
        self._heights_set = heights.copy()
        verts = surface.closed_outer_vertices(self.cyl, heights, self.opt.tessellation)
        self.n_vertices = len(verts)
        self.positions = self.mi.Float(np.ascontiguousarray(verts, np.float32).ravel())
        # Where the facet walk starts: the mean radius of the surface.
        self.walk_radius_mm = self.cyl.radius_mm + float(heights.mean())

    def _landing(self, views: list[int], grad: bool):
        """Where each photon lands on each wall, in pixel units.

        Returns (corner vertex indices (k, 3) of the facet each of the k photons that
        met the outer surface crossed, the facet corners as Dr.Jit leaves (gradients
        enabled when ``grad``), the photons' flux weights (k,) float64, and per view
        (which (n,) int64 of the k photons land on or near the wall's picture, and their
        pixel coordinates x, y as Dr.Jit Floats (n,)).

        Each photon lands on one wall at most, so each view keeps about a third of them:
        chosen in Dr.Jit, only those come to numpy (converting and filtering every
        photon for every wall took a sixth of a fine step).  "Near": within a pixel of
        the picture, wider than ``_landed``'s exact bound, which decides in float64.
        """
        import drjit as dr

        from .trace import _take

        mi = self.mi
        positions = dr.unravel(mi.Point3f, self.positions)
        hit, settled = facetwalk.first_hits(mi, self.o_glass, self.d_glass, positions, *self.fine,
                                            self.cyl.height_mm, self.walk_radius_mm)
        # Photons of no weight (those that never reached the glass, reflections a fin
        # stopped) add nothing to a picture or a gradient.
        met = dr.compress(settled & (self.w_glass > 0))
        prim = dr.gather(mi.UInt32, hit, met)
        o = _take(mi.Point3f, self.o_glass, met)
        d = _take(mi.Vector3f, self.d_glass, met)
        weights = dr.gather(mi.Float, self.w_glass, met).numpy().astype(np.float64)
        # Corners gathered in Dr.Jit, not passed in from numpy: Dr.Jit uses numpy's
        # memory as it lies, and each alignment of each input compiles another kernel.
        index = [dr.gather(mi.UInt32, self.faces, prim * 3 + j) for j in range(3)]
        v = [_take(mi.Point3f, positions, i) for i in index]
        dr.eval(index, v)
        corners = np.stack([i.numpy() for i in index], 1).astype(np.int64)
        if grad:
            for corner in v:
                dr.enable_grad(corner)
        # The facet's plane and outward normal (the winding is outward), as Mitsuba's
        # geometric normal; the hit point moves with the facet along the fixed ray.
        normal = dr.cross(v[1] - v[0], v[2] - v[0])
        p = o + dr.dot(v[0] - o, normal) / dr.dot(d, normal) * d
        n = dr.normalize(normal)
        cos_i = dr.dot(d, n)  # leaving the glass along the outward normal
        eta = 1.0 / self.ior
        sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
        leaves = (sin2_t < 1.0) & (cos_i > 0)
        cos_t = dr.safe_sqrt(1.0 - sin2_t)
        out = dr.normalize(d / eta - (cos_i / eta - cos_t) * n)  # facing normal is -n
        per_view = []
        for view in views:
            wall = self.walls[view]
            rows, cols = self.shapes[view]
            normal_w = mi.Vector3f(*wall.normal.tolist())
            origin = mi.Point3f(*wall.origin.tolist())
            denom = dr.dot(out, normal_w)
            t = dr.dot(origin - p, normal_w) / denom
            rel = p + t * out - origin
            x = dr.dot(rel, mi.Vector3f(*wall.right.tolist())) / wall.width_mm**2 * cols - 0.5
            y = dr.dot(rel, mi.Vector3f(*wall.down.tolist())) / wall.height_mm**2 * rows - 0.5
            near = leaves & (denom < 0) & (t > 0) & (x > -1.5) & (x < cols + 0.5) & (y > -1.5) & (y < rows + 0.5)
            which = dr.compress(near)
            x, y = dr.gather(mi.Float, x, which), dr.gather(mi.Float, y, which)
            dr.eval(x, y)
            per_view.append((which.numpy().astype(np.int64), x, y))
        return corners, v, weights, per_view

    def _landed(self, x: np.ndarray, y: np.ndarray, view: int, weight) -> "_Landed":
        """The photons of flux ``weight`` ((n,) or one for all) near wall ``view``'s
        picture at pixel coordinates (x, y) (n,) float64, those that land on it placed on
        its splat grid: one ``SUPERSAMPLE`` times finer than the image, with a border of
        one cell on every side, so each photon's four bilinear corners fall inside it."""
        rows, cols = self.shapes[view]
        s = SUPERSAMPLE
        fine_rows, fine_cols = rows * s, cols * s
        xf, yf = (x + 0.5) * s - 0.5, (y + 0.5) * s - 0.5
        sel = np.flatnonzero((xf > -1) & (xf < fine_cols) & (yf > -1) & (yf < fine_rows))
        xf, yf = xf[sel], yf[sel]
        x0, y0 = np.floor(xf), np.floor(yf)
        fx, fy = xf - x0, yf - y0
        corner = (y0.astype(np.int64) + 1) * (fine_cols + 2) + x0.astype(np.int64) + 1
        return _Landed(sel, len(x), corner, fx, fy, np.broadcast_to(weight, x.shape)[sel], (rows, cols))

    @staticmethod
    def _image(landed: "_Landed") -> np.ndarray:
        """The (rows*cols,) float64 flux image: bilinear on the splat grid, summed over
        each pixel's sub-pixels (in numpy, in a fixed order)."""
        rows, cols = landed.shape
        s, width = SUPERSAMPLE, landed.width
        fx, fy, weight = landed.fx, landed.fy, landed.weight
        size = (rows * s + 2) * width
        image = np.zeros(size)
        for offset, w in ((0, (1 - fx) * (1 - fy)), (1, fx * (1 - fy)), (width, (1 - fx) * fy), (width + 1, fx * fy)):
            image += np.bincount(landed.corner + offset, weights=weight * w, minlength=size)
        image = image.reshape(rows * s + 2, width)[1:-1, 1:-1]
        return image.reshape(rows, s, cols, s).sum(axis=(1, 3)).ravel()

    @staticmethod
    def _image_adjoint(landed: "_Landed", grad_image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The loss's gradient per photon with respect to x and y, ((n,), (n,)) float64,
        from its gradient per pixel ``grad_image`` (rows*cols,)."""
        rows, cols = landed.shape
        s, width = SUPERSAMPLE, landed.width
        fx, fy = landed.fx, landed.fy
        # Each sub-pixel carries its pixel's gradient; the border carries none.
        per_cell = np.zeros((rows * s + 2, width))
        per_cell[1:-1, 1:-1] = np.repeat(np.repeat(grad_image.reshape(rows, cols), s, 0), s, 1)
        per_cell = per_cell.ravel()
        gx, gy = np.zeros(len(fx)), np.zeros(len(fx))
        for offset, dw_dx, dw_dy in ((0, -(1 - fy), -(1 - fx)), (1, 1 - fy, -fx),
                                     (width, -fy, 1 - fx), (width + 1, fy, fx)):
            g = landed.weight * per_cell[landed.corner + offset]
            gx += g * dw_dx
            gy += g * dw_dy
        out_x, out_y = np.zeros(landed.count), np.zeros(landed.count)
        out_x[landed.sel], out_y[landed.sel] = gx * s, gy * s  # d(xf)/dx = s
        return out_x, out_y

    def render(self, heights: np.ndarray, view: int, seed: int) -> np.ndarray:
        return self._render(heights, [view], seed)[0]

    def render_all(self, heights: np.ndarray, seed: int) -> list[np.ndarray]:
        return self._render(heights, list(range(len(self.walls))), seed)

    def preview_all(self, heights: np.ndarray, seed: int) -> list[np.ndarray]:
        # With the coarse level's photons: a preview only shows the steps' progress,
        # and the fine level's four times as many took 1.3 s a preview.
        return self._render(heights, list(range(len(self.walls))), seed, level=0)

    def _render(self, heights: np.ndarray, views: list[int], seed: int, level: int = -1) -> list[np.ndarray]:
        """(rows, cols) flux images of ``views``, from one trace of the photons of a
        step of ``level``."""
        self._ensure_scene(heights)
        self._photons(seed, level)
        self._set_heights(heights)
        _, _, weights, per_view = self._landing(views, grad=False)
        return [self._image(self._landed(_float64(x), _float64(y), view, weights[which] / self.n_photons))
                .reshape(self.shapes[view]) for view, (which, x, y) in zip(views, per_view)]

    def gradient(self, heights: np.ndarray, views: list[int], seed: int, level: int = -1) -> tuple[float, np.ndarray]:
        import drjit as dr

        self._ensure_scene(heights)
        self._photons(seed, level)
        self._set_heights(heights)
        corners, v, photon_weights, per_view = self._landing(views, grad=True)
        flux = photon_weights / self.n_photons
        weights = self.opt.loss_weights or (1.0,) * len(self.walls)
        total = 0.0
        surrogate = self.mi.Float(0.0)
        for view, (which, x, y) in zip(views, per_view):
            landed = self._landed(_float64(x), _float64(y), view, flux[which])
            image = self._image(landed).reshape(self.shapes[view])
            loss, grad_image = losses.view_loss_and_grad(self.opt.loss, image, self.targets[view], weights[view])
            total += loss
            gx, gy = self._image_adjoint(landed, grad_image.ravel())
            # Linear in x and y with the loss's slopes: its backward pass gives each
            # photon's facet corners their gradient, photon by photon (the adjoints of
            # the sum and of the gather above add nothing up: each photon is one term).
            surrogate = surrogate + dr.sum(_jit_float(self.mi, gx) * x + _jit_float(self.mi, gy) * y)
        dr.backward(surrogate)
        grads = [dr.grad(corner) for corner in v]
        dr.eval(grads)  # one kernel for all nine components
        grad_vertices = np.zeros((self.n_vertices, 3))
        for j, g in enumerate(grads):
            for c, component in enumerate((g.x, g.y, g.z)):
                grad_vertices[:, c] += np.bincount(corners[:, j], weights=component.numpy().astype(np.float64),
                                                   minlength=self.n_vertices)
        mu, mv = self.fine
        g_fine = np.einsum("ij,ij->i", grad_vertices[: mu * mv], self.radial).reshape(mu, mv)
        return total, surface.sample_adjoint(self.cyl, g_fine, *heights.shape)


@dataclass(frozen=True)
class _Landed:
    """Photons on one wall's splat grid (see ``SplatOptimizer._landed``)."""

    sel: np.ndarray  # (k,) int64: which of the photons near the wall these are
    count: int  # the photons near the wall
    corner: np.ndarray  # (k,) int64: each one's upper-left corner on the bordered grid
    fx: np.ndarray  # (k,) float64: where in that cell, 0-1 across
    fy: np.ndarray  # (k,) float64: and down
    weight: np.ndarray  # (k,) float64: its flux
    shape: tuple[int, int]  # the image's (rows, cols)

    @property
    def width(self) -> int:
        """The bordered grid's width."""
        return self.shape[1] * SUPERSAMPLE + 2


def _float64(values) -> np.ndarray:
    """A Dr.Jit Float as (n,) float64."""
    return values.numpy().astype(np.float64)


def _jit_float(mi, values: np.ndarray):
    """A Dr.Jit Float holding ``values``, from a 64-byte aligned float32 buffer.

    Dr.Jit uses numpy's memory as it lies and compiles one kernel per alignment of its
    inputs; aligned buffers keep it to one (a recompile costs more than a tiny step)."""
    buffer = np.empty(len(values) + 16, np.float32)
    start = (-buffer.ctypes.data % 64) // 4
    aligned = buffer[start: start + len(values)]
    aligned[:] = values
    return mi.Float(aligned)
