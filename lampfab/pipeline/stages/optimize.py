"""Stage 4, optimize: the first lens refined (heightmap.npz, loss.csv, previews/,
optimization.gif), or for a lens kind that does not refine (a panel) carried over."""

from __future__ import annotations

import json

import numpy as np

from ... import artifacts
from ...errors import LampfabError
from ...verify import SECOND_RENDER
from ..build import Build
from ..progress import log, steps_bar


def optimize(build: Build) -> dict:
    """Refine the first lens by gradient descent through a differentiable renderer
    (``splat``, or the source's ``ptracer``); resumes from a checkpoint."""
    if not build.kind.refines:
        return _carry_over(build)
    from ... import optimize as opt_mod
    from ... import pictures

    d, opt = build.design, build.design.optimize
    report = build.begin("optimize", {"init": build.init_file, **build.target_paths()})
    init_heights, limits = build.first_lens()
    # Planned on the first design; the solid stage plans them again on the refined one,
    # whose outer surface lies a little elsewhere.
    slots = build.kind.slots(build, init_heights)
    optimizer = build.optimizer(opt, build.inner(), build.targets(opt.sensor_px), limits, slots)
    checkpoint = build.checkpoint_file
    for written in (checkpoint, build.heightmap_file):
        artifacts.remove_stale_temps(written)
    state = opt_mod.State(init_heights.copy(), 0, 0)
    resumed = False
    if checkpoint.exists():
        saved = artifacts.read_npz(checkpoint)
        if str(saved.get("settings_hash", "")) == _settings_hash(build, init_heights):
            state = opt_mod.State.from_arrays(saved)
            resumed = True
            log(f"optimize: resuming from {checkpoint} at step {state.step}")

    def save(s):
        artifacts.write_npz(checkpoint, settings_hash=_settings_hash(build, init_heights), **s.to_arrays())

    def preview(s):
        for wall, img in zip(build.walls, optimizer.preview_all(s.heights, seed=opt.seed + 1)):
            artifacts.write_png(build.preview_picture(s.step, wall.name), img)

    bar = steps_bar(opt.iterations, "optimize", initial=state.step, disable=opt.iterations == 0)

    def progress(s, loss, message):
        bar.update(s.step - bar.n)
        bar.set_postfix(loss=f"{loss:.4f}", level=s.level)
        if message:
            bar.write(f"optimize: {message}")

    if state.step == 0 and opt.iterations:
        preview(state)
    try:
        state = optimizer.run(state, save, preview, progress)
    except opt_mod.Interrupted as exc:
        bar.close()
        raise LampfabError(f"optimize interrupted at step {exc.step}; checkpoint saved to {checkpoint}, "
                           f"run the same command again to resume") from None
    bar.close()
    heights = state.heights
    build.save_heights(heights, radius_mm=d.lens.outer_radius_mm, height_mm=d.lens.height_mm)
    # The optimizer's own picture of its result, with the light it designed for, twice
    # with other photons: verify compares the exported lens's picture with the same
    # light with them, and the two together say how much of a mismatch is their noise.
    renders = {}
    for suffix, seed in (("", opt.seed + 1), (SECOND_RENDER, opt.seed + 2)):
        renders.update({w.name + suffix: img for w, img in zip(build.walls, optimizer.render_all(heights, seed=seed))})
    artifacts.write_npz(build.optimizer_render_file, light=opt.design_light, **renders)
    steps = np.asarray(state.log).reshape(-1, 5)
    artifacts.write_csv(build.loss_file, steps, ["step", "level", "view", "loss", "seconds"],
                        ["%d", "%d", "%d", "%.6g", "%.3f"])
    frames = pictures.optimization_gif(build.previews_dir, [w.name for w in build.walls], build.gif_file)
    report.figure(steps=int(state.step), resumed=resumed, gif_frames=frames,
                  slots_stopping_light=None if slots is None else slots.to_json(),
                  numerical_faults=[{"step": int(a), "learning_rate_scale": b} for a, b in state.faults],
                  backtracks=[{"step": int(a), "learning_rate_scale": b} for a, b in state.backtracks],
                  final_loss=float(steps[-1, 3]) if len(steps) else None,
                  median_step_s=float(np.median(steps[:, 4])) if len(steps) else None,
                  offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()))
    report.write(build.report_file("optimize"))
    artifacts.remove(checkpoint)
    return report.data


def _carry_over(build: Build) -> dict:
    """No refinement: the first design is the lens (a panel's profile allows no steps)."""
    report = build.begin("optimize", {"init": build.init_file})
    heights, _ = build.first_lens()
    build.save_heights(heights)
    report.figure(steps=0, final_loss=None, note="a panel is designed by transport alone",
                  offset_min_mm=float(heights.min()), offset_max_mm=float(heights.max()))
    report.write(build.report_file("optimize"))
    return report.data


def _settings_hash(build: Build, init_heights: np.ndarray) -> str:
    """What a checkpoint must have been made with to be resumed: the settings, the first
    lens and the targets."""
    import hashlib

    h = hashlib.sha256(json.dumps(build.settings(), sort_keys=True).encode())
    h.update(np.ascontiguousarray(init_heights).tobytes())
    for p in build.target_paths().values():
        h.update(artifacts.file_sha256(p).encode())
    return h.hexdigest()
