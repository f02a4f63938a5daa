"""lens.stl: binary STL out and back in, and ADMesh, the slicers' repair, on it (the
small lens of the helpers)."""

import shutil

import pytest

from lampfab import solid
from lampfab.errors import LampfabError
from lampfab.export import stl


def test_stl_round_trip(small_lens, tmp_path):
    path = tmp_path / "lens.stl"
    size = stl.write_stl(path, small_lens.vertices, small_lens.faces)
    assert path.stat().st_size == size == 84 + 50 * len(small_lens.faces)  # binary STL
    assert not list(tmp_path.glob(".lens.stl.*"))                     # no temporary left
    v, f = stl.read_stl(path)
    assert (len(v), len(f)) == (len(small_lens.vertices), len(small_lens.faces))
    assert solid.edge_check(f) == {"watertight": True, "winding_consistent": True, "components": 1, "euler": 2}
    assert solid.mesh_volume(v, f) == pytest.approx(small_lens.volume_mm3, rel=1e-6)


def test_read_stl_errors(tmp_path):
    with pytest.raises(LampfabError, match="not found"):
        stl.read_stl(tmp_path / "missing.stl")
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"\x00" * 10)
    with pytest.raises(LampfabError):
        stl.read_stl(bad)


def test_admesh_is_installed_by_the_setup():
    # stages/00_setup.sh installs it; export relies on it to prove no slicer repair is needed.
    assert shutil.which("admesh"), "admesh missing: run bash stages/00_setup.sh"


def test_exported_stl_needs_no_repair_in_admesh(small_lens, tmp_path):
    path = tmp_path / "lens.stl"
    stl.write_stl(path, small_lens.vertices, small_lens.faces)
    report = stl.admesh_check(path)
    assert report["repairs"] == 0 and report["parts"] == 1 and report["disconnected_facets"] == 0
    assert set(report) >= {"degenerate_facets", "edges_fixed", "facets_reversed", "normals_fixed"}


def test_admesh_sees_a_flipped_facet_and_a_hole(small_lens, tmp_path):
    faces = small_lens.faces.copy()
    faces[10] = faces[10, ::-1]
    stl.write_stl(tmp_path / "flipped.stl", small_lens.vertices, faces)
    flipped = stl.admesh_check(tmp_path / "flipped.stl")
    assert flipped["repairs"] > 0 and flipped["facets_reversed"] + flipped["normals_fixed"] > 0
    stl.write_stl(tmp_path / "hole.stl", small_lens.vertices, small_lens.faces[1:])
    assert stl.admesh_check(tmp_path / "hole.stl")["disconnected_facets"] > 0
