"""Fabrication checks (lampfab.checks): each check on a small synthetic lens built to fail
it, the worst place where the defect was put, and a plain lens that passes.

Lenses are small (R 30 mm, H 40 mm, 64 x 16 nodes, 256 x 64 samples) so every test runs
in a second or two; solids are built here with manifold3d (not lampfab.solid).
"""

from __future__ import annotations

import dataclasses

import manifold3d as m3
import numpy as np
import pytest

from lampfab import checks, surface
from lampfab.checks.distance import closest_on_triangles, distance_to_mesh
from lampfab.checks.fields import compute_fields
from lampfab.profile import PROFILE_DIR, Fabrication, load_fabrication

R, H = 30.0, 40.0
NU, NV = 64, 16
SAMPLES = (256, 61)  # 4 samples per cell edge each way (curvature.sample_counts)
ROOT_FAB = PROFILE_DIR / "fab"
CYL = surface.Cylinder(R, H)
LIGHT = np.array([0.0, 0.0, 20.0])


# ------------------------------------------------------------------ builders

def _manifold(v, f):
    m = m3.Manifold(m3.Mesh(vert_properties=np.asarray(v, np.float32), tri_verts=np.asarray(f, np.uint32)))
    assert m.status() == m3.Error.NoError
    return m


def _arrays(m):
    mesh = m.to_mesh()
    return np.asarray(mesh.vert_properties[:, :3], np.float64), np.asarray(mesh.tri_verts, np.int64)


def inner_cylinder(r=12.0, z0=6.0, z1=34.0, sections=64):
    """A closed cylinder around the light, wound outward: ((n, 3) mm, (m, 3))."""
    return _arrays(m3.Manifold.cylinder(z1 - z0, r, r, sections).translate((0, 0, z0)))


def inner_cone_roof(r=10.0, z0=6.0, z1=26.0, roof_deg=50.0, sections=64):
    """A cylinder with a conical roof leaning roof_deg from horizontal (self-supporting)."""
    body = m3.Manifold.cylinder(z1 - z0, r, r, sections).translate((0, 0, z0))
    cone = m3.Manifold.cylinder(r * np.tan(np.radians(roof_deg)), r, 0.0, sections).translate((0, 0, z1))
    return _arrays(body + cone)


def solid(heights, inner, bore_r=5.0, tess=2):
    """Outer surface (closed by caps) minus the cavity minus the bore through the base."""
    ov, of = surface.closed_outer_mesh(CYL, heights, tess)
    s = _manifold(ov, of) - _manifold(*inner)
    if bore_r > 0:
        floor = float(inner[0][:, 2].min())
        s = s - m3.Manifold.cylinder(floor + 1.5, bore_r, bore_r, 48).translate((0, 0, -1.0))
    assert s.status() == m3.Error.NoError
    return _arrays(s)


def bump(u_deg, z_mm, amp_mm, su_deg, sz_mm):
    """Heightmap nodes (NU, NV) of a Gaussian bump (amp > 0 out, < 0 in)."""
    u = np.degrees(CYL.node_u(NU))[:, None]
    z = CYL.node_z(NV)[None, :]
    du = (u - u_deg + 180.0) % 360.0 - 180.0
    return amp_mm * np.exp(-0.5 * ((du / su_deg) ** 2 + ((z - z_mm) / sz_mm) ** 2))


def fab_for(process="cnc4", **kw):
    base = dict(name="test", process=process, min_wall_mm=1.5, max_slope_deg=60.0,
                tool_radius_mm=3.0 if process.startswith("cnc") else 0.0,
                build_x_mm=200.0, build_y_mm=200.0, build_z_mm=200.0, mount_radius_mm=5.0)
    base.update(kw)
    return Fabrication(**base)


def run(heights, inner, fab, bore_r=5.0, solid_mesh=None, light=LIGHT):
    sv, sf = solid_mesh if solid_mesh is not None else solid(heights, inner, bore_r)
    res = checks.run_checks(CYL, heights, *inner, sv, sf, fab, light, samples=SAMPLES)
    assert [r.name for r in res] == list(checks.NAMES)
    return {r.name: r for r in res}


