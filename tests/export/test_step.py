"""The STEP solid (OCP): B-spline fit, assembly, write and read back, on a small lens."""

import numpy as np
import pytest

from lampfab import solid, surface, tolerances
from lampfab.export import bspline, step_file, stl
from lampfab.errors import GeometryError, LampfabError

from tests.helpers import CYL, bumps, inner

SAMPLES = (64, 15)          # aligned with the 32 x 8 heightmap: 2 per cell in u and v


@pytest.fixture(scope="module")
def written(tmp_path_factory, small_lens):
    folder = tmp_path_factory.mktemp("step")
    stl.write_stl(folder / "lens.stl", small_lens.vertices, small_lens.faces)
    sv, sf = stl.read_stl(folder / "lens.stl")
    info = step_file.write_step(folder / "lens.step", CYL, bumps(), *inner(), 6.0, *SAMPLES,
                                expected_volume_mm3=small_lens.volume_mm3)
    return folder, info, solid.mesh_volume(sv, sf)


@pytest.mark.parametrize("creased", [False, True])
def test_pointwise_spline_is_the_sampled_spline(creased):
    cyl = surface.Cylinder(CYL.radius_mm, CYL.height_mm, creased)
    h = bumps()
    for mu, mv in ((64, 15), (77, 9), (5, 4)):
        uu, zz = np.meshgrid(cyl.node_u(mu), cyl.node_z(mv), indexing="ij")
        got = surface.evaluate(cyl, h, uu.ravel(), zz.ravel()).reshape(mu, mv)
        np.testing.assert_allclose(got, surface.sample(cyl, h, mu, mv), atol=1e-12)


def test_bspline_interpolates_the_samples():
    fit = bspline.bspline_poles(CYL, bumps(), *SAMPLES)
    assert fit["poles"].shape == (64, 15, 3)
    occ = bspline.lamp_surface(fit)
    dev = bspline.deviation(CYL, bumps(), occ, *SAMPLES)
    assert dev["interpolation_mm"] < 1e-9
    assert dev["radial_mm"] < 0.05 and dev["parametric_mm"] < 0.05


def test_step_round_trip(written):
    folder, info, stl_volume = written
    assert info["valid"] and info["closed"] and info["n_solids"] == 1
    # The heightmap's own 32 x 8 nodes already keep the B-spline within 5 µm: no more poles.
    assert (info["poles_u"], info["poles_v"]) == (32, 8)
    assert info["faces"] == 4 + 32 + 32 + 1     # outer, top, bottom, bore; 32 sides, 32 roof facets, floor
    assert info["deviation_mm"] <= tolerances.BSPLINE_DEVIATION_MM
    path = folder / "lens.step"
    assert info["file_bytes"] == path.stat().st_size
    assert not list(folder.glob(".lens.step.*"))
    assert "SI_UNIT(.MILLI.,.METRE.)" in path.read_text()
    back = step_file.read_step(path)
    assert back["n_solids"] == 1 and back["valid"] and back["closed"]
    assert back["faces"] == info["faces"]
    assert back["volume_mm3"] == pytest.approx(info["volume_mm3"], rel=1e-9)
    assert back["volume_mm3"] == pytest.approx(stl_volume, rel=5e-3)


def test_creased_lens_is_one_valid_solid_whose_outer_face_bends_at_the_seams(tmp_path):
    """A creased surface: one periodic B-spline face, C0 at the four sector seams."""
    cyl = surface.Cylinder(CYL.radius_mm, CYL.height_mm, creased=True)
    v, f = inner()
    mesh = solid.build_solid(cyl, bumps(), 2, v, f, mount_radius_mm=6.0)
    info = step_file.write_step(tmp_path / "lens.step", cyl, bumps(), v, f, 6.0, *SAMPLES,
                                expected_volume_mm3=mesh.volume_mm3)
    assert info["deviation_mm"] < 0.05
    back = step_file.read_step(tmp_path / "lens.step")
    assert back["n_solids"] == 1 and back["valid"] and back["closed"]
    assert back["volume_mm3"] == pytest.approx(mesh.volume_mm3, rel=5e-3)
    fit = bspline.bspline_poles(cyl, bumps(), *SAMPLES)
    seams = np.radians(surface.SEAMS_DEG)
    assert np.allclose(fit["u_knots"][fit["u_mults"] == 3][:4], seams)          # C0 exactly there
    assert fit["u_knots"][-1] == pytest.approx(seams[0] + 2 * np.pi)
    occ = bspline.lamp_surface(fit)
    assert occ.IsUPeriodic() and occ.Continuity() == 0                           # GeomAbs_C0


