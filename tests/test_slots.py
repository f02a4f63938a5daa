"""Black-filled slots at the sectors' edges: where they go, the solid and the STEP cut
around them, the facets verify paints black, and the light they stop."""

import numpy as np
import pytest

from lampfab import paint, slots, solid, surface
from lampfab.checks.mesh import inspect_mesh
from lampfab.errors import LampfabError
from lampfab.inner import winding_number
from lampfab.tolerances import VOLUME_REL

from tests.helpers import CYL, bumps, inner

SECTORS = {"right": (-45.0, 45.0), "front": (45.0, 135.0), "left": (135.0, 225.0)}
CAVITY_REACH_MM = 20.0  # helpers.inner's hollow
WALL_MM = 1.0


def _plan(width_mm=1.0, heights=None):
    outer = surface.closed_outer_vertices(CYL, bumps() if heights is None else heights, 2)[:-2]
    return slots.plan(width_mm, SECTORS, CAVITY_REACH_MM, outer, CYL.height_mm, WALL_MM), outer


@pytest.fixture(scope="module")
def slotted():
    planned, _ = _plan()
    v, f = inner()
    return planned, solid.build_solid(CYL, bumps(), 2, v, f, mount_radius_mm=6.0, slots=planned)


def _box_distance(points, cut, s):
    """3D distance (mm) from (n, 3) points to slot ``s``'s box above the base."""
    a = np.radians(s.azimuth_deg)
    along = points[:, 0] * np.cos(a) + points[:, 1] * np.sin(a)
    across = -points[:, 0] * np.sin(a) + points[:, 1] * np.cos(a)
    gaps = [np.maximum(np.maximum(s.from_mm - along, along - s.to_mm), 0.0),
            np.maximum(np.abs(across) - 0.5 * cut.width_mm, 0.0),
            np.maximum(np.maximum(-points[:, 2], points[:, 2] - cut.top_mm), 0.0)]
    return np.sqrt(sum(g ** 2 for g in gaps))


def test_a_slot_stands_at_each_sector_edge_as_far_out_as_the_wall_allows():
    cut, outer = _plan()
    assert [s.azimuth_deg for s in cut.slots] == [45.0, 135.0, 225.0, 315.0]
    assert cut.top_mm == CYL.height_mm - slots.TOP_MARGIN_MM
    for s in cut.slots:
        assert s.from_mm == CAVITY_REACH_MM + WALL_MM
        gap = _box_distance(outer, cut, s).min()
        # The outer surface keeps the thinnest wall, and no more: the slot reaches it.
        assert WALL_MM - 1e-9 <= gap < WALL_MM + 0.05
    assert cut.glass_mm3 == pytest.approx(sum(s.to_mm - s.from_mm for s in cut.slots) * cut.top_mm)
    assert slots.Slots.from_json(cut.to_json()) == cut
    assert slots.plan(0.0, SECTORS, CAVITY_REACH_MM, outer, CYL.height_mm, WALL_MM) is None


def test_an_outer_surface_too_close_to_the_cavity_leaves_no_slot():
    dent = bumps()
    dent[4] = -17.0   # one node column, 45° round: the surface comes in to 23 mm
    with pytest.raises(LampfabError, match=r"sector edge u = 45\.0 deg.*set \[lens\] slot_width_mm = 0"):
        _plan(heights=dent)


def test_the_solid_loses_exactly_the_slots_and_stays_one_clean_body(slotted):
    cut, lens = slotted
    plain = solid.build_solid(CYL, bumps(), 2, *inner(), mount_radius_mm=6.0)
    assert lens.volume_mm3 == pytest.approx(plain.volume_mm3 - cut.glass_mm3, rel=1e-9)
    assert solid.edge_check(lens.faces) == {"watertight": True, "winding_consistent": True, "components": 1,
                                            "euler": 2}
    report = inspect_mesh(lens.vertices, lens.faces)
    assert report.self_intersecting_faces == 0
    for s in cut.slots:
        a = np.radians(s.azimuth_deg)
        along, across = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
        mid = 0.5 * (s.from_mm + s.to_mm) * along
        inside = [mid + [0, 0, z] for z in (0.01, 40.0, cut.top_mm - 0.1)]   # open through the base
        glass = [mid + [0, 0, cut.top_mm + 0.5], mid + 0.8 * across + [0, 0, 40.0],
                 (s.to_mm + 0.5) * along + [0, 0, 40.0], (s.from_mm - 0.5) * along + [0, 0, 40.0]]
        for p in inside:
            assert abs(winding_number(lens.vertices, lens.faces, p)) < 1e-6, (s, p)
        for p in glass:
            assert winding_number(lens.vertices, lens.faces, p) == pytest.approx(1.0, abs=1e-6), (s, p)


