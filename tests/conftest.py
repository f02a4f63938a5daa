"""What the tests share: the tiny profiles, the designs and small lenses built from them,
seeded randomness, the Mitsuba variant."""

from pathlib import Path

import numpy as np
import pytest

from lampfab import profile, room, surface

from tests.helpers import CYL, bumps, inner

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def tiny_profile() -> Path:
    """The lamp's tiny design profile: the whole pipeline in seconds."""
    return DATA / "tiny.toml"


@pytest.fixture(scope="session")
def tiny_panel_profile() -> Path:
    """The panel's tiny design profile."""
    return DATA / "tiny_panel.toml"


@pytest.fixture
def tiny_with(tiny_profile, tmp_path):
    """``tiny_with(name, lens="", room_="", replace=())``: the tiny profile written to
    ``tmp_path / name`` with ``lens`` and ``room_`` lines added to those tables and each
    (old, new) of ``replace`` applied (old must be there); returns its path."""
    def write(name: str, lens: str = "", room_: str = "", replace: tuple = ()) -> Path:
        text = tiny_profile.read_text()
        for old, new in replace:
            assert old in text, old
            text = text.replace(old, new)
        path = tmp_path / name
        path.write_text(text.replace("[lens]\n", f"[lens]\n{lens}\n").replace("[room]\n", f"[room]\n{room_}\n"))
        return path
    return write


@pytest.fixture(scope="session")
def mi():
    """Mitsuba with the variant lampfab picks (LLVM on CPU, CUDA where present)."""
    from lampfab.mi_env import mitsuba

    return mitsuba()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def tiny_design(tiny_profile):
    return profile.load_design(str(tiny_profile))


@pytest.fixture(scope="session")
def tiny_panel_design(tiny_panel_profile):
    return profile.load_design(str(tiny_panel_profile))


@pytest.fixture(scope="session")
def default_design():
    return profile.load_design("default")


@pytest.fixture(scope="session")
def mid_design(default_design):
    """The default profile with the light at mid-height, where a ball LED shining every way
    sits (the default's flat LED sits low): the geometry the optics tests were set on."""
    import dataclasses

    return dataclasses.replace(default_design, lens=dataclasses.replace(default_design.lens, light_height_mm=45.0))


@pytest.fixture(scope="session")
def cyl(default_design):
    lens = default_design.lens
    return surface.Cylinder(lens.outer_radius_mm, lens.height_mm)


@pytest.fixture(scope="session")
def inner_layer(default_design):
    from lampfab import inner as inner_mod

    lens = default_design.lens
    return inner_mod.load_inner(None, 1.0, room.light_position(default_design), lens.outer_radius_mm,
                                lens.max_offset_mm, lens.height_mm)


@pytest.fixture(scope="session")
def small_lens():
    """The small lens of ``helpers`` (CYL, bumps, inner) as a solid with a 6 mm bore."""
    from lampfab import solid

    v, f = inner()
    return solid.build_solid(CYL, bumps(), 2, v, f, mount_radius_mm=6.0)