def near(worst, u_deg, z_mm, du=4.0, dz=2.5):
    d = (worst["u_deg"] - u_deg + 180.0) % 360.0 - 180.0
    return abs(d) <= du and abs(worst["z_mm"] - z_mm) <= dz


PLAIN = np.zeros((NU, NV))
DIMPLE = bump(300.0, 15.0, -4.0, np.degrees(3.0 / R), 3.0)  # 4 mm deep, sigma 3 mm


# ------------------------------------------------------------------ passing lenses

def test_plain_cylinder_passes_every_check_cnc4():
    # A narrow cavity (r 4) under a wider bore (r 5): a tool reaches it through the bore.
    res = run(PLAIN, inner_cylinder(r=4.0), fab_for("cnc4"))
    bad = [r.name for r in res.values() if not r.passed]
    assert bad == []
    assert res["tool_radius"].applies and res["tool_radius"].value is None   # convex everywhere
    assert not res["overhang"].applies and not res["cavity_overhang"].applies
    assert res["min_wall"].value == pytest.approx(6.0)                          # both caps 6 mm


def test_plain_cylinder_passes_every_check_sla_with_self_supporting_roof():
    res = run(PLAIN, inner_cone_roof(), fab_for("sla", min_wall_mm=1.0))
    assert [r.name for r in res.values() if not r.passed] == []
    assert not res["tool_radius"].applies and not res["cavity_access"].applies
    assert res["overhang"].value == pytest.approx(0.0, abs=1e-9)
    assert res["cavity_overhang"].value == pytest.approx(40.0, abs=0.5)        # 50 deg roof
    import json

    stored = json.loads(json.dumps([r.to_json() for r in res.values()]))           # plain JSON
    assert [checks.CheckResult.from_json(r) for r in stored] == list(res.values())


def test_side_wall_matches_geometry():
    inner = inner_cylinder(r=12.0, sections=64)
    f = compute_fields(CYL, PLAIN, *inner, 5.0, SAMPLES)
    # Outer radius 30 against a 64-gon of circumradius 12: between 30 - 12 (at its
    # vertices) and 30 - 12 cos(pi/64) (mid-facet); manifold3d stores float32 (~1e-6).
    mid = f.wall[:, (f.z > 8) & (f.z < 32)]
    assert mid.min() == pytest.approx(18.0, abs=1e-5)
    # Far from the mesh the distance comes from a coarser sample: <= 0.5 % too large.
    assert mid.max() <= (30 - 12 * np.cos(np.pi / 64)) * 1.005
    assert f.wall_top == pytest.approx(6.0) and f.wall_base == pytest.approx(6.0)


# ------------------------------------------------------------------ min_wall

def test_thin_wall_fails_at_the_dent():
    inner = inner_cylinder(r=20.0, z0=4.0, z1=36.0)
    h = bump(100.0, 20.0, -9.5, 12.0, 5.0)           # outer radius down to ~20.5 at the dent
    res = run(h, inner, fab_for("sla", min_wall_mm=1.0))
    r = res["min_wall"]
    assert not r.passed and r.value < 1.0
    assert near(r.worst, 100.0, 20.0)


def test_outer_surface_inside_the_cavity_gives_a_negative_wall():
    inner = inner_cylinder(r=20.0, z0=4.0, z1=36.0)
    h = bump(250.0, 20.0, -14.0, 15.0, 6.0)          # down to radius ~16: through the cavity
    sv, sf = _arrays(_manifold(*surface.closed_outer_mesh(CYL, h, 2)))  # any valid solid will do
    res = run(h, inner, fab_for("sla", min_wall_mm=1.0), solid_mesh=(sv, sf))
    r = res["min_wall"]
    assert r.value < -3.0 and not r.passed
    assert near(r.worst, 250.0, 20.0)


def test_thin_top_cap_fails_at_the_top():
    inner = inner_cylinder(r=10.0, z0=6.0, z1=H - 0.6)
    res = run(PLAIN, inner, fab_for("sla", min_wall_mm=1.0))
    r = res["min_wall"]
    assert r.value == pytest.approx(0.6, abs=1e-4) and not r.passed
    assert r.worst["z_mm"] == pytest.approx(H) and "top cap" in r.note


