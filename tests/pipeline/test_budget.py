"""plan's sharpness budget: what halves the blur, and the warnings for fine detail and text."""

import json

import pytest

from lampfab import pipeline
from lampfab.pipeline import budget


def _walls(h, v, detail_ssim=0.95):
    return {name: {"led_blur_mm": {"horizontal": h, "vertical": v}, "detail_ssim": detail_ssim}
            for name in ("front", "left", "right")}


def _warnings(build, walls):
    """plan's warnings for these blur figures, with no kernels to read text through."""
    unreadable = budget._unreadable(build, walls)
    return budget._warnings(build, walls, None, unreadable, budget._text_led(build, walls, unreadable, {}))


@pytest.fixture
def low_profile(tmp_path):
    """The default profile with the light 15 mm up the lens, where a flat LED facing up
    serves the pictures best."""
    from lampfab import profile

    path = tmp_path / "low.toml"
    path.write_text((profile.PROFILE_DIR / "default.toml").read_text().replace(
        "light_height_mm = 45.0", "light_height_mm = 15.0"))
    return str(path)


@pytest.fixture
def text_build(tmp_path, low_profile):
    """A build folder whose prepare report says every wall shows ``text``, lit by a flat
    LED facing up where it serves best."""
    def make(text: str, led: str = "star3535"):
        out = tmp_path / "b"
        out.mkdir(exist_ok=True)
        figures = {f"{w}_source": f"text: {text}" for w in ("front", "left", "right")}
        (out / "prepare.json").write_text(json.dumps({"figures": figures}))
        return pipeline.Build.open(out, low_profile, "sla_resin", led)
    return make


def test_plan_warns_of_a_flat_led_facing_up_where_it_serves_badly(tmp_path, low_profile):
    def warnings(design, fab, led):
        return budget._mounting(pipeline.Build.open(tmp_path, design, fab, led))

    assert warnings(low_profile, "sla_resin", "star3535") == []
    assert warnings("default", "sla_resin", "post3535") == warnings("default", "acrylic_cnc4", "post3535") == []
    high = warnings("default", "sla_resin", "star3535")
    assert len(high) == 1 and "45 mm up a 90 mm lens" in high[0] and "light_height_mm to 15" in high[0]
    milled = warnings(low_profile, "acrylic_cnc3", "mini1616")
    assert len(milled) == 1 and "milled lens" in milled[0] and "LED=post3535" in milled[0]


def test_text_too_small_for_the_leds_blur_is_a_warning_naming_an_led_that_reads(text_build):
    # The blur plan measured for the four words with the default LED, 60 x 84 mm, is 0.27
    # of their em (309 mm): at the edge (bench/text_blur.py; such a lamp read 11 of 12
    # words back).  A 0.8 mm LED halves it.
    warnings = _warnings(text_build("Sweet dreams little one"), _walls(60.0, 84.0))
    assert len(warnings) == 1 and "may not read" in warnings[0] and "front, left, right" in warnings[0]
    assert "LED=mini1616" in warnings[0]
    assert "still reads whole" not in warnings[0]  # no OCR figures here: no claim about the words
    assert _warnings(text_build("Sweet dreams little one"), _walls(30.0, 42.0)) == []
    assert _warnings(text_build("Hi"), _walls(60.0, 84.0)) == []  # two big letters read


