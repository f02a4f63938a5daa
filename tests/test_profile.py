import pytest

from lampfab import profile
from lampfab.errors import LampfabError


@pytest.mark.parametrize("name", ["draft", "quick", "default", "fine", "floor"])
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