# ------------------------------------------------------------------ max_slope

def test_sharp_bump_fails_slope_on_its_flank():
    h = bump(200.0, 25.0, 4.0, 8.0, 3.0)              # flanks ~40 deg steep in z
    res = run(h, inner_cylinder(), fab_for("cnc4", max_slope_deg=30.0))
    r = res["max_slope"]
    assert not r.passed and r.value > 30.0
    assert near(r.worst, 200.0, 25.0, du=5.0, dz=4.5)
    assert abs(r.worst["z_mm"] - 25.0) > 1.0       # on a flank, not on the flat top


def test_slope_agrees_with_surface_slopes_deg():
    h = bump(200.0, 25.0, 2.0, 10.0, 4.0)
    f = compute_fields(CYL, h, *inner_cylinder(), 5.0, SAMPLES)
    ref, _ = surface.slopes_deg(CYL, h, *SAMPLES)
    # Both come from the spline's exact derivatives on the same samples.
    assert np.abs(f.slope - ref)[:, 2:-2].max() < 0.5


# ------------------------------------------------------------------ tool_radius

def test_small_concave_dimple_fails_tool_radius_on_cnc():
    h = DIMPLE                                        # bottom radius ~ sigma^2 / depth = 2.25 mm
    res = run(h, inner_cylinder(r=8.0), fab_for("cnc4"))
    r = res["tool_radius"]
    assert r.applies and not r.passed and r.value < 3.0
    assert near(r.worst, 300.0, 15.0, du=3.0, dz=1.5)


def test_tool_radius_does_not_apply_to_sla():
    r = run(DIMPLE, inner_cylinder(r=8.0), fab_for("sla"))["tool_radius"]
    assert not r.applies and r.passed and r.value is None


def test_concave_radius_of_a_known_trough():
    # s(z) = a cos(2 pi z / L) rings: at a trough the z-curvature is a (2 pi / L)^2 toward
    # the outside, the u-direction stays convex; concave radius 1 / (a (2 pi / L)^2).
    z = CYL.node_z(64)
    a, L = 0.5, 10.0
    h = np.tile(a * np.cos(2 * np.pi * z / L), (NU, 1))
    f = compute_fields(CYL, h, *inner_cylinder(r=8.0), 5.0, (256, 400))
    inside = f.concave_radius[:, (f.z > 8) & (f.z < 32)]
    assert inside.min() == pytest.approx(1.0 / (a * (2 * np.pi / L) ** 2), rel=0.02)


# ------------------------------------------------------------------ overhang (SLA)

def test_flaring_bump_fails_overhang_below_it():
    h = bump(45.0, 20.0, 5.0, 20.0, 2.5)             # lower flank faces down, ~55 deg
    res = run(h, inner_cone_roof(), fab_for("sla", min_wall_mm=1.0, max_slope_deg=89.0))
    r = res["overhang"]
    assert not r.passed and r.value > 45.0
    assert near(r.worst, 45.0, 17.5, du=4.0, dz=2.5) and r.worst["z_mm"] < 20.0


def test_flat_cavity_roof_fails_cavity_overhang_at_the_ceiling():
    res = run(PLAIN, inner_cylinder(r=12.0, z1=34.0), fab_for("sla", min_wall_mm=1.0))
    r = res["cavity_overhang"]
    assert not r.passed and r.value == pytest.approx(90.0)
    assert r.worst["z_mm"] == pytest.approx(34.0, abs=1e-4)
    assert np.hypot(*r.worst["xyz_mm"][:2]) < 1.0    # the middle of the ceiling


# ------------------------------------------------------------------ build_volume

def test_oversize_fails_build_volume_at_the_bulge():
    h = bump(90.0, 20.0, 5.0, 20.0, 8.0)             # y reaches 35 mm: 65 mm across
    res = run(h, inner_cylinder(), fab_for("cnc4", build_x_mm=62.0, build_y_mm=62.0))
    r = res["build_volume"]
    assert not r.passed and r.value == pytest.approx(65.0 / 62.0, abs=0.01)
    assert near(r.worst, 90.0, 20.0, du=5.0, dz=4.0)


