import re

import pytest

from lampfab import profile
from lampfab.errors import LampfabError


@pytest.mark.parametrize("name", ["draft", "quick", "default", "fine", "floor", "hires"])
def test_bundled_design_profiles_load(name):
    d = profile.load_design(name)
    assert d.name == name and d.room.walls


@pytest.mark.parametrize("text, words", [
    ("[lens]\nouter_radius = 40\n", ["[lens] outer_radius", "unknown key"]),
    ("[lens]\nouter_radius_mm = -4\n", ["outer_radius_mm", "out of range", "10.0 to 300.0"]),
    ("[lens]\nouter_radius_mm = 'big'\n", ["outer_radius_mm", "expected a number"]),
    ("[optimize]\nloss = 'l2'\n", ["loss", "si_mse"]),
    ("[optimize]\nmethod = 'ptracer'\nloss = 'si_mse_ssim'\n", ["[optimize] loss", "si_mse_ssim", "splat"]),
    ("[optimize]\nmethod = 'ptracer'\nloss = 'multiscale'\n", ["[optimize] loss", "multiscale", "splat"]),
    ("[optimize]\nschedule = 'cyclic'\nbacktrack = true\n", ["[optimize] backtrack", "joint"]),
    ("[room]\nwalls = ['ceiling']\n", ["walls", "ceiling", "front"]),
    ("[lens]\nouter_radius_mm = 60\n[room]\nwall_distance_mm = 110\n", ["walls behind or inside the lamp"]),
    ("[lens]\nlight_height_mm = 200\n", ["light_height_mm", "inside the lens"]),
    ("[lens]\nhollow_radius_mm = 2\n", ["hollow_radius_mm", "out of range", "4.0 to 40.0"]),
    ("[lens]\ninner_mesh = 'mine.obj'\nhollow_radius_mm = 16\n", ["hollow_radius_mm", "inner_mesh", "mine.obj",
                                                                  "set one of them"]),
    ("[optimise]\n", ["unknown section"]),
    ("[lens\n", ["not valid TOML"]),
])
def test_bad_profiles_name_file_key_and_range(tmp_path, text, words):
    p = tmp_path / "bad profile.toml"
    p.write_text(text)
    with pytest.raises(LampfabError) as err:
        profile.load_design(str(p))
    message = str(err.value)
    assert str(p) in message and "\n" not in message
    for w in words:
        assert w in message


def test_unknown_profile_name_lists_the_available_ones():
    with pytest.raises(LampfabError, match="available: .*default"):
        profile.load_design("no_such_profile")


@pytest.mark.parametrize("name", ["post3535", "post1616", "star3535", "mini1616", "die1mm", "filament26", "opal10"])
def test_bundled_led_profiles_load_with_a_part_and_a_board(name):
    led = profile.load_led(name)
    assert led.name == name and led.part and led.board_diameter_mm > 0 and led.flux_lm > 0
    assert (led.length_mm > 0) == (led.shape == "cylinder")


def test_a_copied_led_profile_loads_from_its_path_as_the_readme_says(tmp_path):
    bundled = profile.PROFILE_DIR / "led" / "mini1616.toml"
    mine = tmp_path / "my_led.toml"
    mine.write_text(bundled.read_text().replace("radius_mm = 0.8", "radius_mm = 1.0"))
    led = profile.load_led(str(mine))
    assert (led.name, led.radius_mm, led.path) == ("my_led", 1.0, str(mine))


def test_the_default_led_is_one_package_per_wall_facing_it():
    led = profile.load_led(profile.DEFAULT_LED)
    assert (led.shape, led.radius_mm, led.offset_mm, led.board_diameter_mm) == ("post", 1.5, 3.0, 30.0)
    assert (led.fin_radius_mm, led.fin_height_mm) == (14.5, 50.0)
    assert 2 * led.fin_radius_mm < led.board_diameter_mm  # the fins slide through the bore


