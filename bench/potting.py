#!/usr/bin/env python3
"""What potting the LED in clear silicone would change, measured on a made lens.

    .venv/bin/python bench/potting.py build/apple [build/horse ...] [--silicone-ior 1.41]

Potting fills the cavity around the LED with clear silicone: the LED shines into it,
and the inner layer's facets then part silicone from glass (relative index 1.51 / 1.41,
0.1 % reflected square on, against 4 % from air), so the cavity's reflections, a third
to a half of the light reflected inside the lens, are gone.  This script traces each
build's exported STL as verify does (16 M stratified photons, 64 px, the point light and
the LED, the kernels measured as verify measures them) twice: with the cavity empty (as
verify) and potted.  Per wall: the LED's blur (median, across x up), the light reflected
inside the lens, the target blurred by the LED (what a perfect point-light design would
show), the same with this lens's reflections and photon noise (what a perfect outer
surface would show), and the LED render's r and SSIM.

The lens is the one designed for an air-filled cavity; the silicone changes how the
cavity bends the light, so the last two columns score the air design in silicone, not
a potted design.  The blur, the reflections and the two "perfect" figures belong to the
geometry and the materials.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import metrics, verify  # noqa: E402

SILICONE_IOR = 1.41  # clear potting silicones (e.g. Sylgard 184) measure n 1.40-1.43 near 589 nm
EDGE_MM = 0.5  # a hit this close to the base's or the top's plane is on a flat face, not the cavity's


def cavity_ior(loaded: verify.Loaded, glass: float, filler: float):
    """``trace.propagate``'s ``ior(points, normals)``: ``glass / filler`` on the cavity's
    facets (hit points inside the inner layer's radius, between the base and the top),
    ``glass`` (in air) everywhere else."""
    import drjit as dr

    from lampfab.mi_env import mitsuba

    mi = mitsuba()
    v, f = loaded.vertices, loaded.faces
    centre = v[f].mean(1)
    normal = np.cross(v[f][:, 1] - v[f][:, 0], v[f][:, 2] - v[f][:, 0])
    radial = np.einsum("ij,ij->i", centre[:, :2], normal[:, :2])
    # The inner layer's facets face the axis; its widest point bounds the cavity.
    inner = f[radial < 0].ravel()
    cavity_mm = float(np.hypot(v[inner, 0], v[inner, 1]).max()) + EDGE_MM
    z0, z1 = float(v[:, 2].min()) + EDGE_MM, float(v[:, 2].max()) - EDGE_MM

    def ior(p, n):
        inside = (p.x * p.x + p.y * p.y < cavity_mm**2) & (p.z > z0) & (p.z < z1)
        return dr.select(inside, mi.Float(glass / filler), mi.Float(glass))
    return ior


def figures(loaded: verify.Loaded, ior, photons: int, seed: int) -> list[dict]:
    """Per wall: the LED's blur, the reflected share and the scores, traced as verify
    traces (``verify.render_both``) with ``ior`` (``trace.propagate``'s)."""
    point, _, led, led_info, kernels = verify.render_both(loaded, 64, photons, seed, 8, ior)
    out = []
    for k, wall in enumerate(loaded.walls):
        target = loaded.target(k, led[k].shape)
        ref = verify._led_reference(kernels, k, wall, target, point[k], led[k], led_info["ghosts"][k],
                                    led_info["direct_noise"][k], {})
        out.append({"wall": wall.name, "blur": ref["led_blur_mm"],
                    "reflected": float(led_info["ghosts"][k].sum() / led[k].sum()),
                    "reference_ssim": ref["led_reference_ssim"], "ceiling": ref["led_ssim_ceiling"],
                    "r": metrics.pearson(led[k], target), "ssim": metrics.ssim(led[k], target)})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json (make lamp's)")
    parser.add_argument("--photons", type=float, default=16e6, help="photons per light (default: verify's 16 M)")
    parser.add_argument("--silicone-ior", type=float, default=SILICONE_IOR, help="the potting's refractive index")
    args = parser.parse_args()
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        glass = float(loaded.design["material"]["ior"])
        print(f"\n{build}: glass n {glass:g}, silicone n {args.silicone_ior:g}, {args.photons / 1e6:g} M photons per light")
        print("| wall | cavity | LED blur (mm) | reflected inside the lens | the target blurred by the LED: SSIM "
              "| ... with this lens's reflections and noise | LED r / SSIM (the air design) |")
        print("|---|---|---|---|---|---|---|")
        for name, filler in (("air", 1.0), ("silicone", args.silicone_ior)):
            for f in figures(loaded, cavity_ior(loaded, glass, filler), int(args.photons), 7):
                print(f"| {f['wall']} | {name} | {f['blur']['horizontal']:.0f} x {f['blur']['vertical']:.0f} "
                      f"| {f['reflected']:.1%} | {f['reference_ssim']:.3f} | {f['ceiling']:.3f} "
                      f"| {f['r']:.3f} / {f['ssim']:.3f} |")


if __name__ == "__main__":
    main()