def test_build_volume_allows_turning_the_part():
    h = bump(90.0, 20.0, 5.0, 20.0, 8.0)             # 60 x 65 fits 70 x 62 turned by 90 deg
    r = run(h, inner_cylinder(), fab_for("cnc4", build_x_mm=62.0, build_y_mm=70.0))["build_volume"]
    assert r.passed


# ------------------------------------------------------------------ mesh_valid

def test_hole_fails_mesh_valid_at_the_hole():
    sv, sf = solid(PLAIN, inner_cylinder())
    hole_at = np.array([0.0, R, 20.0])                # u = 90 deg
    c = sv[sf].mean(axis=1)
    sf = sf[np.linalg.norm(c - hole_at, axis=1) > 2.0]
    r = run(PLAIN, inner_cylinder(), fab_for("cnc4"), solid_mesh=(sv, sf))["mesh_valid"]
    assert not r.passed and "boundary edges" in r.note
    assert np.linalg.norm(np.array(r.worst["xyz_mm"]) - hole_at) < 3.0


def test_self_intersection_fails_mesh_valid_there():
    sv, sf = solid(PLAIN, inner_cylinder())
    box_v, box_f = _arrays(m3.Manifold.cube((4, 4, 4), True).translate((0.0, -R, 20.0)))  # u = 270
    v = np.vstack([sv, box_v])
    f = np.vstack([sf, box_f + len(sv)])
    r = run(PLAIN, inner_cylinder(), fab_for("cnc4"), solid_mesh=(v, f))["mesh_valid"]
    assert not r.passed and r.value >= 2                 # crossing faces + a second body
    assert near(r.worst, 270.0, 20.0, du=6.0, dz=3.0)


def test_triangle_soup_is_welded_and_passes():
    sv, sf = solid(PLAIN, inner_cylinder())
    soup_v, soup_f = sv[sf].reshape(-1, 3), np.arange(3 * len(sf)).reshape(-1, 3)
    r = run(PLAIN, inner_cylinder(), fab_for("cnc4"), solid_mesh=(soup_v, soup_f))["mesh_valid"]
    assert r.passed and "Welded" in r.note


# ------------------------------------------------------------------ drain / cavity access

def test_sealed_cavity_fails_drain_at_the_void():
    inner = inner_cylinder(r=8.0, z0=10.0, z1=30.0)
    sv, sf = solid(PLAIN, inner, bore_r=0.0)           # no bore: the cavity is sealed
    res = run(PLAIN, inner, fab_for("sla", min_wall_mm=1.0), solid_mesh=(sv, sf))
    r = res["drain"]
    assert not r.passed and r.value == 1
    assert r.worst["z_mm"] == pytest.approx(20.0, abs=0.5)
    assert np.hypot(*r.worst["xyz_mm"][:2]) < 1.0
    assert res["mesh_valid"].passed                   # a void is not a second body


def test_led_inside_material_fails_drain():
    r = run(PLAIN, inner_cylinder(), fab_for("cnc4"), light=np.array([20.0, 0.0, 20.0]))["drain"]
    assert not r.passed and "inside material" in r.note


def test_plain_cylinder_on_two_3axis_setups_fails_tool_axis_at_the_sides():
    # Two setups 180 deg apart: the cylinder's sides, halfway between them, are parallel to the tool.
    r = run(PLAIN, inner_cylinder(r=4.0), fab_for("cnc3", setups=2, max_tool_angle_deg=70.0))["tool_axis"]
    assert r.applies and not r.passed and r.value == pytest.approx(90.0, abs=0.5)
    offset = float(r.note.split("first tool axis at u ")[1].split(" deg")[0])
    assert abs((r.worst["u_deg"] - offset) % 180.0 - 90.0) <= 360.0 / SAMPLES[0] + 1e-6
    assert "3 setups are enough" in r.note                      # 60 deg from a tool axis at worst


