import numpy as np
import pytest
import trimesh

from lampfab import inner
from lampfab.errors import LampfabError

LIGHT = np.array([0.0, 0.0, 45.0])


def load(path, scale=1.0):
    return inner.load_inner(path, scale, LIGHT, 45.0, 20.0, 90.0)


def test_blender_style_split_vertices_are_welded(tmp_path):
    mesh = trimesh.creation.cylinder(radius=12, height=60, sections=64)
    mesh.apply_translation(LIGHT)
    soup = trimesh.Trimesh(mesh.triangles.reshape(-1, 3), np.arange(len(mesh.faces) * 3).reshape(-1, 3),
                           process=False)  # every triangle with its own corners, as OBJ exports split them
    path = tmp_path / "inner layer.obj"
    soup.export(path)
    v, f = load(path)
    assert len(v) == len(mesh.vertices) and len(f) == len(mesh.faces)
    assert inner.winding_number(v, f, LIGHT) == pytest.approx(1.0)


def test_scale_from_metres(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.015)
    mesh.apply_translation(LIGHT / 1000)
    path = tmp_path / "metres.ply"
    mesh.export(path)
    v, _ = load(path, scale=1000.0)
    assert np.linalg.norm(v - LIGHT, axis=1).max() == pytest.approx(15.0, rel=1e-3)


@pytest.mark.parametrize("make, words", [
    (lambda: trimesh.Trimesh(trimesh.creation.icosphere(radius=10).vertices + LIGHT,
                             trimesh.creation.icosphere(radius=10).faces[:-3]), ["not closed", "open edges"]),
    (lambda: trimesh.creation.icosphere(radius=10).apply_translation([0, 0, 20]), ["does not enclose the light"]),
    (lambda: trimesh.creation.icosphere(radius=30).apply_translation(LIGHT), ["reaches radius", "outer layer"]),
    (lambda: trimesh.creation.cylinder(radius=10, height=100).apply_translation(LIGHT), ["spans z", "inside the lens"]),
])
def test_bad_inner_layers_are_refused_with_the_reason(tmp_path, make, words):
    path = tmp_path / "bad.stl"
    make().export(path)
    with pytest.raises(LampfabError) as err:
        load(path)
    assert str(path) in str(err.value)
    for w in words:
        assert w in str(err.value)


def test_missing_and_unsupported_files(tmp_path):
    with pytest.raises(LampfabError, match="file not found"):
        load(tmp_path / "nope.obj")
    (tmp_path / "a.txt").write_text("x")
    with pytest.raises(LampfabError, match="unsupported format"):
        load(tmp_path / "a.txt")


def test_bundled_inner_layer_is_closed_and_encloses_the_light():
    v, f = load(None)
    assert inner.winding_number(v, f, LIGHT) == pytest.approx(1.0)
    assert trimesh.Trimesh(v, f, process=False).is_watertight


def test_bundled_inner_layer_is_the_documented_revolve():
    """lampfab/data/inner_default.obj is ``default_inner_mesh()`` written out: the
    function is its recipe and its description."""
    made = inner.default_inner_mesh()
    bundled = trimesh.load(inner.DEFAULT_INNER, process=False)
    assert bundled.faces.shape == made.faces.shape
    assert np.allclose(np.sort(bundled.vertices, axis=0), np.sort(made.vertices, axis=0), atol=1e-6)
    assert bundled.volume == pytest.approx(made.volume, rel=1e-9)


def test_the_bundled_hollow_takes_the_radius_asked_for():
    v, f = inner.load_inner(None, 1.0, LIGHT, 45.0, 20.0, 90.0, hollow_radius_mm=16.0)
    r = np.hypot(v[:, 0], v[:, 1])
    assert r.max() == pytest.approx(16.0) and v[:, 2].min() == pytest.approx(10.0)
    assert v[:, 2].max() == pytest.approx(86.0)
    # its wall stands up to the 45 degree roof, which starts the radius below the apex
    assert v[r > 15.99, 2].max() == pytest.approx(70.0)
    assert inner.winding_number(v, f, LIGHT) == pytest.approx(1.0)
    assert trimesh.Trimesh(v, f, process=False).is_watertight
    default_v, _ = load(None)
    assert np.hypot(default_v[:, 0], default_v[:, 1]).max() == pytest.approx(inner.DEFAULT_HOLLOW_RADIUS_MM)


def test_a_bundled_hollow_too_wide_for_the_outer_layer_is_refused():
    with pytest.raises(LampfabError, match=r"bundled inner layer \(hollow_radius_mm 30\): reaches radius 30\.00"):
        inner.load_inner(None, 1.0, LIGHT, 45.0, 20.0, 90.0, hollow_radius_mm=30.0)
