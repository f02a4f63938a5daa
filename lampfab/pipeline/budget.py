"""The sharpness budget plan reports before the long stages: how much the LED will blur
each wall's picture, what would halve it, and whether the picture holds finer detail.

The blur depends on the design, not only on the emitter (``sharpness``): a lens that
spreads a sector's light over its whole height sees the LED smaller from its top and
bottom than the plain cylinder does from its middle.  So plan designs this very image
on a coarse grid (a few seconds; its blur came within 1-2 mm of the finished lens's on
the apple and the text), builds that lens and traces the point light and the LED through
it (``sharpness.Kernels``).

What halves the blur follows from the optics, not a second trace: to first order the blur
is proportional to the emitter's size, and scaling the whole lens by s with the walls
where they are scales every angle the LED subtends, and so the blur, by 1/s.  Moving the
walls closer shrinks the blur in millimetres but not in the picture's pixels, which
shrink with the walls.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import metrics, ocr, profile, room, sharpness

# The coarse design: nodes around and up, photons, fitting rounds, correction passes.
# 64 x 17 nodes took 7 s on 2 cores and gave the apple's finished blur within 1 mm
# (58 x 81 mm against 58 x 80); 128 x 33 took 16 s for the same figures.
COARSE_GRID = (64, 17)
COARSE_PHOTONS = 100_000
COARSE_ROUNDS = 2

# Photons traced through the coarse lens, for each of the two lights: ~100 per surface
# cell that lights a picture, enough for its kernel (sharpness.MIN_CELL_PHOTONS).
BUDGET_PHOTONS = 2_000_000

# Below this SSIM of the target against itself blurred by the LED, the picture holds
# detail the lamp cannot show and plan says so.  The bundled pictures and scikit-image's
# photographs score 0.88-0.99 at 64 px with the default LED; a picture of thin lines or
# specks (a star field, a page of text) scores lower and looks soft on the wall.
DETAIL_SSIM = 0.85

# Text reads while the blur (4 sigma) stays under this share of the letters' size (their
# em): it then still leaves the gaps inside and between strokes.  Measured with
# bench/text_blur.py (Tesseract on 16 phrases' targets blurred by Gaussians): 15 of 16
# read whole up to 0.3 em, 6 at 0.4, none at 0.5.  A lamp's blur is no Gaussian and
# comes with haze and photon noise: four-word lamps whose blur was 0.27-0.29 em read 44
# of their 48 words, so plan warns a little before 0.3.
TEXT_BLUR_EM = 0.25

# The outer share of a picture's width, on each side, where the LED's blur has grown:
# the sides lie farther from the lamp and are met obliquely, and on "Dream big little
# star"'s lens the blur there was a third wider than in the middle (78-82 x 108-109 mm
# against 62-64 x 80-84 mm).  A line of text reaching them smears its first and last
# letters (bench/log/2026-12-06.md).
SIDE_SHARE = 0.125

# plan recommends the 128 px profile (hires) when the LED's blur is under this many pixels
# of a coarser design: a finer design would then show detail the LED does not blur away.
FINER_DESIGN_BLUR_PX = 1.0
FINER_DESIGN_PX = 128

# A flat LED facing up lights the lens from below; above a quarter of the lens's height
# its weakest light (near the horizon) is left for the pictures' lower parts: the apple
# at 45 of 90 mm r 0.88-0.90, SSIM 0.26-0.29; at 15 mm (a sixth, the best measured) 0.96,
# 0.38-0.40 (bench/log 12-06).
FLAT_UP_MAX_HEIGHT = 0.25
FLAT_UP_HEIGHT = 1 / 6


def measure(build) -> dict:
    """The LED's blur on each wall of a coarse design of ``build``'s image (a
    ``build.Build``; the lens kind imports this module, and the build imports the kind):
    figures for plan.json."""
    from .. import trace

    opt = build.design.optimize
    coarse = dataclasses.replace(opt, grid_u=COARSE_GRID[0], grid_v=COARSE_GRID[1], transport_photons=COARSE_PHOTONS,
                                 transport_rounds=COARSE_ROUNDS, transport_corrections=0)
    heights, design = build.transport_design(coarse, build.inner(), log=lambda _msg: None)
    lens = build.kind.solid_maker(build)(heights)
    scene = trace.MeshScene(lens.vertices, lens.faces)
    cells = sharpness.Cells.for_photons(0.0, build.design.lens.height_mm, BUDGET_PHOTONS)
    shapes = [room.image_shape(w, opt.sensor_px) for w in build.walls]
    moments = []
    for k, source in enumerate((build.source.point(), build.source)):
        m = sharpness.Moments(cells, len(build.walls))
        trace.render_walls(scene, source, build.fab.ior, build.walls, shapes, BUDGET_PHOTONS,
                           opt.seed + 101 + k, build.design.verify.max_bounces, kernel_moments=m)
        moments.append(m)
    kernels = sharpness.Kernels.of(*moments)
    return summarize(build, kernels, design["bands"])


def summarize(build, kernels: sharpness.Kernels, bands: dict | None = None) -> dict:
    """plan.json's sharpness figures from the LED's ``kernels`` on a design of this build,
    whose transport chose ``bands`` ({wall: ``transport.band_shares``' figures})."""
    px = build.design.optimize.sensor_px
    targets = build.targets(px)
    texts = build.texts_to_read()
    walls, worst, soft, text_fields = {}, [], [], {}
    for k, (wall, target) in enumerate(zip(build.walls, targets)):
        blur = kernels.blur_figures(k, wall)
        if blur is None:
            continue
        median = blur["led_blur_mm"]
        field = kernels.field(k, wall, target.shape)
        blurred = sharpness.blur(target, field, wall)
        walls[wall.name] = {
            **blur, "led_blur_px": {axis: mm / (wall.width_mm / px) for axis, mm in median.items()},
            "resolvable_across": wall.width_mm / median["horizontal"],
            "detail_ssim": metrics.ssim(blurred, target)}
        if walls[wall.name]["detail_ssim"] < DETAIL_SSIM:
            soft.append((wall, target, field))
        if wall.name in texts:
            # The sharp target's reading too: a word the reader misses there is its own
            # limit, not the LED's.
            walls[wall.name].update(words=len(ocr.words(texts[wall.name])),
                                    target_words_read=ocr.words_read(target, texts[wall.name]),
                                    perfect_words_read=ocr.words_read(blurred, texts[wall.name]),
                                    text_sides=_text_sides(texts[wall.name], target, field))
            text_fields[wall.name] = (wall, target, field, texts[wall.name])
        worst.append(max(median.values()))
    figures = {"design_px": px, "led": profile.as_dict(build.led), "walls": walls,
               "finest_detail_mm": float(np.median(worst)) if worst else None}
    figures["halve"] = _halve(build, walls)
    figures["sharper_led"] = _sharper_led(build, soft)
    unreadable = _unreadable(build, walls)
    figures["text_led"] = _text_led(build, walls, unreadable, text_fields)
    figures["bands"] = bands or {}
    figures["warnings"] = (_warnings(build, walls, figures["sharper_led"], unreadable, figures["text_led"])
                           + _out_of_reach(build, figures["bands"]))
    blur_px = max((max(w["led_blur_px"].values()) for w in walls.values()), default=None)
    figures["finer_design"] = bool(blur_px is not None and blur_px < FINER_DESIGN_BLUR_PX and px < FINER_DESIGN_PX)
    return figures


def _sharper_led(build, soft: list) -> dict | None:
    """The largest bundled LED of the build's shape, smaller than its own, with which every wall
    in ``soft`` ((wall, target, kernel field) of the walls whose detail the LED blurs
    away) would keep its detail (``DETAIL_SSIM``), or else the smallest one; None when no
    wall is soft or the build's LED is a filament (its length makes another blur).
    Returns {"name", "radius_mm", "detail_ssim": {wall: SSIM}, "enough": bool}.

    """
    if not soft or build.led.shape == "cylinder":
        return None
    smaller = [o for o in _alike(build.led, build.led.radius_mm) if o.radius_mm < build.led.radius_mm]
    found = None
    for led in smaller:
        scores = {wall.name: metrics.ssim(sharpness.blur(target, _scaled(build, led, field), wall), target)
                  for wall, target, field in soft}
        found = {"name": led.name, "radius_mm": led.radius_mm, "detail_ssim": scores,
                 "enough": min(scores.values()) >= DETAIL_SSIM}
        if found["enough"]:
            break
    return found


def _scaled(build, led: profile.Led, field):
    """The build's LED's kernel ``field`` as ``led`` would draw it: kernels scale with the
    emitter's size, as in ``_halve``, their covariances by the square of the radii's ratio."""
    return field * (led.radius_mm / build.led.radius_mm) ** 2


def _halve(build, walls: dict) -> str:
    """One line: what would halve the blur of this design, with the figure each gives."""
    if not walls:
        return ""
    h = float(np.median([w["led_blur_mm"]["horizontal"] for w in walls.values()]))
    v = float(np.median([w["led_blur_mm"]["vertical"] for w in walls.values()]))
    led, lens = build.led, build.design.lens
    if led.shape == "cylinder":  # a filament's length makes the blur up the wall
        emitter = f"a filament half as long ({led.length_mm / 2:g} mm: {v / 2:.0f} mm up the wall)"
    else:
        smaller = next(iter(_alike(led, led.radius_mm / 2)), None)
        if smaller:
            s = smaller.radius_mm / led.radius_mm
            emitter = (f"an LED at most half as wide (LED={smaller.name}, {smaller.radius_mm:g} mm radius: "
                       f"{h * s:.0f} x {v * s:.0f} mm)")
        else:
            emitter = f"an LED half as wide ({led.radius_mm / 2:g} mm radius: {h / 2:.0f} x {v / 2:.0f} mm)"
    return (f"LED blur {h:.0f} x {v:.0f} mm (across x up). To halve it: {emitter}, or a lens twice as large "
            f"({2 * lens.outer_radius_mm:g} mm radius, {2 * lens.height_mm:g} mm tall: {h / 2:.0f} x {v / 2:.0f} mm); "
            f"walls half as far halve it in mm, not in pixels (the pictures shrink with them)")


def _unreadable(build, walls: dict) -> list[tuple[str, float, float]]:
    """(wall, blur mm, em mm) of the text walls whose LED blur is over ``TEXT_BLUR_EM``
    of the letters' size."""
    from .. import targets

    out = []
    texts = build.wall_texts()
    for wall in build.walls:
        if wall.name not in texts or wall.name not in walls:
            continue
        rows, cols = room.image_shape(wall, build.design.optimize.sensor_px)
        em_mm = targets.text_layout(texts[wall.name], rows, cols)[0] * wall.width_mm / cols
        blur = max(walls[wall.name]["led_blur_mm"].values())
        if blur > TEXT_BLUR_EM * em_mm:
            out.append((wall.name, blur, em_mm))
    return out


def _text_sides(text: str, target: np.ndarray, field_mm2: np.ndarray) -> dict | None:
    """The lines of ``text``, set on ``target`` ((rows, cols)), whose letters reach the
    picture's outer ``SIDE_SHARE`` on either side, with the LED's blur on their letters
    there and on the rest of the text (``field_mm2``: ``Kernels.field``'s (rows, cols, 3)):
    {"lines": [...], "side_blur_mm", "middle_blur_mm": the median over those letters'
    pixels of the kernel's diameter along its larger axis}; None when no line reaches them."""
    from .. import targets

    rows, cols = target.shape
    edge = max(1, int(round(SIDE_SHARE * cols)))
    side = np.zeros(cols, bool)
    side[:edge] = side[cols - edge:] = True
    ink = target > 0.5
    reaching = [line for first, end, line in targets.text_lines(text, rows, cols) if (ink[first:end] & side).any()]
    if not reaching or not (ink & ~side).any():
        return None
    diameter = sharpness.DIAMETER_SIGMAS * np.sqrt(np.maximum(field_mm2[..., 0], field_mm2[..., 1]))
    return {"lines": reaching, "side_blur_mm": float(np.median(diameter[ink & side])),
            "middle_blur_mm": float(np.median(diameter[ink & ~side]))}


def _text_led(build, walls: dict, unreadable: list, text_fields: dict) -> dict | None:
    """The bundled LED of the build's shape to name for the ``unreadable`` walls' text: of those
    whose blur stays under ``TEXT_BLUR_EM`` there, the largest with which a perfect lens
    would show every word the sharp target shows (Tesseract on the target blurred by its
    kernels, on the walls of ``text_fields`` OCR ran on), or else the one that shows the
    most.  Returns {"max_radius_mm": the largest radius under the limit, "name" and
    "radius_mm": the LED's (None when no bundled LED is that small),
    "perfect_words_read": {wall: words}}; None when every wall's text reads."""
    if not unreadable:
        return None
    largest = min(TEXT_BLUR_EM * em / blur for _, blur, em in unreadable) * build.led.radius_mm
    found = {"max_radius_mm": largest, "name": None, "radius_mm": None, "perfect_words_read": {}}
    names = {name for name, _, _ in unreadable}
    best = None
    for led in _alike(build.led, largest):
        read = {name: ocr.words_read(sharpness.blur(target, _scaled(build, led, field), wall), text)
                for name, (wall, target, field, text) in text_fields.items() if name in names}
        if best is None or sum(read.values()) > sum(best[1].values()):
            best = (led, read)
        if all(k >= walls[name]["target_words_read"] for name, k in read.items()):
            best = (led, read)
            break
    if best is not None:
        found.update(name=best[0].name, radius_mm=best[0].radius_mm, perfect_words_read=best[1])
    return found


def _warnings(build, walls: dict, sharper: dict | None, unreadable: list, text_led: dict | None) -> list[str]:
    """What the maker should know before the long stages (warnings, not errors);
    ``sharper``: ``_sharper_led``'s finding; ``unreadable`` and ``text_led``:
    ``_unreadable``'s and ``_text_led``'s."""
    out = []
    soft = [f"{name} {w['detail_ssim']:.3f}" for name, w in walls.items() if w["detail_ssim"] < DETAIL_SSIM]
    if soft:
        if sharper is None:
            advice = "choose a smaller LED"
        else:
            scores = sharper["detail_ssim"].values()
            figure = f"{min(scores):.3f}" + (f"-{max(scores):.3f}" if len(scores) > 1 else "")
            led = f"LED={sharper['name']} ({sharper['radius_mm']:g} mm radius)"
            advice = (f"choose {led}, with which it would score {figure}" if sharper["enough"] else
                      f"even the smallest bundled LED, {led}, would leave it at {figure}")
        out.append(f"the picture holds detail finer than this LED can show: blurred by it, it scores SSIM "
                   f"{', '.join(soft)} against itself (below {DETAIL_SSIM}); expect it soft, or {advice}")
    if unreadable:
        names, blurs, ems = zip(*unreadable)
        if text_led["name"]:
            led = f"LED={text_led['name']} ({text_led['radius_mm']:g} mm radius)"
            read = text_led["perfect_words_read"]
            if read:  # OCR ran on those walls
                led += (", with which a perfect lens would show " +
                        ", ".join(f"{n} {read[n]}/{walls[n]['words']}" for n in read))
        else:
            led = f"an LED of at most {text_led['max_radius_mm']:.2g} mm radius"
        short = [f"{name} {w['perfect_words_read']}/{w['words']} (sharp {w['target_words_read']}/{w['words']})"
                 for name, w in ((n, walls[n]) for n in names)
                 if w.get("perfect_words_read", 0) < w.get("target_words_read", 0)]
        if short:
            evidence = (f"; even a perfect lens would show OCR only {', '.join(short)} words (the target blurred "
                        f"by this LED)")
        elif all("perfect_words_read" in walls[n] and walls[n]["perfect_words_read"] == walls[n]["words"]
                 for n in names):  # OCR ran on every such wall and read every word
            evidence = "; blurred by this LED the target still reads whole, so expect most words to read"
        else:
            evidence = ""
        out.append(f"the text may not read whole with this LED on the {', '.join(names)} wall{'s' * (len(names) > 1)}: "
                   f"its blur ({min(blurs):.0f}-{max(blurs):.0f} mm) is over {TEXT_BLUR_EM:g} of the letters' size "
                   f"({min(ems):.0f} mm){_at_the_sides(walls, names)}{evidence}; use fewer words, or {led}")
    return out + _mounting(build)


def _out_of_reach(build, bands: dict) -> list[str]:
    """A warning for the walls whose picture's light sits higher in its frame than the
    lens can lift its lower light: their band below grew (``transport.band_shares``'
    ``lifted``), and that light glows below the picture."""
    high = [name for name, b in bands.items() if b["lifted"]]
    if not high:
        return []
    place = (f"the {', '.join(high)} pictures' light sits high in their frames" if len(high) > 1
             else f"the {high[0]} picture's light sits high in its frame")
    glow = [bands[name]["above"] + bands[name]["below"] for name in high]
    share = f"{min(glow):.0%}" + (f"-{max(glow):.0%}" if max(glow) - min(glow) > 0.005 else "")
    return [f"{place}: lifting the lens's lower light that high would bend it more than "
            f"{bands[high[0]]['reach_deg']:.0f}°, farther than its flanks can, so {share} of the light goes to glows "
            f"beside the picture, most of it below, rather than onto its black (a picture that fills its frame: "
            f"{build.design.optimize.dump_share:.0%}), and "
            f"the picture is that much dimmer; to keep more light in it, move its light nearer the frame's middle "
            f"(pad the image above, or crop it below)"]


def _at_the_sides(walls: dict, names) -> str:
    """The clause of the text warning on lines that reach the pictures' sides of the
    walls ``names``, where the blur is wider than on the rest of the text ("" if none)."""
    sides = [walls[n]["text_sides"] for n in names if walls[n].get("text_sides")]
    sides = [s for s in sides if s["side_blur_mm"] > s["middle_blur_mm"]]
    if not sides:
        return ""
    lines = list(dict.fromkeys(line for s in sides for line in s["lines"]))
    quoted = " and ".join('"' + line + '"' for line in lines)
    which = f"the line {quoted} reaches" if len(lines) == 1 else f"the lines {quoted} reach"
    blur = [s["side_blur_mm"] for s in sides]
    return (f", and {min(blur):.0f}-{max(blur):.0f} mm where {which} the walls' sides (the first and last letters "
            f"smear first; a line break keeps a line off the sides)")


def _mounting(build) -> list[str]:
    """Warnings for a flat LED facing up where it serves the pictures badly."""
    if not build.source.facing_up:
        return []
    out, lens = [], build.design.lens
    if build.fab.process in ("cnc3", "cnc4"):
        out.append(f"a milled lens cannot bend the light of a flat LED facing up (LED={build.led.name}) down onto "
                   f"the walls: its slopes and tool radius leave a smear (the apple r 0.10-0.18); use an LED that "
                   f"faces the walls (LED=post3535)")
    elif lens.light_height_mm > FLAT_UP_MAX_HEIGHT * lens.height_mm:
        out.append(f"a flat LED facing up (LED={build.led.name}) {lens.light_height_mm:g} mm up a {lens.height_mm:g} mm "
                   f"lens leaves its weakest light for the pictures' lower parts (the apple at 45 of 90 mm: r 0.88, "
                   f"at 15 mm 0.96): set [lens] light_height_mm to {FLAT_UP_HEIGHT * lens.height_mm:.0f} "
                   f"in a copy of the profile, or use an LED that faces the walls (LED=post3535)")
    return out


def _bundled_leds() -> list[profile.Led]:
    """The LED profiles in ``profiles/led/``."""
    return [profile.load_led(str(p)) for p in sorted((profile.PROFILE_DIR / "led").glob("*.toml"))]


def _alike(led: profile.Led, max_radius_mm: float) -> list[profile.Led]:
    """The bundled LEDs of ``led``'s shape (a ball or a flat LED, whose blur scales with
    its radius) of radius up to ``max_radius_mm``, largest first."""
    return sorted((o for o in _bundled_leds() if o.shape == led.shape and 0 < o.radius_mm <= max_radius_mm),
                  key=lambda o: -o.radius_mm)
