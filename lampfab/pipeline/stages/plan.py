"""Stage 2, plan: where the plain lens's light falls, wall by wall (plan.json, plan/)."""

from __future__ import annotations

import numpy as np

from ... import artifacts, room
from ..build import Build
from ..progress import log


def plan(build: Build) -> dict:
    """The un-optimized lens in the room: where its light falls, wall by wall.

    Each wall plane is rendered three times larger than its target rectangle so the
    report shows light that would fall outside it.
    """
    from ... import trace

    d = build.design
    report = build.begin("plan", {})
    scene, emitter = build.kind.plain_optics(build)
    walls = build.walls
    big = [room.Wall(w.name, w.origin - w.right - w.down, 3 * w.right, 3 * w.down) for w in walls]
    px = d.verify.image_px
    shapes = [room.image_shape(w, 3 * px) for w in big]
    # A quarter of verify's photons: the shares and extents plan reports come out the same
    # to a tenth of a per cent.
    images, info = trace.render_walls(scene, build.source.point(), build.fab.ior, big, shapes,
                                      d.verify.photons // 4, d.optimize.seed, d.verify.max_bounces, emitter)
    figures = {"lost_share": info["lost"], "walls": {}}
    for wall, img in zip(walls, images):
        artifacts.write_png(build.plan_picture(wall.name), img)
        rows, cols = img.shape
        inside = img[rows // 3: 2 * rows // 3, cols // 3: 2 * cols // 3].sum()
        lit = np.argwhere(img > 0.05 * img.max())
        extent = {}
        if len(lit):
            (r0, c0), (r1, c1) = lit.min(0), lit.max(0)
            extent = {"left_mm": (c0 / cols * 3 - 1) * wall.width_mm, "right_mm": ((c1 + 1) / cols * 3 - 1) * wall.width_mm,
                      "top_mm": (r0 / rows * 3 - 1) * wall.height_mm, "bottom_mm": ((r1 + 1) / rows * 3 - 1) * wall.height_mm}
        figures["walls"][wall.name] = {
            "share_in_target": float(inside), "share_on_plane": float(img.sum()),
            "lit_extent_from_target_corner": extent,
            "target_mm": [wall.width_mm, wall.height_mm]}
        log(f"plan: {wall.name}: {inside:.1%} of the light inside the target rectangle, "
            f"{img.sum():.1%} on the wall plane")
    sharp = build.kind.sharpness_budget(build)
    if sharp is not None:
        _sharpness(figures, sharp)
    report.figure(**figures)
    report.write(build.report_file("plan"))
    return report.data


def _sharpness(figures: dict, sharp: dict) -> None:
    """The LED's blur into plan's figures (per wall and ``finest_detail_mm``) and its log."""
    figures["sharpness"] = sharp
    figures["finest_detail_mm"] = sharp["finest_detail_mm"]
    for name, w in sharp["walls"].items():
        figures["walls"][name]["led_blur_mm"] = w["led_blur_mm"]
        blur, px = w["led_blur_mm"], w["led_blur_px"]
        log(f"plan: {name}: the LED blurs {blur['horizontal']:.0f} x {blur['vertical']:.0f} mm (across x up; "
            f"{px['horizontal']:.1f} x {px['vertical']:.1f} px of the {sharp['design_px']} px picture): about "
            f"{w['resolvable_across']:.0f} details across")
    if sharp["halve"]:
        log(f"plan: {sharp['halve']}")
    for warning in sharp["warnings"]:
        log(f"plan: WARNING: {warning}")
    if sharp["finer_design"]:
        log("plan: this LED blurs less than a pixel: PROFILE=hires designs at 128 px and would show more")