def test_the_fit_takes_as_many_samples_as_the_deviation_needs_and_no_more():
    rough = 3.0 * np.sin(5 * CYL.node_u(16))[:, None] * np.cos(np.linspace(0, 3 * np.pi, 6))[None, :]
    fitted = bspline.fit_samples(CYL, rough, 512, 161)
    mu, mv = fitted["samples"]
    assert (mu, mv) != rough.shape and mu % 16 == 0 and (mv - 1) % 5 == 0        # refined from the nodes
    within = bspline.deviation(CYL, rough, bspline.lamp_surface(bspline.bspline_poles(CYL, rough, mu, mv)), mu, mv)
    assert within["radial_mm"] <= tolerances.BSPLINE_DEVIATION_MM
    assert fitted["deviation"]["radial_mm"] == within["radial_mm"]
    half = (mu // 2, (mv - 1) // 2 + 1)
    coarser = bspline.deviation(CYL, rough, bspline.lamp_surface(bspline.bspline_poles(CYL, rough, *half)), *half)
    assert coarser["radial_mm"] > tolerances.BSPLINE_DEVIATION_MM
    with pytest.raises(GeometryError, match="raise \\[export\\] step_samples"):
        bspline.fit_samples(CYL, rough, 16, 6)


def test_step_bore_opens_the_cavity(written):
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    reader = STEPControl_Reader()
    reader.ReadFile(str(written[0] / "lens.step"))
    reader.TransferRoots()
    shape = reader.OneShape()

    def state(x, y, z):
        return BRepClass3d_SolidClassifier(shape, gp_Pnt(x, y, z), 1e-7).State()

    for z in (0.01, 6.0, 11.99, 40.0):
        assert state(0.0, 0.0, z) == TopAbs_OUT, z
    assert state(10.0, 0.0, 6.0) == TopAbs_IN
    assert state(30.0, 0.0, 40.0) == TopAbs_IN
    assert state(0.0, 0.0, 74.0) == TopAbs_IN


def test_step_counterbore_is_one_valid_solid_matching_the_stl(tmp_path):
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    v, f = inner(sections=16)
    mesh = solid.build_solid(CYL, bumps(), 2, v, f, mount_radius_mm=20.5)
    info = step_file.write_step(tmp_path / "lens.step", CYL, bumps(), v, f, 20.5, *SAMPLES,
                                expected_volume_mm3=mesh.volume_mm3)
    back = step_file.read_step(tmp_path / "lens.step")
    assert back["n_solids"] == 1 and back["valid"] and back["closed"]
    assert back["faces"] == info["faces"] == 4 + 16 + 16 + 1     # the floor became the shoulder ring
    assert back["volume_mm3"] == pytest.approx(mesh.volume_mm3, rel=5e-3)
    reader = STEPControl_Reader()
    reader.ReadFile(str(tmp_path / "lens.step"))
    reader.TransferRoots()
    shape = reader.OneShape()
    for p, want in (((0.0, 0.0, 11.9), TopAbs_OUT), ((19.0, 0.0, 6.0), TopAbs_OUT), ((21.0, 0.0, 6.0), TopAbs_IN),
                    ((20.3, 0.0, 12.1), TopAbs_IN), ((0.0, 0.0, 40.0), TopAbs_OUT)):
        assert BRepClass3d_SolidClassifier(shape, gp_Pnt(*p), 1e-7).State() == want, p


def test_step_bytes_are_reproducible_with_source_date_epoch(tmp_path, monkeypatch):
    v, f = inner()
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    texts = []
    for name in ("a", "b"):
        step_file.write_step(tmp_path / name / "lens.step", CYL, bumps(), v, f, 6.0, *SAMPLES)
        texts.append((tmp_path / name / "lens.step").read_bytes())
    assert texts[0] == texts[1]
    assert b"FILE_NAME('lens.step','2023-11-14T22:13:20'" in texts[0] and b"PRODUCT('lens','lens'" in texts[0]
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "yesterday")
    with pytest.raises(LampfabError, match="SOURCE_DATE_EPOCH='yesterday': give whole seconds"):
        step_file.write_step(tmp_path / "c" / "lens.step", CYL, bumps(), v, f, 6.0, *SAMPLES)


def test_step_refuses_a_bore_too_wide_and_writes_nothing(tmp_path):
    v, f = inner()
    with pytest.raises(LampfabError, match="too large"):
        step_file.write_step(tmp_path / "lens.step", CYL, bumps(), v, f, 19.6, *SAMPLES)
    assert not list(tmp_path.iterdir())


def test_step_volume_mismatch_is_an_error(tmp_path):
    v, f = inner()
    with pytest.raises(GeometryError, match="differs from the expected"):
        step_file.write_step(tmp_path / "lens.step", CYL, bumps(), v, f, 6.0, *SAMPLES, expected_volume_mm3=1e5)
    assert not (tmp_path / "lens.step").exists()


def test_read_step_errors(tmp_path):
    with pytest.raises(LampfabError, match="not found"):
        step_file.read_step(tmp_path / "missing.step")
    bad = tmp_path / "bad.step"
    bad.write_text("not a step file\n")
    with pytest.raises(LampfabError, match="not a readable STEP"):
        step_file.read_step(bad)
