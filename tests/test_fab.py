"""What finishing may cost: the tolerance study and the post-processing guidance, on
small lenses (seconds)."""

import dataclasses

import numpy as np
import pytest

from lampfab import guidance, lens, room, tolerance_study, trace
from lampfab.profile import load_fabrication, load_led
from lampfab.source import Source

from tests.helpers import CYL, bumps, inner


def test_error_field_is_smooth_periodic_and_peaks_at_one():
    field = tolerance_study.error_field(CYL, (256, 65), 5.0, seed=3)
    assert np.abs(field).max() == pytest.approx(1.0)
    # Correlated over 5 mm with nodes ~1 mm apart: neighbours agree, and the seam (the last
    # column to the first) is as smooth as anywhere else.
    steps = np.abs(np.diff(field, axis=0, append=field[:1]))
    assert steps.max() < 0.3 and steps[-1].max() < 0.3
    assert np.corrcoef(field[:-1].ravel(), field[1:].ravel())[0, 1] > 0.9
    assert not np.allclose(field, tolerance_study.error_field(CYL, (256, 65), 5.0, seed=4))


@pytest.fixture(scope="module")
def study_setup():
    """A bumpy lens and its own render as the target: r is 1 for the unperturbed lens."""
    v, f = inner(sections=32)
    light = np.array([0.0, 0.0, 40.0])
    walls = [room.Wall("front", np.array([-900.0, 1000.0, 715.0]), np.array([1800.0, 0.0, 0.0]),
                       np.array([0.0, 0.0, -1350.0]))]
    shapes = [room.image_shape(walls[0], 16)]
    verts, faces = lens.optical_mesh(CYL, bumps(), 2, v, f)
    target, _ = trace.render_walls(trace.MeshScene(verts, faces), Source(light), 1.5, walls, shapes, 40_000, 5, 8)
    return v, f, light, walls, target


def test_tolerance_study_finds_where_the_image_degrades(study_setup, monkeypatch):
    v, f, light, walls, target = study_setup
    monkeypatch.setattr(tolerance_study, "AMPLITUDES_MM", (0.05, 3.0))
    res = tolerance_study.study(CYL, bumps(), lambda h: lens.optical_mesh(CYL, h, 2, v, f), Source(light), 1.5, walls,
                                target, 40_000, 5, 8, 0.02)
    assert res["amplitudes_mm"] == [0.0, 0.02, 0.05, 3.0]
    r = res["walls"]["front"]
    assert r[0] == pytest.approx(1.0)                       # same lens, same photons as the target
    assert res["max_drop"][0] == 0.0
    assert res["max_drop"][1] < res["r_drop"] < res["max_drop"][3]   # 3 mm of error ruins the image
    assert res["allowance_mm"] == 0.05 and not res["allowance_at_least"]
    assert res["profile_error_mm"] == 0.02 and res["profile_error_drop"] == res["max_drop"][1]