@pytest.mark.parametrize("reads_whole_from, named", [("mini1616", "mini1616"), ("die1mm", "die1mm"), (None, "die1mm")])
def test_plan_names_the_largest_led_with_which_the_text_reads(text_build, monkeypatch, reads_whole_from, named):
    """Of the LEDs under the blur limit, plan names the largest with which a perfect lens
    shows every word the sharp target shows, or else the one that shows the most.  A
    stand-in reader reads one word more the sharper the picture (its peak: a smaller LED
    blurs the light of one lit pixel less)."""
    import numpy as np

    from lampfab import ocr, room, sharpness

    build = text_build("Sweet dreams little one")
    wall = build.walls[0]
    rows, cols = room.image_shape(wall, build.design.optimize.sensor_px)
    target = np.zeros((rows, cols))
    target[rows // 2, cols // 2] = 1.0
    field = np.broadcast_to([60.0**2 / 16, 84.0**2 / 16, 0.0], (rows, cols, 3))  # the default's 60 x 84 mm
    peak = {o.name: sharpness.blur(target, budget._scaled(build, o, field), wall).max() for o in budget._alike(build.led, 0.8)}
    # The peak with which the stand-in first reads all four words; past every LED: never.
    cut = peak[reads_whole_from] if reads_whole_from else 2 * max(peak.values())
    # Short of that, the dimmest peak reads 2 words, the next 3.
    monkeypatch.setattr(ocr, "words_read", lambda image, text: 4 if image.max() >= cut - 1e-12
                        else 2 + sum(p < image.max() - 1e-12 for p in peak.values()))
    walls = {wall.name: {"target_words_read": 4}}
    found = budget._text_led(build, walls, [(wall.name, 85.0, 300.0)], {wall.name: (wall, target, field, "x")})
    assert found["name"] == named and found["max_radius_mm"] == pytest.approx(0.25 * 300 / 85 * 1.5)
    assert found["perfect_words_read"] == {wall.name: 4 if reads_whole_from else 3}


def test_detail_finer_than_the_blur_is_a_warning(text_build):
    build = text_build("Hi")
    soft = _warnings(build, _walls(60.0, 84.0, detail_ssim=0.6))
    assert len(soft) == 1 and "finer than this LED can show" in soft[0]
    # Just under the limit it says so with a figure that is under it (not "0.85, below 0.85").
    near = _warnings(build, _walls(60.0, 84.0, detail_ssim=budget.DETAIL_SSIM - 0.002))
    assert f"{budget.DETAIL_SSIM - 0.002:.3f}" in near[0]


def test_what_halves_the_blur_comes_with_its_figures(text_build):
    line = budget._halve(text_build("Hi"), _walls(60.0, 84.0))
    # The 1 mm die is the largest bundled LED at most half as wide: a third of the blur.
    assert "LED=die1mm" in line and "20 x 28 mm" in line
    assert "a lens twice as large (90 mm radius, 180 mm tall: 30 x 42 mm)" in line
    assert "not in pixels" in line


def test_a_filaments_blur_up_the_wall_halves_with_its_length(text_build):
    line = budget._halve(text_build("Hi", led="filament26"), _walls(44.0, 720.0))
    assert "a filament half as long (13 mm: 360 mm up the wall)" in line


def _uniform_kernels(build, h_mm: float, v_mm: float, sides: float = 1.0):
    """The LED's kernel the same (``h_mm`` x ``v_mm`` across x up, 4 sigma) everywhere on
    every wall, or ``sides`` times as wide in the pictures' outer eighths: a grid of cells
    over each wall's picture, eight across."""
    import numpy as np

    from lampfab import sharpness

    centres, walls = [], []
    for k, wall in enumerate(build.walls):
        xs, ys = np.meshgrid(np.linspace(0, wall.width_mm, 9)[:-1] + wall.width_mm / 16,
                             np.linspace(0, wall.height_mm, 7)[:-1] + wall.height_mm / 12)
        centres.append(np.stack([xs.ravel(), ys.ravel()], 1))
        walls.append(np.full(xs.size, k))
    centre = np.concatenate(centres)
    cov = np.tile([(h_mm / 4) ** 2, (v_mm / 4) ** 2, 0.0], (len(centre), 1))
    width = build.walls[0].width_mm
    cov[(centre[:, 0] < width / 8) | (centre[:, 0] > 7 * width / 8)] *= sides**2
    return sharpness.Kernels(np.concatenate(walls), centre, cov, np.ones(len(centre)))


def test_plan_names_the_line_that_reaches_the_sides_where_the_blur_is_wider(text_build):
    """A line set edge to edge reaches the pictures' outer eighths, where the LED blurs
    more: the text warning names it with the blur there; with the blur even, or the words
    set clear of the sides, it says nothing of them."""
    from lampfab import targets

    by_hand = "Dream\nbig little\nstar"  # the middle line edge to edge
    build = text_build(by_hand)
    build.save_targets({w.name: targets.text_image(by_hand, 48, 64) for w in build.walls})
    wider = budget.summarize(build, _uniform_kernels(build, 68.0, 97.0, sides=1.4))
    for wall in wider["walls"].values():
        assert wall["text_sides"]["lines"] == ["big little"]
        assert wall["text_sides"]["side_blur_mm"] > 1.2 * wall["text_sides"]["middle_blur_mm"]
    assert any("mm where the line \"big little\" reaches the walls' sides" in w for w in wider["warnings"])
    even = budget.summarize(build, _uniform_kernels(build, 68.0, 97.0))
    assert any("may not read" in w for w in even["warnings"])
    assert not any("walls' sides" in w for w in even["warnings"])

    build = text_build("Dream big little star")  # four lines, clear of the sides
    build.save_targets({w.name: targets.text_image("Dream big little star", 48, 64) for w in build.walls})
    clear = budget.summarize(build, _uniform_kernels(build, 68.0, 97.0, sides=1.4))
    assert all(w["text_sides"] is None for w in clear["walls"].values())
    assert not any("walls' sides" in w for w in clear["warnings"])


@pytest.mark.parametrize("phrase, blur_mm, read_whole, warns", [
    ("Sleep tight my angel", (120.0, 170.0), False, True),  # over half an em: lines run into each other
    ("Sleep tight my angel", (33.0, 45.0), True, False),
    ("Good night sweet pea", (68.0, 97.0), True, True)],
    ids=["an LED half as large again as the default", "mini1616", "the default LED, another phrase"])
def test_plan_reads_a_perfect_lenss_text_through_the_leds_blur(text_build, phrase, blur_mm, read_whole, warns):
    from lampfab import ocr, targets

    build = text_build(phrase)
    build.save_targets({w.name: targets.text_image(phrase, 48, 64) for w in build.walls})  # at the design's 64 px
    figures = budget.summarize(build, _uniform_kernels(build, *blur_mm))
    assert ocr.available()
    walls = figures["walls"].values()
    assert all(w["words"] == w["target_words_read"] == 4 for w in walls)
    read = [w["perfect_words_read"] for w in walls]
    if read_whole:
        assert read == [4, 4, 4] and not any("even a perfect lens" in w for w in figures["warnings"])
        # Past the blur at which text reads surely, the warning says that these words still read.
        warned = [w for w in figures["warnings"] if "may not read" in w]
        assert len(warned) == warns and all("still reads whole" in w for w in warned)
    else:
        assert max(read) < 4
        assert any("even a perfect lens would show OCR only front" in w and "(sharp 4/4)" in w
                   for w in figures["warnings"])
    if warns:
        # The LED plan names is read through too: its kernels are this LED's scaled by the
        # radii's ratio, as the same blur given outright reads.
        named = figures["text_led"]
        assert named["name"] in {o.name for o in budget._alike(build.led, named["max_radius_mm"])}
        assert set(named["perfect_words_read"]) == {"front", "left", "right"}
        ratio = named["radius_mm"] / build.led.radius_mm
        direct = budget.summarize(build, _uniform_kernels(build, blur_mm[0] * ratio, blur_mm[1] * ratio))
        assert named["perfect_words_read"] == {n: w["perfect_words_read"] for n, w in direct["walls"].items()}
        shown = ", ".join(f"{n} {k}/4" for n, k in named["perfect_words_read"].items())
        led = f"LED={named['name']} ({named['radius_mm']:g} mm radius)"
        assert any(f"{led}, with which a perfect lens would show {shown}" in w
                   for w in figures["warnings"])
    else:
        assert figures["text_led"] is None


def _checkerboard(rows: int, cols: int, square_px: int) -> "np.ndarray":
    """Squares of ``square_px`` pixels, alternately bright and dark: detail of that size."""
    import numpy as np

    yy, xx = np.mgrid[0:rows, 0:cols]
    return ((yy // square_px + xx // square_px) % 2).astype(float)


@pytest.mark.parametrize("blur_mm, named, enough", [
    ((60.0, 84.0), "mini1616", True),     # the default LED's blur: half of it keeps the squares
    ((120.0, 168.0), "die1mm", True),     # twice that: the 1.6 mm package smears them too
    ((240.0, 336.0), "die1mm", False)],   # four times: even the die's third of it does
    ids=["half the LED", "a third of the LED", "no bundled LED"])
def test_fine_detail_names_the_led_that_would_show_it(text_build, blur_mm, named, enough):
    # Squares of 2 px (56 x 56 mm) on every wall, under a blur of 0.5-0.75 px sigma or more.
    build = text_build("Hi")
    build.save_targets({w.name: _checkerboard(48, 64, 2) for w in build.walls})
    figures = budget.summarize(build, _uniform_kernels(build, *blur_mm))
    assert all(w["detail_ssim"] < budget.DETAIL_SSIM for w in figures["walls"].values())
    sharper = figures["sharper_led"]
    assert sharper["name"] == named and sharper["enough"] is enough
    assert (min(sharper["detail_ssim"].values()) >= budget.DETAIL_SSIM) is enough
    soft = [w for w in figures["warnings"] if "finer than this LED can show" in w]
    assert len(soft) == 1
    if enough:
        assert f"choose LED={named} (" in soft[0] and "mm radius), with which it would score 0." in soft[0]
    else:
        assert "even the smallest bundled LED, LED=die1mm (0.5 mm radius), would leave it at 0." in soft[0]


def test_a_picture_the_led_shows_names_no_other_led(text_build):
    import numpy as np

    build = text_build("Hi")
    broad = np.zeros((48, 64))
    broad[12:36, 16:48] = 1.0  # one large square: nothing the LED's blur takes away
    build.save_targets({w.name: broad for w in build.walls})
    figures = budget.summarize(build, _uniform_kernels(build, 60.0, 84.0))
    assert figures["sharper_led"] is None and figures["warnings"] == []


def _verify_figures(reference_ssim: float) -> dict:
    walls = {name: {"led_pearson": 0.97, "led_reference_ssim": reference_ssim} for name in ("front", "left", "right")}
    return {"walls": walls, "real_light": "LED 1.5 mm"}


def test_the_verdict_says_soft_when_the_led_blurs_the_pictures_detail_away(text_build):
    from lampfab.pipeline.report_page import verdict

    build = text_build("Hi")
    die = {"name": "die1mm", "radius_mm": 0.5, "detail_ssim": {"front": 0.9}, "enough": True}
    line, tone = verdict(build, _verify_figures(budget.DETAIL_SSIM - 0.02), [], die)
    assert tone == "warn" and "soft: it holds detail finer than this LED can show (LED=die1mm would show it)" in line
    line, tone = verdict(build, _verify_figures(budget.DETAIL_SSIM - 0.02), [], {**die, "enough": False})
    assert tone == "warn" and "LED=" not in line
    line, tone = verdict(build, _verify_figures(budget.DETAIL_SSIM + 0.02), [], None)
    assert tone == "good" and line.startswith("Projects your picture well with the real LED 1.5 mm")


def test_plan_warns_where_the_pictures_light_sits_higher_than_the_lens_can_lift_it(tmp_path):
    """The transport's band below (``transport.band_shares``) grows only where the picture's
    light sits higher than a print can lift the lens's lower light; plan then says which
    walls, how much light goes to the glow beside the picture, and what would help."""
    build = pipeline.Build.open(tmp_path, "default", "sla_resin", "post3535")

    def band(below):
        return {"above": 0.05, "below": below, "bend_deg": [-20.0, 20.0], "reach_deg": 24.0, "lifted": below > 0.05}

    even = {name: band(0.05) for name in ("front", "left", "right")}
    assert budget._out_of_reach(build, even) == []
    high = budget._out_of_reach(build, {name: band(0.225) for name in ("front", "left", "right")})
    assert len(high) == 1
    assert "the front, left, right pictures' light sits high in their frames" in high[0]
    assert "more than 24°, farther than its flanks can" in high[0] and "28% of the light goes to glows beside the picture" in high[0]
    assert "its frame: 10%" in high[0] and "pad the image above" in high[0]
    one = budget._out_of_reach(build, {**even, "left": band(0.15)})
    assert "the left picture's light sits high in its frame" in one[0] and "20% of the light" in one[0]
