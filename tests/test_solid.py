"""The lens solid (manifold3d), on a small lens (fast)."""

import numpy as np
import pytest

from lampfab import solid, surface
from lampfab.errors import GeometryError, LampfabError
from lampfab.inner import winding_number

from tests.helpers import CYL, bumps, inner


def test_solid_is_closed_one_body_with_expected_volume(small_lens):
    topo = solid.edge_check(small_lens.faces)
    assert topo == {"watertight": True, "winding_consistent": True, "components": 1, "euler": 2}
    assert small_lens.genus == 0
    assert small_lens.vertices.dtype == np.float64 and small_lens.faces.dtype == np.int64
    assert solid.mesh_volume(small_lens.vertices, small_lens.faces) == pytest.approx(small_lens.volume_mm3, rel=1e-9)
    # Independent bookkeeping: outer mesh - inner cylinder - bore polygon prism under the floor.
    ov, of = surface.closed_outer_mesh(CYL, bumps(), 2)
    iv, inf = inner()
    bore = small_lens.bore
    assert (bore.z_floor_mm, bore.radius_mm) == (12.0, 6.0)
    expected = solid.mesh_volume(ov, of) - solid.mesh_volume(iv, inf) - bore.polygon_area_mm2 * 12.0
    assert small_lens.volume_mm3 == pytest.approx(expected, rel=1e-9)
    assert small_lens.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    assert small_lens.vertices[:, 2].max() == pytest.approx(80.0, abs=1e-12)


def test_cavity_opens_through_the_base(small_lens):
    v, f = small_lens.vertices, small_lens.faces
    # Up the axis from below the base to the LED: never inside the glass.
    for z in (-0.5, 0.01, 6.0, 11.99, 12.01, 40.0):
        assert abs(winding_number(v, f, np.array([0.0, 0.0, z]))) < 1e-6, z
    assert winding_number(v, f, np.array([30.0, 0.0, 40.0])) == pytest.approx(1.0, abs=1e-6)   # wall
    assert winding_number(v, f, np.array([10.0, 0.0, 6.0])) == pytest.approx(1.0, abs=1e-6)    # base beside bore
    assert winding_number(v, f, np.array([0.0, 0.0, 74.0])) == pytest.approx(1.0, abs=1e-6)   # roof


def test_bore_wider_than_the_inner_floor_is_refused():
    v, f = inner()       # 32-gon of radius 20: the floor reaches 20 cos(pi/32) = 19.90 mm
    with pytest.raises(LampfabError, match=r"mount_radius_mm 19\.6 is too large.*reaches 19\.90 mm.*<= 19\.40"):
        solid.build_solid(CYL, bumps(), 2, v, f, mount_radius_mm=19.6)
    assert solid.plan_bore(v, f, 19.3).floor_reach_mm == pytest.approx(20 * np.cos(np.pi / 32))


def test_the_bounds_a_refused_bore_names_are_accepted():
    import re

    v, f = inner(sections=1024, radius_mm=16.0)   # the floor reaches 16 cos(pi/1024): 15.99992 mm
    with pytest.raises(LampfabError) as refused:
        solid.plan_bore(v, f, 15.5)
    narrower, wider = (float(x) for x in re.search(r"<= ([0-9.]+) or >= ([0-9.]+)", str(refused.value)).groups())
    assert narrower == 15.49    # rounded down: 15.50 itself needs 16.00 mm of floor
    assert not solid.plan_bore(v, f, narrower).counterbore
    assert solid.plan_bore(v, f, wider).counterbore


def test_counterbore_opens_the_whole_floor():
    v, f = inner()       # the floor reaches 20 mm: a counterbore needs >= 20.5
    lens = solid.build_solid(CYL, bumps(), 2, v, f, mount_radius_mm=20.5)
    assert lens.bore.counterbore and lens.bore.z_top_mm == lens.bore.z_floor_mm == 12.0
    topo = solid.edge_check(lens.faces)
    assert topo["watertight"] and topo["winding_consistent"] and topo["components"] == 1
    ov, of = surface.closed_outer_mesh(CYL, bumps(), 2)
    expected = solid.mesh_volume(ov, of) - solid.mesh_volume(v, f) - lens.bore.polygon_area_mm2 * 12.0
    assert lens.volume_mm3 == pytest.approx(expected, rel=1e-9)
    for p in ((0.0, 0.0, 6.0), (19.0, 0.0, 11.9), (0.0, 0.0, 40.0)):       # in the counterbore and cavity
        assert abs(winding_number(lens.vertices, lens.faces, np.array(p))) < 1e-6, p
    for p in ((21.0, 0.0, 6.0), (20.3, 0.0, 12.1)):                        # glass beside it, the shoulder
        assert winding_number(lens.vertices, lens.faces, np.array(p)) == pytest.approx(1.0, abs=1e-6), p
    with pytest.raises(LampfabError, match=r"<= 19\.40 or >= 20\.50 \(a counterbore"):
        solid.plan_bore(v, f, 20.0)


def test_inner_layer_without_flat_bottom_is_refused():
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=2, radius=15.0)
    ball.apply_translation([0.0, 0.0, 40.0])
    with pytest.raises(LampfabError, match="no flat bottom"):
        solid.build_solid(CYL, bumps(), 2, np.asarray(ball.vertices), np.asarray(ball.faces, np.int64), 6.0)


def test_inner_layer_crossing_the_outer_surface_is_refused():
    v, f = inner(radius_mm=39.0)
    with pytest.raises(LampfabError, match="crosses the outer surface"):
        solid.build_solid(CYL, bumps(), 2, v, f, 6.0)


def test_manifold_status_becomes_geometry_error():
    v, f = inner()
    with pytest.raises(GeometryError, match="inner layer.*NotManifold"):
        solid.build_solid(CYL, bumps(), 2, v, f[:-1], 6.0)       # one triangle missing: open
    heights = bumps()
    heights[3, 0] = np.nan
    with pytest.raises(GeometryError, match="outer surface.*NonFiniteVertex"):
        solid.build_solid(CYL, heights, 2, v, f, 6.0)


def test_edge_check_sees_holes_flips_and_shells():
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    assert solid.edge_check(tet) == {"watertight": True, "winding_consistent": True, "components": 1, "euler": 2}
    assert not solid.edge_check(tet[:3])["watertight"]
    flipped = tet.copy()
    flipped[0] = flipped[0, ::-1]
    assert not solid.edge_check(flipped)["winding_consistent"]
    two = solid.edge_check(np.vstack([tet, tet + 4]))
    assert (two["components"], two["euler"]) == (2, 4)


def test_cavity_mesh_is_inner_plus_bore():
    v, f = inner()
    bore = solid.plan_bore(v, f, 6.0, 128)
    cavity, _ = solid._cavity(v, f, bore)
    cv, cf = solid._arrays(cavity)
    assert solid.edge_check(cf)["watertight"]
    expected = solid.mesh_volume(v, f) + bore.polygon_area_mm2 * (bore.z_floor_mm - bore.z_bottom_mm)
    assert solid.mesh_volume(cv, cf) == pytest.approx(expected, rel=1e-9)
    assert cv[:, 2].min() == pytest.approx(-1.0)
