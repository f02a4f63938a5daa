"""Shared fixtures: tiny designs, seeded randomness, the Mitsuba variant."""

from pathlib import Path

import numpy as np
import pytest

from lampfab import profile, room, surface

DATA = Path(__file__).parent / "data"
TINY = DATA / "tiny.toml"


@pytest.fixture(scope="session")
def mi():
    """Mitsuba with the variant lampfab picks (LLVM on CPU, CUDA where present)."""
    from lampfab.mi_env import mitsuba

    return mitsuba()


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def tiny_design():
    return profile.load_design(str(TINY))


@pytest.fixture(scope="session")
def default_design():
    return profile.load_design("default")


@pytest.fixture(scope="session")
def cyl(default_design):
    lens = default_design.lens
    return surface.Cylinder(lens.outer_radius_mm, lens.height_mm)


@pytest.fixture(scope="session")
def inner_layer(default_design):
    from lampfab import inner

    lens = default_design.lens
    return inner.load_inner(None, 1.0, room.light_position(default_design), lens.outer_radius_mm,
                            lens.max_offset_mm, lens.height_mm)
