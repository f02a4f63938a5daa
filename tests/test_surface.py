import numpy as np
import pytest
import trimesh
from scipy.interpolate import make_interp_spline

from lampfab import surface


def test_u_matrix_matches_scipys_periodic_spline(rng):
    n, m = 24, 96
    y = rng.normal(size=n)
    x = np.linspace(0, 2 * np.pi, n + 1)
    ref = make_interp_spline(x, np.append(y, y[0]), k=3, bc_type="periodic")(np.arange(m) * 2 * np.pi / m)
    assert np.allclose(surface.u_matrix(n, m) @ y, ref, atol=1e-12)


@pytest.mark.parametrize("creased", [False, True])
def test_refine_keeps_node_values_and_adjoint_is_transpose(rng, cyl, creased):
    cyl = surface.Cylinder(cyl.radius_mm, cyl.height_mm, creased)
    h = rng.normal(size=(16, 5))
    fine = surface.refine(cyl, h, 4)
    assert fine.shape == (64, 17)
    assert np.allclose(fine[::4, ::4], h)
    g = rng.normal(size=fine.shape)
    # <A h, g> == <h, A^T g>
    assert np.isclose(np.sum(fine * g), np.sum(h * surface.sample_adjoint(cyl, g, 16, 5)))


def test_closed_outer_mesh_is_a_watertight_outward_solid(cyl, rng):
    h = 2.0 * rng.normal(size=(32, 9))
    v, f = surface.closed_outer_mesh(cyl, h, 2)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0
    plain_v, plain_f = surface.closed_outer_mesh(cyl, np.zeros((64, 9)), 4)
    plain = trimesh.Trimesh(plain_v, plain_f, process=False).volume
    assert plain == pytest.approx(np.pi * cyl.radius_mm**2 * cyl.height_mm, rel=2e-4)


def test_slopes_of_a_cone_section(cyl):
    # A radius that grows 0.5 mm per mm of height tilts atan(0.5) along z everywhere.
    z = cyl.node_z(9)
    h = np.tile(0.5 * (z - z.mean()), (16, 1))
    tilt, tilt_z = surface.slopes_deg(cyl, h, 64, 33)
    expected = np.degrees(np.arctan(0.5))
    assert np.allclose(tilt_z, expected, atol=1e-6)
    assert np.allclose(tilt, expected, atol=1e-6)
