"""Black paint on the faces that light no wall: which facets, and that light ends there
in lampfab's tracer and in Mitsuba's."""

import numpy as np
import pytest

from lampfab import mitsuba_reference, paint, trace
from lampfab.room import Wall
from lampfab.source import Source

from .helpers import CYL

LIGHT = (0.0, 0.0, 40.0)
FRONT = Wall("front", np.array([-900.0, 1000.0, 715.0]), np.array([1800.0, 0, 0]), np.array([0, 0, -1350.0]))


def _centres_normals(lens):
    tri = lens.vertices[lens.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return tri.mean(axis=1), normal / np.linalg.norm(normal, axis=1, keepdims=True)


def test_the_top_and_the_base_are_the_flat_faces_at_the_lens_ends(small_lens):
    centre, normal = _centres_normals(small_lens)
    painted = paint.painted_faces(small_lens.vertices, small_lens.faces, "top_and_base", CYL.height_mm)
    assert np.all(np.isin(np.round(centre[painted, 2], 6), [0.0, CYL.height_mm]))
    assert np.allclose(np.abs(normal[painted, 2]), 1.0)
    radius = np.hypot(centre[:, 0], centre[:, 1])
    assert radius[painted].min() > 6.0  # the bore's wall (6 mm) stays clear: the LED goes in there
    # Every flat facet at either end, top and base alike; the hollow's floor is inside.
    ends = (np.abs(normal[:, 2]) > 0.999) & np.isin(np.round(centre[:, 2], 6), [0.0, CYL.height_mm])
    assert np.array_equal(painted, ends) and (centre[painted, 2] > 1).any() and (centre[painted, 2] < 1).any()
    assert not paint.painted_faces(small_lens.vertices, small_lens.faces, "none", CYL.height_mm).any()


def test_the_back_is_the_outer_surface_where_no_wall_s_sector_lies(small_lens):
    centre, normal = _centres_normals(small_lens)
    back = paint.free_span_deg({"right": (-50.6, 39.4), "front": (39.4, 129.4), "left": (129.4, 225.0)})
    assert back == pytest.approx((225.0, 309.4))
    painted = paint.painted_faces(small_lens.vertices, small_lens.faces, "top_base_and_back", CYL.height_mm, back)
    ends = paint.painted_faces(small_lens.vertices, small_lens.faces, "top_and_base", CYL.height_mm)
    sides = painted & ~ends
    u = np.degrees(np.arctan2(centre[:, 1], centre[:, 0])) % 360
    outward = np.einsum("ij,ij->i", normal[:, :2], centre[:, :2]) > 0
    assert sides.sum() > 100 and np.all((u[sides] > 225.0) & (u[sides] < 309.4)) and outward[sides].all()
    # The hollow's wall behind the back stays clear.
    assert not (painted & ~outward & (u > 240) & (u < 300) & (centre[:, 2] > 20) & (centre[:, 2] < 60)).any()
    assert np.array_equal(painted & ends, ends)
    assert paint.free_span_deg({"right": (-45, 45), "front": (45, 135), "left": (135, 225), "floor": (225, 315)}) \
        is None


def test_light_ends_on_painted_faces_in_both_tracers(mi, small_lens):
    """Painted ends swallow much of the light reflected inside the lens, and what of the
    LED's own light leaves through them (this undesigned lens sends some there); Mitsuba's
    light tracer, given the same paint, loses as large a share of the wall's light."""
    painted = paint.painted_faces(small_lens.vertices, small_lens.faces, "top_and_base", CYL.height_mm)
    point = Source(LIGHT)
    shapes = [(12, 16)]
    images, info, mitsuba = {}, {}, {}
    for name, mask in (("clear", None), ("painted", painted)):
        scene = trace.MeshScene(small_lens.vertices, small_lens.faces, mask)
        (images[name],), info[name] = trace.render_walls(scene, point, 1.5, [FRONT], shapes, 400_000, seed=2)
        mitsuba[name] = mitsuba_reference.render(small_lens.vertices, small_lens.faces, 1.5, point, [FRONT],
                                                 shapes, 400_000, 3, mask)[0]
    ghosts = {name: float(info[name]["ghosts"][0].sum()) for name in info}
    assert ghosts["painted"] < 0.8 * ghosts["clear"]
    assert images["painted"].sum() - ghosts["painted"] < images["clear"].sum() - ghosts["clear"]
    lost = 1 - images["painted"].sum() / images["clear"].sum()
    assert lost > 0.05
    assert 1 - mitsuba["painted"].sum() / mitsuba["clear"].sum() == pytest.approx(lost, abs=0.03)