def test_the_slots_walls_are_black_whatever_the_paint(slotted):
    cut, lens = slotted
    centre = lens.vertices[lens.faces].mean(axis=1)
    for choice in ("none", "top_and_base"):
        painted = paint.painted_faces(lens.vertices, lens.faces, choice, CYL.height_mm, slots=cut)
        ends = paint.painted_faces(lens.vertices, lens.faces, choice, CYL.height_mm)
        black = painted & ~ends
        # Each slot's two long walls, its two ends and its roof, and nothing else.
        for s in cut.slots:
            near = _box_distance(centre, cut, s) < 1e-6
            assert (black & near).sum() >= 5 and np.array_equal(black & near, near & ~ends)
        assert not (black & ~np.any([_box_distance(centre, cut, s) < 1e-6 for s in cut.slots], axis=0)).any()
    from_json = paint.painted_from_json(lens.vertices, lens.faces, {"black_paint": "none", "slots": cut.to_json()})
    assert np.array_equal(from_json, paint.painted_faces(lens.vertices, lens.faces, "none", CYL.height_mm, slots=cut))


def test_rays_that_enter_a_slot_are_stopped(mi):
    cut, _ = _plan()
    s = cut.slots[0]   # at 45°, from 21 mm out
    a = np.radians(s.azimuth_deg)
    along, across = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
    rays = [  # (origin, direction, stopped?)
        (np.array([0.0, 0.0, 40.0]), along, True),                                  # into the slot's floor
        (np.array([0.0, 0.0, 40.0]), np.array([np.cos(a + 0.05), np.sin(a + 0.05), 0]), False),  # beside it
        (30.0 * along - 3 * across + [0, 0, 40], across, True),                     # across it, in the glass
        (30.0 * along - 3 * across + [0, 0, cut.top_mm + 1], across, False),        # across, above it
        (30.0 * along - 3 * across + [0, 0, 40], -across, False),                   # away from it
        ((s.to_mm + 2) * along - 3 * across + [0, 0, 40], across, False),           # past its outer end
    ]
    o = mi.Point3f(*(np.array([r[0][k] for r in rays], np.float32) for k in range(3)))
    d = mi.Vector3f(*(np.array([r[1][k] for r in rays], np.float32) for k in range(3)))
    assert cut.stops(mi, o, d).numpy().tolist() == [r[2] for r in rays]


def test_the_step_solid_has_the_slots_as_pockets_in_its_base(tmp_path, slotted):
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    from lampfab.export import step_file

    cut, lens = slotted
    info = step_file.write_step(tmp_path / "lens.step", CYL, bumps(), *inner(), 6.0, 64, 15,
                                expected_volume_mm3=lens.volume_mm3, slots=cut)
    plain = step_file.write_step(tmp_path / "plain.step", CYL, bumps(), *inner(), 6.0, 64, 15)
    back = step_file.read_step(tmp_path / "lens.step")
    assert back["n_solids"] == 1 and back["valid"] and back["closed"]
    assert back["volume_mm3"] == pytest.approx(lens.volume_mm3, rel=VOLUME_REL)   # B-spline vs facets
    # Four walls and a roof each, and exactly their glass less than the lens without them.
    assert info["faces"] == plain["faces"] + 5 * len(cut.slots)
    assert plain["volume_mm3"] - back["volume_mm3"] == pytest.approx(cut.glass_mm3, rel=1e-6)
    reader = STEPControl_Reader()
    reader.ReadFile(str(tmp_path / "lens.step"))
    reader.TransferRoots()
    shape = reader.OneShape()
    for s in cut.slots:
        a = np.radians(s.azimuth_deg)
        along, across = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
        mid = 0.5 * (s.from_mm + s.to_mm) * along
        for p, state in ((mid + [0, 0, 40.0], TopAbs_OUT), (mid + [0, 0, 0.2], TopAbs_OUT),
                         (mid + [0, 0, cut.top_mm + 0.5], TopAbs_IN), (mid + 0.8 * across + [0, 0, 40.0], TopAbs_IN)):
            where = BRepClass3d_SolidClassifier(shape, gp_Pnt(*map(float, p)), 1e-6)
            assert where.State() == state, (s, p)