def test_plain_cylinder_on_four_3axis_setups_passes_tool_axis():
    r = run(PLAIN, inner_cylinder(r=4.0), fab_for("cnc3", setups=4, max_tool_angle_deg=70.0))["tool_axis"]
    assert r.passed and r.value == pytest.approx(45.0, abs=1.0)


def test_ridge_round_the_lens_fails_tool_axis_midway_between_setups():
    # A ridge all around at z 20 mm: its flanks tilt ~39 deg up or down. Sideways tilt never
    # matters (every azimuth is within 45 deg of one of 4 setups), tilt along the axis adds:
    # midway between two setups the flank is acos(cos 39 cos 45) ~ 57 deg from both tools.
    heights = bump(0.0, 20.0, 4.0, 1e9, 3.0)
    fab = fab_for("cnc3", setups=4, max_tool_angle_deg=50.0)
    res = run(heights, inner_cylinder(r=4.0), fab)
    r = res["tool_axis"]
    assert res["max_slope"].passed
    slope = res["max_slope"].value
    assert not r.passed
    assert r.value == pytest.approx(np.degrees(np.arccos(np.cos(np.radians(slope)) * np.cos(np.pi / 4))), abs=0.5)
    offset = float(r.note.split("first tool axis at u ")[1].split(" deg")[0])
    assert abs((r.worst["u_deg"] - offset) % 90.0 - 45.0) <= 360.0 / SAMPLES[0] + 1e-6
    assert abs(abs(r.worst["z_mm"] - 20.0) - 3.0) < 1.0                        # on a flank


def test_tool_axis_applies_to_3axis_only():
    res = run(PLAIN, inner_cylinder(r=4.0), fab_for("cnc4"))
    assert not res["tool_axis"].applies and "radial" in res["tool_axis"].note
    assert "slope against the tool axis" in res["max_slope"].note


def test_wide_cavity_behind_a_narrow_bore_fails_cavity_access_on_cnc():
    iv, fi = inner_cylinder(r=12.0)
    r = run(PLAIN, (iv, fi), fab_for("cnc4"))["cavity_access"]
    # The floor's ring outside the bore faces up, hidden from a tool coming through the bore.
    floor = 0.5 * 64 * 12.0 ** 2 * np.sin(2 * np.pi / 64)
    assert not r.passed and r.value == pytest.approx(floor - np.pi * 5.0 ** 2, rel=1e-6)
    assert np.hypot(*r.worst["xyz_mm"][:2]) == pytest.approx(12.0, abs=1e-4)
    assert r.worst["z_mm"] == pytest.approx(6.0)


def test_counterbore_makes_the_cavity_reachable():
    iv, fi = inner_cylinder(r=4.0)                                  # floor 4 mm, counterbore 5 mm
    r = run(PLAIN, (iv, fi), fab_for("cnc4"))["cavity_access"]
    assert r.passed and r.value == 0.0 and "counterbore" in r.note


def test_cavity_widening_upward_fails_cavity_access_even_with_a_counterbore():
    # A frustum r 4 at its floor to r 9 at its top: its walls face up into the cavity.
    body = m3.Manifold.cylinder(20.0, 4.0, 9.0, 64).translate((0, 0, 8.0))
    iv, fi = _arrays(body)
    r = run(PLAIN, (iv, fi), fab_for("cnc3", setups=4, max_tool_angle_deg=70.0))["cavity_access"]
    walls = np.pi * (4.0 + 9.0) * np.hypot(20.0, 5.0)               # the cone's lateral area
    assert not r.passed and r.value == pytest.approx(walls, rel=0.01)
    assert np.hypot(*r.worst["xyz_mm"][:2]) == pytest.approx(9.0, abs=1e-4)


# ------------------------------------------------------------------ paint

