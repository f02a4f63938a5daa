"""How much surface error the projection tolerates: perturb the outer layer, re-trace.

Finishing (sanding, polishing) and the process itself leave the outer surface off by
some tens of micrometres, unevenly.  The study adds a smooth random error field to the
heightmap at growing amplitudes, traces each perturbed lens with the verify tracer
(true facets, the same photons for every amplitude so differences come from the
surface, not from noise), and reports Pearson r against the targets.  The *allowance*
is the largest peak error at which no wall's r drops by more than ``R_DROP``.

The error field is a Gaussian random field on the heightmap's nodes with correlation
length ``CORRELATION_MM``, periodic around the lens, scaled so its largest magnitude is
1: an amplitude ``a`` moves the surface by at most ``a`` mm, in and out.  Errors finer
than the nodes (tool scallops, grit scratches) scatter light into haze rather than
move the image; this study does not model them.
"""

from __future__ import annotations

import numpy as np

from . import metrics, surface
from .room import Wall

# Uneven removal follows the tool that removes material: a hand-held sanding block or
# polishing pad touches ~5-10 mm at a time, so errors are correlated over ~5 mm.  Chosen,
# not sourced; smaller than one 90 deg sector's features (~70 mm wide) and larger than
# the nodes (~1 mm), so the heightmap can carry it.
CORRELATION_MM = 5.0

# A wall whose r falls by more than this has visibly lost contrast (r 0.95 -> 0.93 is
# about the gap between a draft and a default design in the README).  Chosen.
R_DROP = 0.02

# Peak errors tried (mm), from a fine polish (10 um) to a careless hand finish (0.5 mm);
# the profile's own surface error is added to them.
AMPLITUDES_MM = (0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5)


def error_field(cyl: surface.Cylinder, shape: tuple[int, int], correlation_mm: float, seed: int) -> np.ndarray:
    """(nu, nv) float64: a smooth random field on the heightmap nodes, max |field| = 1.

    Periodic in u; node spacings are the cylinder's (2 pi R / nu around, H / (nv - 1) up).
    """
    from scipy.ndimage import gaussian_filter

    nu, nv = shape
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((nu, nv))
    sigma = (correlation_mm / (2 * np.pi * cyl.radius_mm / nu), correlation_mm / (cyl.height_mm / (nv - 1)))
    field = gaussian_filter(noise, sigma, mode=("wrap", "reflect"))
    return field / np.abs(field).max()


def study(cyl: surface.Cylinder, heights: np.ndarray, lens_mesh, source, ior: float,
          walls: list[Wall], targets: list[np.ndarray], photons: int, seed: int, max_bounces: int,
          profile_error_mm: float) -> dict:
    """Trace the lens at each amplitude of one error field; r against each target.

    heights (nu, nv) mm; ``lens_mesh(heights)`` -> ((n, 3) mm, (m, 3) int): the closed lens
    to trace, wound outward (the made solid: its bore changes the ghosts); ``source`` the
    light to trace (a ``source.Source``: the LED's beam from a point, so that the study
    sees the surface's errors, not the LED's blur); targets: one (rows, cols) image per wall, the render's shape.
    Returns {"amplitudes_mm": [0, ...] (ascending), "walls": {name: [r per amplitude]},
    "max_drop": [largest r drop over the walls per amplitude], "allowance_mm": largest
    amplitude tried whose drop stays within R_DROP, "allowance_at_least": True when even
    the largest amplitude stays within it, "profile_error_mm", "profile_error_drop",
    "correlation_mm", "photons", "r_drop"}.
    """
    from . import trace

    amplitudes = sorted({0.0, *AMPLITUDES_MM, float(profile_error_mm)})
    field = error_field(cyl, heights.shape, CORRELATION_MM, seed)
    shapes = [t.shape for t in targets]
    per_wall = {w.name: [] for w in walls}
    for a in amplitudes:
        verts, faces = lens_mesh(heights + a * field)
        images, _ = trace.render_walls(trace.MeshScene(verts, faces), source, ior, walls, shapes,
                                       photons, seed, max_bounces)
        for wall, img, target in zip(walls, images, targets):
            per_wall[wall.name].append(metrics.pearson(img, target))
    r = np.array(list(per_wall.values()))                     # (walls, amplitudes)
    drop = (r[:, :1] - r).max(axis=0)
    ok = drop <= R_DROP
    # The allowance is the last amplitude before the first one that degrades.
    first_bad = int(np.argmin(ok)) if not ok.all() else len(amplitudes)
    k = amplitudes.index(float(profile_error_mm))
    return {"amplitudes_mm": amplitudes, "walls": per_wall, "max_drop": drop.tolist(),
            "allowance_mm": amplitudes[first_bad - 1], "allowance_at_least": bool(ok.all()),
            "profile_error_mm": float(profile_error_mm), "profile_error_drop": float(drop[k]),
            "correlation_mm": CORRELATION_MM, "photons": int(photons), "r_drop": R_DROP}
