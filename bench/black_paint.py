#!/usr/bin/env python3
"""What black paint on the faces that light no wall does to a made lens's pictures.

    .venv/bin/python bench/black_paint.py build/apple [build/horse ...]

Traces each build's exported STL with its LED as verify does (16 M photons, 64 px, the
same photons each time), once per ``black_paint`` choice: nothing painted, the flat top
and base, and those and the outer surface where no wall's sector lies (init's sectors).
Prints per wall the LED render's SSIM against the target and the share of the wall's
light that was reflected inside the lens at least once.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from lampfab import metrics, paint, trace, verify  # noqa: E402
from lampfab.profile import PAINTS  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("builds", nargs="+", type=Path, help="build folders holding design.json and init.json")
    parser.add_argument("--photons", type=float, default=16e6, help="photons per render (default: verify's 16 M)")
    args = parser.parse_args()
    for build in args.builds:
        loaded = verify.load(build / "design.json")
        sectors = json.loads((build / "init.json").read_text())["figures"].get("sectors_deg") or {
            w.name: w.sector_deg() for w in loaded.walls}
        back = paint.free_span_deg(sectors)
        print(f"\n{build} (the back: {'none' if back is None else f'u {back[0]:g} to {back[1] % 360:g} deg'}): "
              f"LED SSIM / light reflected inside the lens, per wall")
        print("| black paint | " + " | ".join(w.name for w in loaded.walls) + " |")
        print("|---|" + "---|" * len(loaded.walls))
        for choice in PAINTS:
            painted = paint.painted_faces(loaded.vertices, loaded.faces, choice, float(loaded.vertices[:, 2].max()),
                                          back)
            scene = trace.MeshScene(loaded.vertices, loaded.faces, painted)
            images, info = verify.render_design(verify.Loaded(**{**vars(loaded), "scene": scene}), 64,
                                                int(args.photons), 7, 8)
            cells = [f"{metrics.ssim(img, loaded.target(k, img.shape)):.3f} / "
                     f"{info['ghosts'][k].sum() / img.sum():.1%}" for k, img in enumerate(images)]
            print(f"| {choice} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