def test_guidance_names_the_sides_finishing_and_allowance():
    study = {"allowance_mm": 0.05, "allowance_at_least": False, "profile_error_mm": 0.02,
             "profile_error_drop": 0.004, "r_drop": 0.02, "correlation_mm": 5.0, "photons": 1000,
             "amplitudes_mm": [0.0, 0.02, 0.05, 0.1], "max_drop": [0.0, 0.004, 0.01, 0.05],
             "walls": {"front": [0.9, 0.896, 0.89, 0.85]}}
    fab = load_fabrication("acrylic_cnc3")
    text = guidance.advice(fab, load_led("mini1616"), ["front", "left", "right"], np.array([0.0, 0.0, 45.0]), study)
    joined = " ".join(text)
    assert "+y side (u 45 to 135 deg) lights the front wall" in joined
    assert "-x side (u 135 to 225 deg) lights the left wall" in joined
    assert "2000 grit" in joined and "Anneal" in joined and "witness lines" in joined
    assert "up to 50 um" in joined and "costs r 0.004 (within it)" in joined
    assert "33 mm across" in joined and "Cree XLamp XQ-D" in joined and "(mini1616)" in joined
    # A package on its board is mounted facing up, and the maker is told so.
    assert "facing straight up, 45 mm above the base" in joined and "nothing below the horizon" in joined
    ball = " ".join(guidance.advice(fab, load_led("opal10"), ["front"], np.array([0.0, 0.0, 45.0]), study))
    assert "its centre 45 mm above the base" in ball and "evenly in every direction" in ball
    bare = dataclasses.replace(load_led("post3535"), fin_radius_mm=0.0, fin_height_mm=0.0)
    post = " ".join(guidance.advice(fab, bare, ["front"], np.array([0.0, 0.0, 45.0]), study))
    assert "each LED's emitting face upright and square to its wall, their middles 45 mm above the base" in post
    assert "shines level towards its wall" in post and "stand matt black fins" not in post
    fins = " ".join(guidance.advice(fab, load_led("post3535"), ["front"], np.array([0.0, 0.0, 45.0]), study))
    assert "matt black fins, 14.5 mm out from the axis and 50 mm tall" in fins
    page = guidance.html(text, study)
    assert page.count("<tr>") == 5 and '<td class="fail">0.050</td>' in page and "20 um (profile)" in page
    sla = " ".join(guidance.advice(load_fabrication("sla_resin"), load_led("star3535"), ["front"], np.zeros(3),
                                   {**study, "profile_error_drop": 0.03}))
    assert "clear coat" in sla and "finish more carefully" in sla and "witness" not in sla


def test_guidance_says_which_faces_to_paint_black():
    study = {"allowance_mm": 0.05, "allowance_at_least": False, "profile_error_mm": 0.02,
             "profile_error_drop": 0.004, "r_drop": 0.02, "correlation_mm": 5.0}
    args = (load_fabrication("sla_resin"), load_led("post3535"), ["front", "left", "right"], np.zeros(3), study)
    back = " ".join(guidance.advice(*args, {"black_paint": "top_base_and_back", "painted_u_deg": [225.0, 309.36]}))
    assert "paint the flat top and the base, and the outer surface from u 225 to 309.36 deg" in back
    assert "matt black" in back
    ends = " ".join(guidance.advice(*args, {"black_paint": "top_base_and_back", "painted_u_deg": None}))
    assert "paint the flat top and the base matt black" in ends and "outer surface from u" not in ends
    assert "matt black paint" not in " ".join(guidance.advice(*args, {"black_paint": "none"}))


def test_guidance_says_how_to_fill_the_slots():
    from lampfab.slots import Slot, Slots

    study = {"allowance_mm": 0.05, "allowance_at_least": False, "profile_error_mm": 0.02,
             "profile_error_drop": 0.004, "r_drop": 0.02, "correlation_mm": 5.0}
    args = (load_fabrication("sla_resin"), load_led("post3535"), ["front", "left", "right"], np.zeros(3), study)
    cut = Slots(1.0, 85.0, tuple(Slot(a, 17.0, 34.0 + a / 100) for a in (45.0, 135.0, 225.0, 315.0)))
    text = " ".join(guidance.advice(*args, {"black_paint": "top_and_base", "slots": cut.to_json()}))
    assert ("Fill the 4 slots that open in the base (1 mm wide, 17 to 37 mm out from the axis, 85 mm deep, "
            "at u 45, 135, 225, 315 deg) with black epoxy") in text
    assert "air gap" in text
    assert "slots" not in " ".join(guidance.advice(*args, {"black_paint": "top_and_base"}))
    assert "left empty" not in text
    walls = {"front": {"led_ssim": 0.883, "led_ssim_slots_empty": 0.728, "led_ghost_share": 0.004,
                       "led_ghost_share_slots_empty": 0.028},
             "left": {"led_ssim": 0.877, "led_ssim_slots_empty": 0.733, "led_ghost_share": 0.006,
                      "led_ghost_share_slots_empty": 0.031}}
    traced = " ".join(guidance.advice(*args, {"black_paint": "top_and_base", "slots": cut.to_json()}, walls))
    assert ("Traced again with the slots left empty, the walls (front / left) score LED SSIM 0.73 / 0.73 "
            "instead of 0.88 / 0.88, with 2.8% / 3.1% of their light reflected inside the lens instead of "
            "0.4% / 0.6%: on every picture measured so, lower than a lens made without slots") in traced
