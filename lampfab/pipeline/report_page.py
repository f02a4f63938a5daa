"""report.html: the page verify ends with, assembled from the stage reports, verify's
renders and the page's own pictures (``report`` writes the HTML)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import artifacts
from .build import Build

if TYPE_CHECKING:
    from ..verify import Loaded

_NEXT_STEPS_BLENDER = (
    "<p>For a beauty render, import <code>lens.glb</code> into Blender (File › Import › glTF): it arrives "
    "at its real size with a glass material of the same refractive index. <code>design.json</code> gives "
    "the light and the walls in the same frame.</p>")


def pictures(build: Build, loaded: Loaded) -> dict:
    """The report's own pictures of ``build``'s design (``loaded``: ``verify.load``'s):
    the lamp in its room, the lens close up as glass and as a matte object, the unrolled
    heightmap.  Returns their paths by name (room, closeup, lens, heightmap)."""
    from .. import beauty, verify

    v = build.design.verify
    design, vertices, faces = loaded.design, loaded.vertices, loaded.faces
    walls = loaded.walls
    paths = {name: build.report_picture(name) for name in ("room", "closeup", "lens", "heightmap")}
    around = beauty.room_walls(walls)
    # A quarter of verify's photons: shown at the room picture's scale, the walls' photon
    # grain stays under a grey level, and the trace takes 4 s instead of 13.
    light = verify.room_light(loaded, around, beauty.ROOM_WALL_SCALE * v.image_px, v.photons // 4,
                              build.design.optimize.seed + 13)
    floor_z = float(build.light[2]) - build.design.room.floor_depth_mm
    room_view, close = beauty.room_pictures(vertices, faces, loaded.painted, build.fab.ior,
                                            build.kind.report_light(build, design),
                                            around, light, floor_z, v.scene_px, v.scene_spp,
                                            build.design.optimize.seed)
    artifacts.write_png(paths["room"], room_view, normalize=False)
    artifacts.write_png(paths["closeup"], close, normalize=False)
    artifacts.write_png(paths["lens"], beauty.bumpy_lens(vertices, faces, v.scene_px // 2, 4), normalize=False)
    build.kind.heightmap_picture(build, [w.name for w in walls], paths["heightmap"])
    return paths


def write(build: Build, figures: dict, pics: dict) -> None:
    """report.html from verify's ``figures`` and the report's ``pics`` (``pictures``)."""
    from .. import report
    from ..checks import CheckResult

    plan = (build.stage_report("plan") or {}).get("figures", {})
    checks_report = build.checks_report()
    checks = [CheckResult.from_json(c) for c in checks_report["figures"]["checks"]] if checks_report else []
    text, tone = verdict(build, figures, checks, plan.get("sharpness", {}).get("sharper_led"))
    room_picture, lens_pictures = build.kind.report_pictures(build, pics)
    sections = [("The lens", '<div class="row">' + "".join(report.figure(p) for p in lens_pictures) + "</div>")]
    if plan.get("sharpness"):
        sections.append(("Sharpness: what the LED allows", _sharpness_html(plan["sharpness"], figures)))
    if checks:
        sections.append((f"Fabrication checks ({build.fab.name})", _checks_html(build, checks)))
    if "guidance" in figures:
        from .. import guidance

        sections.append(("Finishing and tolerances", guidance.html(figures["guidance"], figures["tolerance"])))
    if build.gif_file.exists():
        sections.append(("Optimization", report.figure_html(
            "The walls during optimization", build.gif_file, "one frame per preview step (loss per step: loss.csv)")))
    sections.append(("Next steps", build.kind.next_steps(build) + _NEXT_STEPS_BLENDER))
    report.write_report(build.report_html, f"lampfab: {build.out.name}", text, tone=tone, hero=room_picture,
                        facts=_facts(build, figures, plan, checks), walls=_walls(build, figures),
                        groups=_groups(build, figures, plan), sections=sections)


# A wall's picture "looks like the image" from this Pearson r of the LED's render on: every
# photograph and silhouette measured reaches 0.96-0.99 with the default LED; the four-word
# text, whose letters the LED's blur runs together, 0.91-0.93.
WELL_R = 0.95
# Below this the picture is hard to recognise (the tiny test lens of 16 px, with two steps,
# sits at 0.7-0.9).
RECOGNISABLE_R = 0.85


def verdict(build: Build, figures: dict, checks: list, sharper_led: dict | None = None) -> tuple[str, str]:
    """The report's one line: does it project well, does it pass, what to send where;
    and its tone ("good", "warn", "bad").  ``sharper_led``: plan's LED that would show
    the picture's detail (``budget._sharper_led``)."""
    from .budget import DETAIL_SSIM

    walls = figures["walls"]
    r = min(w["led_pearson"] for w in walls.values())
    light = figures["real_light"]
    # The target blurred by this lens's own LED kernels: under DETAIL_SSIM the picture
    # holds detail no design can show with this LED, however well its r reads.
    reference = min((w["led_reference_ssim"] for w in walls.values() if "led_reference_ssim" in w), default=1.0)
    if r >= WELL_R and reference < DETAIL_SSIM:
        instead = f" (LED={sharper_led['name']} would show it)" if sharper_led and sharper_led["enough"] else ""
        look, tone = (f"Projects your picture with the real {light} (r {r:.2f} or better on every wall), but "
                      f"soft: it holds detail finer than this LED can show{instead}"), "warn"
    elif r >= WELL_R:
        look, tone = f"Projects your picture well with the real {light} (r {r:.2f} or better on every wall)", "good"
    elif r >= RECOGNISABLE_R:
        look, tone = (f"Projects your picture recognisably but softened by the {light}'s blur (r {r:.2f} on its "
                      f"weakest wall)"), "warn"
    else:
        look, tone = f"Projects your picture poorly (r {r:.2f} on its weakest wall)", "bad"
    read = [w for w in walls.values() if "words" in w]
    if read:
        look += (f"; OCR reads {sum(w['led_words_read'] for w in read)} of its {sum(w['words'] for w in read)} "
                 f"words on the walls ({sum(w['target_words_read'] for w in read)} in the sharp targets)")
    failed = [c.name for c in checks if c.failed]
    if failed:
        return f"{look}, but fails the {', '.join(failed)} check for {build.fab.name}: see below.", "bad"
    send = "send lens.stl to your printer's slicer" if build.fab.process == "sla" else \
        "send lens.step to the CNC shop"
    passes = f"passes all {sum(c.applies for c in checks)} checks for {build.fab.name}" if checks else "was not checked"
    return f"{look}, and {passes}: {send}.", tone


def _facts(build: Build, figures: dict, plan: dict, checks: list) -> list[tuple[str, str]]:
    from ..report import span

    walls = figures["walls"].values()
    out = [("What you will see (LED)", f"r {span([w['led_pearson'] for w in walls], _two)}, "
                                       f"SSIM {span([w['led_ssim'] for w in walls], _two)}")]
    read = [w for w in walls if "words" in w]
    if read:
        out.append(("Words read back by OCR (LED)", ", ".join(f"{w['led_words_read']}/{w['words']}" for w in read)
                    + " on the walls with words; in the sharp targets "
                    + ", ".join(f"{w['target_words_read']}/{w['words']}" for w in read)))
    blur = [w["led_blur_mm"] for w in walls if "led_blur_mm" in w]
    if blur:
        px = build.design.verify.image_px
        worst = max(max(b.values()) for b in blur)
        out.append(("Sharpness", f"details under ~{worst:.0f} mm blur together "
                                 f"({worst / (build.walls[0].width_mm / px):.1f} px of the {px} px picture)"))
    if checks:
        failed = sum(c.failed for c in checks)
        applies = sum(c.applies for c in checks)
        out.append(("Fabrication", f"{applies - failed} of {applies} checks pass ({build.fab.name})"))
    mitsuba = [w["mitsuba_pearson"] for w in walls if "mitsuba_pearson" in w]
    if mitsuba:
        out.append(("Second opinion", f"Mitsuba's light tracer agrees: r {span(mitsuba)}"))
    lux = _lux(build, figures)
    if lux:
        out.append(("Brightness", lux))
    return out


def _walls(build: Build, figures: dict) -> list:
    """Per wall: the target, the point light's picture, the LED's, Mitsuba's."""
    from ..report import Picture, number, percent
    from ..verify import mitsuba_file

    out = []
    light = figures["real_light"]
    for name, f in figures["walls"].items():
        point_png, led_png, _ = build.verify_pictures(name)
        led_figs = [("r", number(f["led_pearson"])), ("SSIM", number(f["led_ssim"])),
                    ("light", percent(f["led_share"]))]
        if "led_ssim_ceiling" in f:
            led_figs.append(("a perfect design's SSIM", number(f["led_ssim_ceiling"])))
        if f.get("led_contrast_ratio"):
            led_figs.append(("contrast on black", f"{f['led_contrast_ratio']:.0f}:1"))
        if "words" in f:
            led_figs.append(("words read by OCR", f"{f['led_words_read']}/{f['words']}"))
        pictures = [
            Picture("Target", build.target_preview(name)),
            Picture(f"With the {light} (what you will see)", led_png, led_figs),
            Picture("With an ideal point light", point_png,
                    [("r", number(f["pearson"])), ("SSIM", number(f["ssim"])), ("light", percent(f["share"])),
                     ("reflected", percent(f["ghost_share"]))])]
        if "mitsuba_pearson" in f:
            pictures.append(Picture(f"Mitsuba's light tracer ({light})", mitsuba_file(build.verify_dir, name),
                                    [("r against lampfab's", number(f["mitsuba_pearson"]))]))
        out.append((name, pictures))
    return out


def _groups(build: Build, figures: dict, plan: dict) -> dict:
    """The key figures by group, with human labels and units."""
    from ..report import number, percent, span

    walls = list(figures["walls"].values())
    light = [("Light on each picture (LED)", span([w["led_share"] for w in walls], percent)),
             ("Reflected inside the lens (Fresnel)", span([w["ghost_share"] for w in walls], percent)),
             ("Missing every wall", percent(figures["lost_share"]))]
    dark = [w for w in walls if w.get("led_contrast_ratio")]
    if dark:
        light += [("Contrast on the picture's black (LED: bright over black)",
                   span([w["led_contrast_ratio"] for w in dark], lambda x: f"{x:.0f}:1")),
                  ("LED light falling on the black", span([w["led_black_share"] for w in dark], percent))]
    lux = _lux(build, figures)
    if lux:
        light.append(("Brightness", lux))
    sharp = []
    if any("led_blur_mm" in w for w in walls):
        sharp += [("LED", f"{build.led.name}: {build.led.part}"),
                  ("Blur across the wall (median)", span([w["led_blur_mm"]["horizontal"] for w in walls], _mm)),
                  ("Blur up the wall (median)", span([w["led_blur_mm"]["vertical"] for w in walls], _mm)),
                  ("SSIM of the target blurred by it (a perfect design, no reflections)",
                   span([w["led_reference_ssim"] for w in walls])),
                  ("... with this lens's reflections and verify's photon noise (a perfect outer surface)",
                   span([w["led_ssim_ceiling"] for w in walls])),
                  ("SSIM that verify's photon noise takes off (a lamp has none)",
                   span([w["led_ssim_photon_noise"] for w in walls])),
                  ("Blur model against the LED render (r)", span([w["led_kernel_pearson"] for w in walls]))]
    agree = []
    if any("optimizer_pearson" in w for w in walls):
        agree.append(("verify against the optimizer's own render (r)",
                      span([w.get("optimizer_pearson") for w in walls])))
    if any("mitsuba_pearson" in w for w in walls):
        agree += [("Mitsuba's light tracer against verify, LED (r)", span([w["mitsuba_pearson"] for w in walls])),
                  ("... point light (r)", span([w["mitsuba_point_pearson"] for w in walls]))]
    geometry, fab, time = [], [], []
    solid, export = build.stage_report("solid"), build.stage_report("export")
    if solid:
        geometry += [("Volume of glass", f"{solid['figures']['volume_mm3'] / 1000:.0f} cm³"),
                     ("Triangles", f"{solid['figures']['triangles']:,}")]
        slots = solid["figures"].get("slots")
        if slots:
            geometry.append(("Slots in the base, to fill with black epoxy",
                             f"{len(slots['slots'])}, {slots['width_mm']:g} mm wide, {slots['top_mm']:g} mm deep"))
    if export:
        e = export["figures"]
        geometry += [("lens.stl", f"{e['stl_bytes'] / 1e6:.1f} MB"), ("lens.step", f"{e['step_bytes'] / 1e6:.1f} MB"),
                     ("STEP's B-spline from the heightmap", f"within {e['bspline_deviation_mm'] * 1000:.2g} µm")]
        if "fins_stl_bytes" in e:
            geometry.append(("fins.stl (print in black)", f"{e['fins_stl_bytes'] / 1e3:.0f} kB"))
    fab += [("Material", f"{build.fab.material} (n = {build.fab.ior})"),
            ("Bore through the base", f"{2 * build.fab.mount_radius_mm:g} mm across")]
    init = (build.stage_report("init") or {}).get("figures", {})
    if "slope_limit_deg" in init:
        limit, preferred = init["slope_limit_deg"], build.limits.max_slope_deg
        fab.append(("Slopes of the outer surface", f"up to {limit:g}°" + (
            f", past the {preferred:g}° the profile prefers: the light could not land under it"
            if limit > preferred else "")))
    if "tolerance" in figures:
        t = figures["tolerance"]
        fab.append(("Polishing allowance", f"{'at least ' if t['allowance_at_least'] else ''}"
                                           f"{t['allowance_mm'] * 1000:.0f} µm"))
    total = 0.0
    for stage in ("prepare", "plan", "init", "optimize", "solid", "fabcheck", "export", "verify"):
        data = build.stage_report(stage)
        if data:
            total += data["wall_time_s"]
            time.append((stage, f"{data['wall_time_s']:.1f} s"))
    if time:
        time.append(("all stages", f"{total / 60:.1f} min"))
    return {"Light": light, "Sharpness": sharp, "Renderers agree": agree,
            "Geometry": geometry, "Fabrication": fab, "Time": time}


def _sharpness_html(sharp: dict, figures: dict) -> str:
    """plan's budget: the blur per wall, what would halve it, its warnings."""
    import html

    rows = "".join(
        f"<tr><td>{html.escape(name)}</td><td>{w['led_blur_mm']['horizontal']:.0f} × {w['led_blur_mm']['vertical']:.0f}"
        f" mm</td><td>{w['led_blur_px']['horizontal']:.1f} × {w['led_blur_px']['vertical']:.1f} px</td>"
        f"<td>{w['resolvable_across']:.0f}</td></tr>" for name, w in sharp["walls"].items())
    warnings = "".join(f'<p class="warn">{html.escape(w)}</p>' for w in sharp["warnings"])
    # Which way the light leaves decides where a lens can send it (README, The LED).
    traced = {"cylinder": "a rod standing on the lamp's axis, shining all round",
              "disc": "a flat emitter facing up the lamp's axis, as a package on its board shines: brightest "
                      "straight up, nothing below the horizon",
              "post": "flat emitters on a post on the lamp's axis, one facing each wall, as packages on their "
                      "boards shine: brightest straight out, level" + (", black fins between them keeping each to "
                      "its wall's part of the lens" if sharp["led"].get("fin_radius_mm") else ""),
              "sphere": "a ball shining evenly in every direction (an LED in an opal ball; a bare LED on its "
                        "board would light only the top of each picture)"}[sharp["led"]["shape"]]
    return (f"<p>The LED ({html.escape(sharp['led']['part'])}) is not a point: every picture is drawn again from "
            f"each point of its surface, a blur. lampfab traces it as {traced}. plan measured the blur before the "
            f"long stages on a quick design of this image:</p><table><tr><th>wall</th><th>blur across × up</th>"
            f"<th>in the {sharp['design_px']} px picture</th><th>details across</th></tr>{rows}</table>"
            f"<p>{html.escape(sharp['halve'])}.</p>{warnings}")


def _checks_html(build: Build, checks: list) -> str:
    from .. import report
    from ..checks.result import short

    rows = "".join(
        f"<tr><td>{r.name}</td><td class=\"{'ok' if r.passed else 'fail'}\">{'pass' if r.passed else 'FAIL'}</td>"
        f"<td>{short(r.value)} {r.unit}</td><td>{short(r.limit)}</td></tr>" for r in checks if r.applies)
    picture = report.figure_html("Checks on the unrolled lens", build.checks_picture, "red: where a check fails") \
        if build.checks_picture.exists() else ""
    return f"<table><tr><th>check</th><th>result</th><th>value</th><th>limit</th></tr>{rows}</table>{picture}"


def _lux(build: Build, figures: dict) -> str:
    """How bright the pictures are with the LED profile's flux: mean illuminance of a
    picture, lumen over square metres."""
    if figures["real_light"].startswith("beam"):
        return ""
    from ..report import span

    lux = [build.led.flux_lm * figures["walls"][w.name]["led_share"] / (w.width_mm * w.height_mm / 1e6)
           for w in build.walls]
    return f"about {span(lux, lambda v: f'{v:.0f}')} lux over each picture, from the LED's {build.led.flux_lm:g} lm"


def _two(value) -> str:
    return f"{value:.2f}"


def _mm(value) -> str:
    return f"{value:.0f} mm"