@pytest.mark.parametrize("text, words", [
    ("shape = 'cube'\n", ["shape", "'cube'", "sphere"]),
    ("shape = 'cylinder'\n", ["length_mm", "filament"]),
    ("length_mm = 5.0\n", ["length_mm", "cylinder"]),
    ("shape = 'disc'\nlength_mm = 5.0\n", ["length_mm", "cylinder"]),
    ("offset_mm = 3.0\n", ["offset_mm", "post"]),
    ("shape = 'post'\nfin_radius_mm = 9.0\n", ["fin_radius_mm and fin_height_mm go together"]),
    ("shape = 'post'\noffset_mm = 3.0\nfin_radius_mm = 4.0\nfin_height_mm = 9.0\n", ["fin_radius_mm 4", "past the LEDs"]),
    ("shape = 'post'\nfin_radius_mm = 11.0\nfin_height_mm = 9.0\nboard_diameter_mm = 22.0\n",
     ["fin_radius_mm 11", "22 mm across", "slide through the bore", "under 11"]),
    ("shape = 'post'\noffset_mm = 3.0\nfin_radius_mm = 10.0\nfin_height_mm = 9.0\nboard_diameter_mm = 22.0\n",
     ["rod_width_mm 0", "square rod", "under 2 x offset_mm (6)"]),
    ("rod_width_mm = 4.0\n", ["rod_width_mm", "post"]),
    ("radius_mm = 30.0\n", ["radius_mm", "out of range", "0.0 to 20.0"]),
    ("colour = 'warm'\n", ["colour", "unknown key"]),
])
def test_bad_led_profiles_name_file_key_and_range(tmp_path, text, words):
    p = tmp_path / "my led.toml"
    p.write_text(text)
    with pytest.raises(LampfabError) as err:
        profile.load_led(str(p))
    assert str(p) in str(err.value)
    for w in words:
        assert w in str(err.value)


def test_a_flat_led_facing_up_cannot_light_the_floor(tmp_path):
    flat = tmp_path / "flat.toml"
    flat.write_text("shape = 'disc'\nradius_mm = 1.5\n")
    led = profile.load_led(str(flat))
    profile.check_led_for(profile.load_design("default"), led)  # walls only: fine
    with pytest.raises(LampfabError) as err:
        profile.check_led_for(profile.load_design("floor"), led)
    for w in (str(flat), "floor", "below the horizon", "LED=post3535"):
        assert w in str(err.value)
    profile.check_led_for(profile.load_design("floor"), profile.load_led("post3535"))


def test_the_leds_board_widens_the_bore_never_narrows_it():
    sla, cnc = profile.load_fabrication("sla_resin"), profile.load_fabrication("acrylic_cnc4")
    star, mini = profile.load_led("star3535"), profile.load_led("mini1616")
    assert profile.with_bore_for(sla, star).mount_radius_mm == 10.0   # the 20 mm star board
    assert profile.with_bore_for(sla, mini).mount_radius_mm == 5.0
    assert profile.with_bore_for(cnc, mini).mount_radius_mm == 16.5   # the mill's counterbore stays


@pytest.mark.parametrize("name", ["acrylic_cnc3", "acrylic_cnc4", "glass"])
def test_a_shop_opens_the_whole_floor_of_the_bundled_cavity(name):
    # A floor ledge around a narrower bore faces up, hidden from a tool entering from
    # below (cavity_access fails); the counterbore must clear the bundled hollow's floor.
    from lampfab.inner import default_inner_mesh
    from lampfab.solid import plan_bore

    mesh = default_inner_mesh()
    fab = profile.with_bore_for(profile.load_fabrication(name), profile.load_led("post3535"))
    assert plan_bore(mesh.vertices, mesh.faces, fab.mount_radius_mm).counterbore


def test_a_print_prefers_gentle_slopes_and_may_steepen_a_mill_may_not():
    from lampfab.limits import Limits

    design = profile.load_design("default")
    sla = Limits.of(design, profile.load_fabrication("sla_resin"))
    assert (sla.max_slope_deg, sla.steepest_slope_deg) == (60.0, 68.0)
    assert sla.steepened().max_slope_deg == 68.0 and sla.steepened().steepest_slope_deg is None
    assert sla.with_slope(64.0) == Limits(20.0, 64.0, 45.0, 0.0, None)
    cnc = Limits.of(design, profile.load_fabrication("acrylic_cnc4"))
    assert (cnc.max_slope_deg, cnc.steepest_slope_deg) == (60.0, None)


def test_a_preferred_slope_steeper_than_the_limit_is_refused_and_an_unset_one_is_the_limit(tmp_path):
    from lampfab.limits import Limits

    bundled = (profile.PROFILE_DIR / "fab" / "sla_resin.toml").read_text()
    steeper = tmp_path / "steeper.toml"
    steeper.write_text(bundled.replace("preferred_slope_deg = 60.0", "preferred_slope_deg = 70.0"))
    with pytest.raises(LampfabError, match=r"steeper\.toml: preferred_slope_deg 70 is steeper than max_slope_deg 68"):
        profile.load_fabrication(str(steeper))
    unset = tmp_path / "unset.toml"
    unset.write_text(bundled.replace("preferred_slope_deg = 60.0\n", ""))
    limits = Limits.of(profile.load_design("default"), profile.load_fabrication(str(unset)))
    assert (limits.max_slope_deg, limits.steepest_slope_deg) == (68.0, None)


def _design(tmp_path, text: str):
    """The design profile ``text`` as written to tmp_path/p.toml and loaded."""
    p = tmp_path / "p.toml"
    p.write_text(text)
    return profile.load_design(str(p))


