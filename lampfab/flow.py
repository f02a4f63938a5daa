"""Moving points so that their density approaches a target density on a grid.

A linearized Monge-Ampère step: the density difference d = rho - target (both scaled to
mean 1) is the divergence of the displacement u = grad(phi) whose Poisson equation
laplace(phi) = d is solved with a cosine transform (no flux through the grid's border),
so the points spread out of cells that hold too much and into cells that hold too little.
The displacement is a gradient field: curl-free, and smooth because the solve divides by
the squared frequency, so nearby points move alike and a smooth surface can follow.
Pure numpy/scipy.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import dctn, idctn
from scipy.ndimage import map_coordinates


def poisson_displacement(density: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first-order displacement (cells) that moves ``density`` onto ``target``.

    density, target: (w, h) non-negative masses on the same grid (normalized here).
    Returns ((w, h) along the first axis, (w, h) along the second), sampled at the cell
    centres.
    """
    w, h = density.shape
    difference = density / density.sum() * (w * h) - target / target.sum() * (w * h)
    # Eigenvalues of the 5-point Laplacian with reflecting borders, per DCT-II frequency.
    lam = (2 * np.cos(np.pi * np.arange(w) / w) - 2)[:, None] + (2 * np.cos(np.pi * np.arange(h) / h) - 2)[None, :]
    lam[0, 0] = 1.0  # the mean of phi is free: its coefficient is set to zero below
    spectrum = dctn(difference, type=2, norm="ortho") / lam
    spectrum[0, 0] = 0.0
    phi = idctn(spectrum, type=2, norm="ortho")
    return np.gradient(phi, axis=0), np.gradient(phi, axis=1)


def flow(x: np.ndarray, y: np.ndarray, target: np.ndarray, gain: float, substeps: int
         ) -> tuple[np.ndarray, np.ndarray]:
    """Points (x, y) in cell units of ``target`` (w, h) moved towards its density.

    ``substeps`` displacements of ``gain / substeps`` each, the density re-binned before
    each: the linearization holds only for small moves, and a gain under 1 leaves part
    of the way to later passes.  Points stay inside the grid.  Returns the new (x, y).
    """
    w, h = target.shape
    x, y = np.clip(x, 0.0, w - 1e-9), np.clip(y, 0.0, h - 1e-9)
    for _ in range(substeps):
        density, _, _ = np.histogram2d(x, y, bins=[w, h], range=[[0, w], [0, h]])
        ux, uy = poisson_displacement(density, target)
        at = [x - 0.5, y - 0.5]
        step_x = map_coordinates(ux, at, order=1, mode="nearest")
        step_y = map_coordinates(uy, at, order=1, mode="nearest")
        x = np.clip(x + gain / substeps * step_x, 0.0, w - 1e-9)
        y = np.clip(y + gain / substeps * step_y, 0.0, h - 1e-9)
    return x, y
