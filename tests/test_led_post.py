"""The fins' part a maker prints for a post: one closed solid that slides over the rod,
with fins where the optics put them and room for the LED boards."""

import numpy as np
import pytest

from lampfab import led_post, profile, solid
from lampfab.source import Source


@pytest.fixture(scope="module")
def part():
    led = profile.load_led("post3535")
    fins = Source.of_led(np.array([0.0, 0.0, 45.0]), led, [0.0, 90.0, 270.0]).fin_azimuths_deg()
    v, f = led_post.fin_part(led, 45.0, fins)
    return led, v, f


def test_the_fins_part_is_one_closed_solid_that_passes_the_bore(part):
    led, v, f = part
    edges = solid.edge_check(f)
    assert edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1
    assert solid.mesh_volume(v, f) > 0
    assert v[:, 2].min() == pytest.approx(20.0) and v[:, 2].max() == pytest.approx(70.0)
    assert np.hypot(v[:, 0], v[:, 1]).max() < 0.5 * led.board_diameter_mm  # through the bore


def _inside(v, f, points):
    """(n,) bool: whether each point lies in the solid (a 0.02 mm cube there meets it)."""
    import manifold3d

    m = solid._manifold(v, f, "the fins' part")
    cube = manifold3d.Manifold.cube((0.02, 0.02, 0.02), True)
    return np.array([(m ^ cube.translate(tuple(p))).volume() > 0 for p in np.asarray(points, float)])


def test_the_fins_stand_at_the_rods_corners_and_leave_the_rod_and_boards_free(part):
    led, v, f = part
    # On each fin, halfway out and a little off the LEDs' height: glass-black plastic.
    corners = np.radians([45.0, 135.0, 225.0, 315.0])
    on_fins = np.stack([7.0 * np.cos(corners), 7.0 * np.sin(corners), np.full(4, 50.0)], 1)
    assert _inside(v, f, on_fins).all()
    # Between the fins, in front of each face, at every height: nothing (the light's way).
    faces = np.radians([0.0, 90.0, 180.0, 270.0])
    between = np.concatenate([np.stack([r * np.cos(faces), r * np.sin(faces), np.full(4, z)], 1)
                              for r in (5.0, 9.0) for z in (30.0, 45.0, 60.0)])
    assert not _inside(v, f, between).any()
    # The rod's square (with its corners) and each LED board at the LEDs' height: nothing.
    h = 0.5 * led.rod_width_mm
    g = np.linspace(-h, h, 9)
    rod = np.stack(np.meshgrid(g, g, [22.0, 45.0, 68.0]), -1).reshape(-1, 3)
    # The board on the front face, from the rod out to the LED's face, over its height.
    boards = np.stack(np.meshgrid(np.linspace(h, led.offset_mm, 5), np.linspace(-h, h, 17), [43.5, 45.0, 46.5]),
                      -1).reshape(-1, 3)
    assert not _inside(v, f, np.concatenate([rod, boards])).any()