def test_more_photons_on_the_fine_level_needs_the_splat_refinement(tmp_path):
    with pytest.raises(LampfabError, match=r"p\.toml: \[optimize\] fine_level_photons needs method \"splat\""):
        _design(tmp_path, "[optimize]\nmethod = 'ptracer'\nloss = 'si_mse'\nfine_level_photons = 2.0\n")
    with pytest.raises(LampfabError, match=r"p\.toml.*fine_level_photons.*0\.1.*16"):
        _design(tmp_path, "[optimize]\nfine_level_photons = 20.0\n")


def test_designing_for_the_led_needs_the_splat_refinement(tmp_path):
    with pytest.raises(LampfabError, match="design_light.*splat"):
        _design(tmp_path, "[optimize]\nmethod = 'ptracer'\nloss = 'si_mse'\ndesign_light = 'led'\n")


def test_slots_are_half_a_millimetre_wide_at_least_and_only_printed(tmp_path):
    with pytest.raises(LampfabError, match=r"p\.toml: \[lens\] slot_width_mm 0\.3: allowed 0 \(no slots\) or 0\.5 to 3"):
        _design(tmp_path, "[lens]\nslot_width_mm = 0.3\n")
    design = _design(tmp_path, "[lens]\nslot_width_mm = 1.0\n")
    profile.check_fab_for(design, profile.load_fabrication("sla_resin"))
    with pytest.raises(LampfabError, match=r"p\.toml: \[lens\] slot_width_mm 1: .*acrylic_cnc4.*cnc4.*FAB=sla_resin"):
        profile.check_fab_for(design, profile.load_fabrication("acrylic_cnc4"))
    profile.check_fab_for(profile.load_design("default"), profile.load_fabrication("acrylic_cnc4"))


def _resolved(design) -> dict:
    d = profile.as_dict(design)
    d.pop("path"), d.pop("name")
    return d


def test_a_profile_on_a_base_is_the_base_with_what_it_sets(tmp_path):
    """The README's two-line profile: the default with slots, nothing else changed."""
    mine = tmp_path / "my_slots.toml"
    mine.write_text('base = "default"\n\n[lens]\nslot_width_mm = 1.0\n')
    design, default = profile.load_design(str(mine)), profile.load_design("default")
    assert design.name == "my_slots" and design.lens.slot_width_mm == 1.0
    expected = _resolved(default)
    expected["lens"]["slot_width_mm"] = 1.0
    assert _resolved(design) == expected


def test_a_base_path_is_read_from_the_profiles_folder_and_errors_name_the_file_that_set_the_key(tmp_path):
    (tmp_path / "wide.toml").write_text('base = "default"\n[room]\ntarget_height_mm = 700\n')
    (tmp_path / "wider.toml").write_text('base = "wide.toml"\n[optimize]\niterations = 12\n')
    design = profile.load_design(str(tmp_path / "wider.toml"))
    assert design.room.target_height_mm == 700.0 and design.optimize.iterations == 12
    assert design.lens == profile.load_design("default").lens
    (tmp_path / "wide.toml").write_text('base = "default"\n[room]\ntarget_height_mm = -5\n')
    with pytest.raises(LampfabError, match=rf"^{re.escape(str(tmp_path / 'wide.toml'))}: \[room\] target_height_mm"):
        profile.load_design(str(tmp_path / "wider.toml"))


@pytest.mark.parametrize("base, words", [
    ('"no_such_profile"', ["loop_a.toml: base", "no_such_profile", "available"]),
    ('"missing.toml"', ["loop_a.toml: base", "missing.toml not found"]),
    ("3", ["base", "expected a profile's name"]),
    ('"loop_b.toml"', ["name each other", "loop_a.toml", "loop_b.toml"]),
])
def test_a_bad_base_is_one_clear_error(tmp_path, base, words):
    (tmp_path / "loop_a.toml").write_text(f"base = {base}\n")
    (tmp_path / "loop_b.toml").write_text('base = "loop_a.toml"\n')
    with pytest.raises(LampfabError) as err:
        profile.load_design(str(tmp_path / "loop_a.toml"))
    assert "\n" not in str(err.value)
    for w in words:
        assert w in str(err.value)


@pytest.mark.parametrize("name", ["floor", "quick", "hires", "fine"])
def test_the_bundled_variants_follow_the_default_where_they_say_nothing(name):
    variant, default = _resolved(profile.load_design(name)), _resolved(profile.load_design("default"))
    text = (profile.PROFILE_DIR / f"{name}.toml").read_text()
    assert 'base = "default"' in text
    for section, values in default.items():
        for key, value in values.items():
            if f"\n{key} =" not in text:
                assert variant[section][key] == value, (section, key)
