"""The lines ``make lamp`` ends with: one per stage, its wall time and its key figure."""

from __future__ import annotations

from ..report import number, span
from .build import STAGES, Build

# Under this share of a perfect outer surface's LED SSIM (verify's ``led_ssim_ceiling``)
# on some wall, the summary names the longer refinement: #26's bar for silhouettes,
# which the horse passes with ``fine`` (0.91-0.93) and misses with the default (0.85-0.88).
LONGER_REFINEMENT_BELOW = 0.9


def summary(build: Build) -> None:
    """One line per finished stage, then the total and where report.html is."""
    total = 0.0
    for stage in STAGES:
        data = build.stage_report(stage)
        if data is None:
            continue
        total += data.get("wall_time_s", 0.0)
        print(f"{stage:9s} {data.get('wall_time_s', 0):7.1f} s  {_key_figure(stage, data['figures'])}")
    print(f"{'total':9s} {total:7.1f} s  -> {build.report_html}")
    verified = build.stage_report("verify")
    hint = _longer_refinement(build, verified["figures"]) if verified else None
    if hint:
        print(hint)


def _longer_refinement(build: Build, figs: dict) -> str | None:
    """A line naming the ``fine`` profile when a wall falls short of what a perfect outer
    surface would show and ``fine`` is this build's design refined longer (the default's:
    a floor, 128 px walls or a maker's slots would be lost by switching)."""
    import dataclasses

    from .. import profile

    shares = [w["led_ssim"] / w["led_ssim_ceiling"] for w in figs["walls"].values() if w.get("led_ssim_ceiling")]
    fine, opt = profile.load_design("fine"), build.design.optimize
    longer = dataclasses.replace(build.design, name=fine.name, path=fine.path, optimize=dataclasses.replace(
        opt, iterations=fine.optimize.iterations, fine_level_photons=fine.optimize.fine_level_photons))
    if (not shares or min(shares) >= LONGER_REFINEMENT_BELOW or longer != fine
            or opt.iterations >= fine.optimize.iterations):
        return None
    return (f"sharper: the walls reach {span(shares)} of a perfect outer surface's SSIM; "
            f"PROFILE=fine refines {fine.optimize.iterations} steps instead of {opt.iterations}, "
            f"about two and a half times as long: often closer, not on every picture (docs/results.md)")


def _key_figure(stage: str, figs: dict) -> str:
    """A stage's headline, in words."""
    if stage == "prepare":
        # A phrase's own line breaks would break the summary's one line per stage.
        sources = {k[:-len("_source")]: str(v).replace("\n", " / ") for k, v in figs.items() if k.endswith("_source")}
        return "; ".join(f"{v} on {', '.join(w for w in sources if sources[w] == v)}"
                         for v in dict.fromkeys(sources.values()))
    if stage == "plan":
        line = f"{1 - figs['lost_share']:.0%} of the light on the wall planes"
        sharp = figs.get("sharpness")
        if sharp and sharp["walls"]:
            h = max(w["led_blur_mm"]["horizontal"] for w in sharp["walls"].values())
            v = max(w["led_blur_mm"]["vertical"] for w in sharp["walls"].values())
            line += f"; LED blur up to {h:.0f} x {v:.0f} mm, finest detail {sharp['finest_detail_mm']:.0f} mm"
            if sharp["warnings"]:
                line += f" ({len(sharp['warnings'])} warning{'s' * (len(sharp['warnings']) > 1)}: see plan.json)"
        return line
    if stage == "init":
        tilt, limit = figs.get("max_tilt_deg"), figs.get("slope_limit_deg")
        return (figs["method"] + (f", max tilt {tilt:.1f}°" if tilt is not None else "")
                + (f" (slopes up to {limit:g}°)" if limit is not None else ""))
    if stage == "optimize":
        loss = figs.get("final_loss")
        return f"{figs['steps']} steps" + (f", final loss {loss:.3g}" if loss is not None else "")
    if stage == "solid":
        slots = figs.get("slots")
        return (f"{figs['volume_mm3'] / 1000:.0f} cm³, {figs['triangles']} triangles"
                + (f", {len(slots['slots'])} slots to fill black" if slots else ""))
    if stage == "fabcheck":
        from ..checks import CheckResult, failed

        names = [r.name for r in failed([CheckResult.from_json(c) for c in figs["checks"]])]
        return f"FAILED: {', '.join(names)}" if names else "all checks pass"
    if stage == "export":
        return (f"lens.stl {figs['stl_bytes'] / 1e6:.1f} MB, lens.step {figs['step_bytes'] / 1e6:.1f} MB, "
                f"B-spline within {figs['bspline_deviation_mm'] * 1000:.2g} µm"
                + (", fins.stl" if "fins_stl_bytes" in figs else ""))
    empty = [f["led_ssim_slots_empty"] for f in figs["walls"].values() if "led_ssim_slots_empty" in f]
    return (", ".join(f"{n} r {f['led_pearson']:.2f} SSIM {f['led_ssim']:.2f}"
                      + (f" {f['led_words_read']}/{f['words']} words read" if "words" in f else "")
                      for n, f in figs["walls"].items()) + f" with the {figs['real_light']}"
            + (f"; slots left empty: SSIM {span(empty, lambda v: number(v, 2))}" if empty else ""))
