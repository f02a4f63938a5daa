"""The fast refinement (``splat``): differentiable photon splatting onto the walls.

The light inside the glass does not depend on the outer surface: photons are traced
from the LED through the fixed inner layer once.  Each step then needs a single
differentiable intersection with the outer mesh (Mitsuba's ``ray_intersect``, whose hit
point and facet normal carry Dr.Jit gradients of the vertices), Snell's law, the
wall plane, and a bilinear splat into each wall's image.  Every photon counts (no
camera connection), and the photon set is fixed, so the objective has no Monte Carlo
noise from step to step.  Fresnel reflections are left out of the gradient; verify
traces them.
"""

from __future__ import annotations

import numpy as np

from . import losses, surface
from .optimize import Optimizer


class SplatOptimizer(Optimizer):
    def _ensure_scene(self, heights: np.ndarray) -> None:
        if self._scene_grid == heights.shape:
            return
        from .trace import MeshScene

        verts, faces = surface.closed_outer_mesh(self.cyl, heights, self.opt.tessellation)
        self.outer = MeshScene(verts, faces)
        mi = self.mi = self.outer.mi
        self.params = mi.traverse(self.outer.scene)
        self.key = "lens.vertex_positions"
        self.fine = surface.fine_shape(*heights.shape, self.opt.tessellation)
        self.radial = surface.radial_dirs(*self.fine)
        self.inner = MeshScene(self.inner_v, self.inner_f[:, ::-1])  # normals into the cavity
        self._photon_seed = None
        self._scene_grid = heights.shape

    def _photons(self, seed: int) -> None:
        """Photons in the glass, after the inner layer (refracted, never reflected).

        A new set per step: a fixed set would let fine levels fit its noise."""
        import drjit as dr

        from .trace import emit, refract_or_reflect

        if seed == self._photon_seed:
            return
        mi = self.mi
        n = self.opt.splat_photons
        rng = mi.PCG32(n, dr.opaque(mi.UInt64, seed), dr.opaque(mi.UInt64, 0))
        o, d = emit(mi, self.light, 0.0, n, rng)
        si = self.inner.scene.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
        d = refract_or_reflect(mi, d, si.n, self.ior, dr.full(mi.Float, 1.0, n))
        self.o_glass = si.p + 1e-3 * d
        self.d_glass = d
        dr.eval(self.o_glass, self.d_glass)
        self._photon_seed = seed

    def _set_heights(self, heights: np.ndarray) -> None:
        verts, _ = surface.closed_outer_mesh(self.cyl, heights, self.opt.tessellation)
        self.params[self.key] = self.mi.Float(verts.astype(np.float32).ravel())
        self.params.update()

    def _images(self, views: list[int]):
        """Differentiable flux images of the given walls (Dr.Jit Float, row-major)."""
        import drjit as dr

        mi = self.mi
        si = self.outer.scene.ray_intersect(mi.Ray3f(self.o_glass, self.d_glass), mi.RayFlags.All, False)
        n = si.n
        d = self.d_glass
        cos_i = dr.dot(d, n)  # leaving the glass along the outward normal
        eta = 1.0 / self.ior
        sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
        ok = si.is_valid() & (sin2_t < 1.0) & (cos_i > 0)
        cos_t = dr.safe_sqrt(1.0 - sin2_t)
        out = dr.normalize(d / eta - (cos_i / eta - cos_t) * n)  # facing normal is -n
        p = si.p
        weight = 1.0 / self.opt.splat_photons
        images = []
        for view in views:
            wall = self.walls[view]
            rows, cols = self.shapes[view]
            normal = mi.Vector3f(*wall.normal.tolist())
            denom = dr.dot(out, normal)
            t = dr.dot(mi.Point3f(*wall.origin.tolist()) - p, normal) / denom
            rel = p + t * out - mi.Point3f(*wall.origin.tolist())
            x = dr.dot(rel, mi.Vector3f(*wall.right.tolist())) / wall.width_mm**2 * cols - 0.5
            y = dr.dot(rel, mi.Vector3f(*wall.down.tolist())) / wall.height_mm**2 * rows - 0.5
            hit = ok & (denom < 0) & (t > 0) & (x > -1) & (x < cols) & (y > -1) & (y < rows)
            x0, y0 = dr.floor(x), dr.floor(y)
            fx, fy = x - x0, y - y0
            image = dr.zeros(mi.Float, rows * cols)
            for dx, dy, w in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)),
                              (0, 1, (1 - fx) * fy), (1, 1, fx * fy)):
                cx, cy = mi.Int32(x0) + dx, mi.Int32(y0) + dy
                inside = hit & (cx >= 0) & (cx < cols) & (cy >= 0) & (cy < rows)
                dr.scatter_add(image, weight * w, mi.UInt32(cy * cols + cx), inside)
            images.append(image)
        return images

    def render(self, heights: np.ndarray, view: int, seed: int) -> np.ndarray:
        self._ensure_scene(heights)
        self._photons(seed)
        self._set_heights(heights)
        image = self._images([view])[0]
        return image.numpy().astype(np.float64).reshape(self.shapes[view])

    def gradient(self, heights: np.ndarray, views: list[int], seed: int) -> tuple[float, np.ndarray]:
        import drjit as dr

        self._ensure_scene(heights)
        self._photons(seed)
        mi = self.mi
        self._set_heights(heights)
        positions = self.params[self.key]
        dr.enable_grad(positions)
        self.params.update()
        weights = self.opt.loss_weights or (1.0,) * len(self.walls)
        total = mi.Float(0.0)
        for view, image in zip(views, self._images(views)):
            target = mi.Float(self.targets[view].ravel().astype(np.float32))
            total += losses.view_loss(self.opt.loss, image, target, dr.mean, weights[view])
        dr.backward(total)
        grad = dr.grad(positions).numpy().astype(np.float64)
        dr.disable_grad(positions)
        mu, mv = self.fine
        g = grad.reshape(-1, 3)[: mu * mv]
        g_fine = np.einsum("ij,ij->i", g, self.radial).reshape(mu, mv)
        return float(total.numpy()[0]), surface.sample_adjoint(g_fine, *heights.shape)