def test_paint_marks_the_failing_cells_red(tmp_path):
    from PIL import Image

    from lampfab.checks.paint import RED, TITLE_PX

    inner = inner_cylinder(r=20.0, z0=4.0, z1=36.0)
    h = bump(100.0, 20.0, -9.5, 12.0, 5.0)
    sv, sf = solid(h, inner)
    fab = fab_for("sla", min_wall_mm=1.0)
    res = checks.run_checks(CYL, h, *inner, sv, sf, fab, LIGHT, samples=SAMPLES)
    out = tmp_path / "checks.png"
    checks.paint_checks(out, CYL, h, *inner, fab, res, samples=SAMPLES)
    img = np.asarray(Image.open(out).convert("RGB"))
    w, h_px = SAMPLES
    assert img.shape[1] == w
    # The min_wall panel is the first after the header; find red pixels in it.
    header = 2 * TITLE_PX + 14
    panel = img[header + TITLE_PX: header + TITLE_PX + h_px]
    ys, xs = np.nonzero(np.all(panel == RED, axis=-1))
    assert len(xs) > 0
    assert abs(xs.mean() / w * 360.0 - 100.0) < 5.0
    assert abs((1 - ys.mean() / (h_px - 1)) * H - 20.0) < 3.0


# ------------------------------------------------------------------ geometry helpers

def test_distance_to_mesh_matches_brute_force():
    rng = np.random.default_rng(7)
    v, f = inner_cone_roof(sections=32)
    p = rng.uniform([-25, -25, -5], [25, 25, 45], (1500, 3))
    p = np.vstack([p, v[rng.choice(len(v), 200)] + rng.normal(0, 0.3, (200, 3))])  # near ones
    d, _ = distance_to_mesh(p, v, f)
    tri = v[f]
    brute = np.full(len(p), np.inf)
    for t in tri:
        q = closest_on_triangles(p, *(np.broadcast_to(t[k], p.shape) for k in range(3)))
        brute = np.minimum(brute, np.linalg.norm(p - q, axis=1))
    assert np.all(d >= brute - 1e-9)
    assert np.max((d - brute) / np.maximum(brute, 1.0)) < 5e-3


def test_closest_on_triangles_against_dense_sampling():
    rng = np.random.default_rng(3)
    a, b, c = (rng.normal(size=(200, 3)) for _ in range(3))
    p = 2 * rng.normal(size=(200, 3))
    q = closest_on_triangles(p, a, b, c)
    s, t = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = s + t <= 1
    s, t = s[keep], t[keep]
    for i in range(0, 200, 10):
        pts = a[i] + s[:, None] * (b[i] - a[i]) + t[:, None] * (c[i] - a[i])
        assert np.linalg.norm(p[i] - q[i]) <= np.linalg.norm(pts - p[i], axis=1).min() + 1e-12


def test_spline_derivative_matrices():
    # First derivative of a pure harmonic sampled at the nodes: exact to spline accuracy.
    u = 2 * np.pi * np.arange(32) / 32
    d = surface.u_matrix(32, 96, 1) @ np.sin(3 * u)
    assert np.allclose(d, 3 * np.cos(3 * 2 * np.pi * np.arange(96) / 96), atol=0.02)
    z = np.linspace(0, 1, 12)
    assert np.allclose(surface.open_matrix(12, 40, 1) @ z**2, 2 * np.linspace(0, 1, 40), atol=1e-9)


# ------------------------------------------------------------------ profiles

@pytest.mark.parametrize("name,process", [("sla_resin", "sla"), ("acrylic_cnc4", "cnc4"),
                                          ("acrylic_cnc3", "cnc3"), ("glass", "glass")])
def test_fabrication_profiles_load_and_set_every_field(name, process):
    import tomllib

    fab = load_fabrication(name)
    assert fab.process == process
    with open(fab.path, "rb") as fh:
        keys = set(tomllib.load(fh))
    fields = {f.name for f in dataclasses.fields(Fabrication)} - {"path"}
    assert keys == fields
    assert (fab.tool_radius_mm > 0) == process.startswith("cnc")
    assert 1.3 < fab.ior < 2.0 and fab.min_wall_mm > 0


def test_3axis_profile_needs_two_setups(tmp_path):
    from lampfab.errors import LampfabError

    text = (ROOT_FAB / "acrylic_cnc3.toml").read_text().replace("setups = 4", "setups = 1")
    (tmp_path / "one.toml").write_text(text)
    with pytest.raises(LampfabError, match=r"one\.toml: setups 1: 3-axis milling .* at least 2"):
        load_fabrication(str(tmp_path / "one.toml"))
