"""The panel (the source's prior-work scene): its transport, its solid, and `make lamp`
with a tiny panel profile."""

import json

import numpy as np
import pytest

from lampfab import profile, room, solid
from lampfab.errors import LampfabError
from lampfab.panel import geometry as panel
from lampfab.panel import transport as panel_transport

from tests.helpers import make

SHAPE = panel.PanelShape(100.0, 100.0, 10.0)


@pytest.fixture(scope="module")
def wall(tiny_panel_design):
    return room.walls(tiny_panel_design)[0]


def test_transport_sends_the_light_where_the_target_has_it(wall):
    """A target lit only in its upper-left quarter: every node's light lands there, and
    the light's centroid on the wall is the quarter's centre."""
    target = np.zeros((16, 16))
    target[:8, :8] = 1.0
    goal, err = panel_transport.target_map(SHAPE, wall, target, (17, 17))
    x, z = goal[..., 0], goal[..., 2]
    left, top = wall.origin[0], wall.origin[2]
    assert err < 1e-3
    assert np.all(goal[..., 1] == wall.origin[1])
    # Within the lit quarter, give or take the entropic blur (about a pixel, 25 mm).
    assert np.all(x < left + 0.5 * wall.width_mm + 30) and np.all(z > top - 0.5 * wall.height_mm - 30)
    mass = panel_transport.beam_mass(17, 17)
    assert np.sum(mass * x) == pytest.approx(left + 0.25 * wall.width_mm, abs=10)
    assert np.sum(mass * z) == pytest.approx(top - 0.25 * wall.height_mm, abs=10)


def test_designed_relief_refracts_each_node_to_its_goal(wall):
    """The relief's own normals send the beam where the transport asked (finite
    distance included), and a uniform target makes a diverging (concave) relief."""
    target = np.ones((16, 16))
    heights, figs = panel_transport.design(SHAPE, wall, target, 1.5, (17, 17), 3, 2, 1e-3, 8.0, 45.0,
                                           log=lambda _: None)
    assert figs["aim_error_deg"][-1] < 0.05
    d = panel_transport.refracted(panel_transport.spline_normals(SHAPE, heights), 1.5)
    p = panel.points(SHAPE, heights)
    hit = p + ((wall.origin[1] - p[..., 1]) / d[..., 1])[..., None] * d
    goal, _ = panel_transport.target_map(SHAPE, wall, target, (17, 17))
    assert np.abs(hit - goal).max() < 5.0  # mm on a wall 1.5 m away
    assert heights[8, 8] < heights[0, 8] and heights[8, 8] < heights[8, 0]  # thinner in the middle


def test_closed_mesh_is_one_outward_solid_of_the_right_volume():
    heights = np.random.default_rng(1).normal(scale=0.5, size=(9, 7))
    v, f = panel.closed_mesh(SHAPE, heights, 3)
    edges = solid.edge_check(f)
    assert edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1
    mx, mz = panel.fine_shape(9, 7, 3)
    fine = panel.sample(SHAPE, heights, mx, mz)
    # Volume = the trapezoid-rule integral of the thickness over the face.
    wx = np.full(mx, SHAPE.width_mm / (mx - 1))
    wz = np.full(mz, SHAPE.height_mm / (mz - 1))
    wx[[0, -1]] /= 2
    wz[[0, -1]] /= 2
    expected = float(wx @ (SHAPE.thickness_mm + fine) @ wz)
    assert solid.mesh_volume(v, f) == pytest.approx(expected, rel=1e-3)


def test_panel_profile_is_strict(tmp_path, tiny_panel_profile):
    tiny = tiny_panel_profile.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(tiny.replace('kind = "panel"', 'kind = "panel"\nouter_radius_mm = 40.0'))
    with pytest.raises(LampfabError, match=r"\[lens\] outer_radius_mm applies only to kind"):
        profile.load_design(str(bad))
    bad.write_text(tiny.replace("max_relief_mm = 4.0", "max_relief_mm = 12.0"))
    with pytest.raises(LampfabError, match="max_relief_mm 12.0 must be below thickness_mm"):
        profile.load_design(str(bad))
    bad.write_text(tiny.replace('kind = "panel"\n', ""))
    with pytest.raises(LampfabError, match=r"\[panel\] applies only"):
        profile.load_design(str(bad))


@pytest.mark.slow
@pytest.mark.e2e
def test_make_lamp_with_a_panel(tmp_path, tiny_panel_profile):
    from lampfab.export import step_file, stl

    run = make("lamp", f"BUILD={tmp_path}", "NAME=apple", f"PROFILE={tiny_panel_profile}")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    out = tmp_path / "apple"
    for name in ["lens.stl", "lens.step", "lens.glb", "design.json", "checks.json", "checks.png", "report.html"]:
        assert (out / name).is_file(), name
    v, f = stl.read_stl(out / "lens.stl")
    back = step_file.read_step(out / "lens.step")
    assert back["n_solids"] == 1 and back["valid"] and back["closed"] and back["faces"] == 6
    assert back["volume_mm3"] == pytest.approx(solid.mesh_volume(v, f), rel=1e-3)
    checks = {c["name"]: c for c in json.loads((out / "checks.json").read_text())["figures"]["checks"]}
    for name in ("cavity_overhang", "drain", "cavity_access"):
        assert not checks[name]["applies"] and checks[name]["note"] == "not applicable to a panel"
    assert checks["min_wall"]["applies"] and checks["min_wall"]["passed"]
    wall = json.loads((out / "verify.json").read_text())["figures"]["walls"]["front"]
    assert wall["pearson"] > 0.8 and wall["share"] > 0.8
