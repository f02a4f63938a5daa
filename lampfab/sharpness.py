"""The LED's blur on the walls, measured by tracing: its size, its kernel, its reference.

A point light draws each wall's picture; a real LED draws that picture again from every
point of its emitting surface and the copies add up, a blur.  Each small patch of the
outer surface sees the LED under an angle of about its size over its distance, and
sends that bundle of directions on to the wall, widened or narrowed by how its own
facet bends the light.  So the blur depends on the emitter, the lens's size, the walls'
distance and the design itself, and it is measured here, never assumed.

The measurement: photons that leave the lens through the same cell of the outer
surface (a patch in angle u and height z) land together with the point light: the
cell's footprint.  With the LED they spread around it.  Per wall and cell,
``Moments`` accumulates the landings' count, mean and covariance (wall coordinates,
mm: ``right`` then ``down``); the cell's LED kernel is the covariance of its LED
landings minus that of its point landings (independent spreads add).  Only photons
never reflected inside the lens count: a ghost's path has no footprint to speak of.

The kernels' diameters are 4 standard deviations along the wall's width and height:
the diameter of a uniform disc, the LED's own picture through a patch.  A detail
smaller than that blurs into its neighbours.  ``blur`` applies them, cell by cell
where they land, to any image: verify blurs the target with the lens's own kernels (the
best a point-light design could show with this LED) and the point-light render (which
must come out as the LED render, a check of the kernels themselves).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .room import Wall

# Cells of the outer surface around and up, at most: at the default lens 1.1 mm by 1.5 mm
# of surface, whose point-light footprint on the wall (15-25 mm) is well under the LED's
# blur (60-100 mm), so the subtraction of footprints stays a small correction.
CELLS_U = 256
CELLS_Z = 64
# Fewer photons get fewer, larger cells: about this many photons per cell, so that the
# cells lighting a picture (half of them or more) pass ``MIN_CELL_PHOTONS``.
PHOTONS_PER_CELL = 250

# A cell's kernel needs this many photons of each light through it: the covariance of
# n samples has a relative standard error of about sqrt(2 / n), 20 % at 50.
MIN_CELL_PHOTONS = 50

# Kernels are spread over the wall's pixels by Gaussian-weighted averaging of the cells
# that land near each pixel, over this many pixels: the LED's blur (2-3 px at 64 px)
# changes over tens of pixels, the photon noise of single cells over one.
FIELD_BANDWIDTH_PX = 3.0

# The smallest kernel variance, in square pixels, a blur applies: a tenth of a pixel's
# width as its standard deviation keeps a degenerate kernel a delta, not a division by 0.
MIN_VARIANCE_PX2 = 0.01

# The diameter of the LED's picture through a patch, in standard deviations of its
# spread: 4 sigma is a uniform disc's diameter (sigma = d / 4).
DIAMETER_SIGMAS = 4.0

# ``blur`` spreads a pixel's light this many standard deviations out: what lies farther
# is under 4e-6 of it.
BLUR_TRUNCATE_SIGMAS = 5.0


class Cells:
    """The outer surface's cells: ``CELLS_U`` around (angle about the lamp axis) by
    ``CELLS_Z`` up, between heights ``z0_mm`` and ``z1_mm``."""

    def __init__(self, z0_mm: float, z1_mm: float, nu: int = CELLS_U, nz: int = CELLS_Z):
        self.z0, self.z1, self.nu, self.nz = float(z0_mm), float(z1_mm), nu, nz

    @staticmethod
    def for_photons(z0_mm: float, z1_mm: float, photons: int) -> "Cells":
        """As many cells as ``photons`` fill (``PHOTONS_PER_CELL``), four times as many
        around as up, at most ``CELLS_U`` x ``CELLS_Z``."""
        nz = int(np.clip(np.sqrt(photons / (4 * PHOTONS_PER_CELL)), 2, CELLS_Z))
        return Cells(z0_mm, z1_mm, 4 * nz, nz)

    @property
    def count(self) -> int:
        return self.nu * self.nz

    def of(self, points_mm: np.ndarray) -> np.ndarray:
        """(n,) int64 cell index of each exit point (n, 3) mm."""
        u = np.mod(np.arctan2(points_mm[:, 1], points_mm[:, 0]), 2 * np.pi) / (2 * np.pi)
        z = (points_mm[:, 2] - self.z0) / (self.z1 - self.z0)
        iu = np.clip((u * self.nu).astype(np.int64), 0, self.nu - 1)
        iz = np.clip((z * self.nz).astype(np.int64), 0, self.nz - 1)
        return iu * self.nz + iz


class Moments:
    """Per (wall, cell): count, sums and sums of products of the landings' wall
    coordinates (mm), accumulated batch by batch in numpy (a fixed order: a seed gives
    the same moments every time)."""

    def __init__(self, cells: Cells, n_walls: int):
        self.cells = cells
        self.size = cells.count * n_walls
        self.sums = np.zeros((6, self.size))  # n, x, y, xx, yy, xy

    def add(self, exits_mm: np.ndarray, wall: np.ndarray, xy_mm: np.ndarray) -> None:
        """Photons that left the lens at ``exits_mm`` (k, 3) and landed on ``wall``
        (k,) int at ``xy_mm`` (k, 2) (along the wall's right, then down)."""
        key = wall * self.cells.count + self.cells.of(exits_mm)
        x, y = xy_mm[:, 0], xy_mm[:, 1]
        for row, w in enumerate((None, x, y, x * x, y * y, x * y)):
            self.sums[row] += np.bincount(key, weights=w, minlength=self.size)

    def mean_cov(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(count (m,), mean (m, 2) mm, covariance (m, 3) mm^2 as xx, yy, xy); mean and
        covariance NaN where a cell got no photon."""
        n, x, y, xx, yy, xy = self.sums
        with np.errstate(invalid="ignore", divide="ignore"):
            mx, my = x / n, y / n
            cov = np.stack([xx / n - mx * mx, yy / n - my * my, xy / n - mx * my], 1)
        return n, np.stack([mx, my], 1), cov


@dataclass(frozen=True)
class Kernels:
    """The LED's kernel per (wall, cell) that both lights lit well enough.

    ``wall`` (k,) int, ``centre_mm`` (k, 2) where the cell's point light lands,
    ``cov_mm2`` (k, 3) kernel covariance (xx, yy, xy; positive semi-definite),
    ``weight`` (k,) the point light's photon count through the cell (its flux)."""
    wall: np.ndarray
    centre_mm: np.ndarray
    cov_mm2: np.ndarray
    weight: np.ndarray

    @staticmethod
    def of(point: Moments, led: Moments) -> "Kernels":
        n_p, mean_p, cov_p = point.mean_cov()
        n_l, _, cov_l = led.mean_cov()
        ok = (n_p >= MIN_CELL_PHOTONS) & (n_l >= MIN_CELL_PHOTONS)
        index = np.flatnonzero(ok)
        return Kernels(index // point.cells.count, mean_p[ok], _psd(cov_l[ok] - cov_p[ok]), n_p[ok])

    def on(self, k: int, wall: Wall) -> np.ndarray:
        """Indices of wall ``k``'s kernels whose cell lands inside its picture."""
        c = self.centre_mm
        return np.flatnonzero((self.wall == k) & (c[:, 0] >= 0) & (c[:, 0] < wall.width_mm)
                              & (c[:, 1] >= 0) & (c[:, 1] < wall.height_mm))

    def diameters_mm(self, k: int, wall: Wall, quantiles=(0.1, 0.5, 0.9)) -> dict:
        """The blur's diameter on wall ``k`` along its width and its height (mm), at
        ``quantiles`` of the picture's light: {"horizontal": [...], "vertical": [...]};
        None where no cell lands inside the picture."""
        sel = self.on(k, wall)
        if not len(sel):
            return {"horizontal": None, "vertical": None}
        w = self.weight[sel]
        return {axis: [_weighted_quantile(DIAMETER_SIGMAS * np.sqrt(self.cov_mm2[sel, i]), w, q) for q in quantiles]
                for i, axis in ((0, "horizontal"), (1, "vertical"))}

    def blur_figures(self, k: int, wall: Wall) -> dict | None:
        """plan's and verify's figures of wall ``k``'s blur: {"led_blur_mm": the median
        diameters {"horizontal", "vertical"}, "led_blur_range_mm": their 10-90 % range};
        None where no cell lands inside the picture."""
        d = self.diameters_mm(k, wall)
        if d["horizontal"] is None:
            return None
        return {"led_blur_mm": {axis: q[1] for axis, q in d.items()},
                "led_blur_range_mm": {axis: [q[0], q[2]] for axis, q in d.items()}}

    def field(self, k: int, wall: Wall, shape: tuple[int, int]) -> np.ndarray:
        """The kernel at each pixel of wall ``k``'s (rows, cols) picture: (rows, cols, 3)
        covariance (xx, yy, xy) in mm^2, the flux-weighted Gaussian average of the
        cells landing within ``FIELD_BANDWIDTH_PX`` of the pixel (their wall's mean
        where none lands near)."""
        rows, cols = shape
        sel = np.flatnonzero(self.wall == k)
        if not len(sel):
            raise ValueError(f"no LED kernel lands on the {wall.name} wall")
        c, cov, w = self.centre_mm[sel], self.cov_mm2[sel], self.weight[sel]
        px = c[:, 0] / wall.width_mm * cols - 0.5
        py = c[:, 1] / wall.height_mm * rows - 0.5
        mean = (w @ cov) / w.sum()
        out = np.empty((rows, cols, 3))
        xs = np.arange(cols)[:, None]
        # A vanishing weight of the wall's mean fills pixels no cell lands near.
        floor = 1e-9 * w.sum()
        for i in range(rows):
            g = np.exp(-((xs - px) ** 2 + (i - py) ** 2) / (2 * FIELD_BANDWIDTH_PX**2)) * w
            out[i] = (g @ cov + floor * mean) / (g.sum(1, keepdims=True) + floor)
        return out


def blur(image: np.ndarray, field_mm2: np.ndarray, wall: Wall) -> np.ndarray:
    """``image`` (rows, cols) on ``wall`` with each pixel's light spread by the
    Gaussian of its own kernel (``field_mm2`` (rows, cols, 3), ``Kernels.field``):
    (rows, cols) float64, the same total light less what spreads past the picture's
    edges (a lamp's light there lands on the wall outside the picture: lost to it)."""
    img = np.asarray(image, np.float64)
    rows, cols = img.shape
    sx, sy = wall.width_mm / cols, wall.height_mm / rows
    out = np.zeros((rows, cols))
    for (i, j), value in np.ndenumerate(img):
        if value == 0:
            continue
        a, b, c = field_mm2[i, j]
        cov = _psd_px(np.array([[a / sx**2, c / (sx * sy)], [c / (sx * sy), b / sy**2]]))
        inv = np.linalg.inv(cov)
        r = int(np.ceil(BLUR_TRUNCATE_SIGMAS * np.sqrt(np.linalg.eigvalsh(cov)[-1])))
        dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
        g = np.exp(-0.5 * (inv[0, 0] * dx * dx + 2 * inv[0, 1] * dx * dy + inv[1, 1] * dy * dy))
        g *= value / g.sum()
        top, bottom, left, right = max(i - r, 0), min(i + r + 1, rows), max(j - r, 0), min(j + r + 1, cols)
        out[top:bottom, left:right] += g[top - i + r:bottom - i + r, left - j + r:right - j + r]
    return out


def _psd(cov: np.ndarray) -> np.ndarray:
    """(k, 3) covariances (xx, yy, xy) with negative eigenvalues (noise of a kernel
    smaller than its footprint's spread) raised to 0."""
    m = np.stack([np.stack([cov[:, 0], cov[:, 2]], -1), np.stack([cov[:, 2], cov[:, 1]], -1)], 1)
    ev, vec = np.linalg.eigh(m)
    m = np.einsum("kij,kj,klj->kil", vec, np.maximum(ev, 0.0), vec)
    return np.stack([m[:, 0, 0], m[:, 1, 1], m[:, 0, 1]], 1)


def _psd_px(m: np.ndarray) -> np.ndarray:
    ev, vec = np.linalg.eigh(m)
    return (vec * np.maximum(ev, MIN_VARIANCE_PX2)) @ vec.T


def _weighted_quantile(x: np.ndarray, w: np.ndarray, q: float) -> float:
    order = np.argsort(x)
    cum = np.cumsum(w[order])
    return float(x[order][min(np.searchsorted(cum, q * cum[-1]), len(x) - 1)])
