"""plan's sharpness budget: what halves the blur, and the warnings for fine detail and text."""

import json

import pytest

from lampfab import pipeline
from lampfab.pipeline import budget


def _walls(h, v, detail_ssim=0.95):
    return {name: {"led_blur_mm": {"horizontal": h, "vertical": v}, "detail_ssim": detail_ssim}
            for name in ("front", "left", "right")}


@pytest.fixture
def text_build(tmp_path):
    """A build folder whose prepare report says every wall shows ``text``."""
    def make(text: str, led: str = "star3535"):
        out = tmp_path / "b"
        out.mkdir(exist_ok=True)
        figures = {f"{w}_source": f"text: {text}" for w in ("front", "left", "right")}
        (out / "prepare.json").write_text(json.dumps({"figures": figures}))
        return pipeline.Build.open(out, "default", "sla_resin", led)
    return make


def test_text_too_small_for_the_leds_blur_is_a_warning_naming_an_led_that_reads(text_build):
    # The blur plan measured for the four words with the default LED, 60 x 84 mm, is 0.27
    # of their em (309 mm): at the edge (bench/text_blur.py; such a lamp read 11 of 12
    # words back).  A 0.8 mm LED halves it.
    warnings = budget._warnings(text_build("Sweet dreams little one"), _walls(60.0, 84.0))
    assert len(warnings) == 1 and "may not read" in warnings[0] and "front, left, right" in warnings[0]
    assert "LED=mini1616" in warnings[0]
    assert budget._warnings(text_build("Sweet dreams little one"), _walls(30.0, 42.0)) == []
    assert budget._warnings(text_build("Hi"), _walls(60.0, 84.0)) == []  # two big letters read


def test_detail_finer_than_the_blur_is_a_warning(text_build):
    build = text_build("Hi")
    soft = budget._warnings(build, _walls(60.0, 84.0, detail_ssim=0.6))
    assert len(soft) == 1 and "finer than this LED can show" in soft[0]


def test_what_halves_the_blur_comes_with_its_figures(text_build):
    line = budget._halve(text_build("Hi"), _walls(60.0, 84.0))
    # The 1 mm die is the largest bundled LED at most half as wide: a third of the blur.
    assert "LED=die1mm" in line and "20 x 28 mm" in line
    assert "a lens twice as large (90 mm radius, 180 mm tall: 30 x 42 mm)" in line
    assert "not in pixels" in line


def test_a_filaments_blur_up_the_wall_halves_with_its_length(text_build):
    line = budget._halve(text_build("Hi", led="filament26"), _walls(44.0, 720.0))
    assert "a filament half as long (13 mm: 360 mm up the wall)" in line
