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


@pytest.mark.parametrize("creased", [False, True])
def test_radius_derivatives_are_the_node_to_sample_matrices(rng, cyl, creased):
    """Evaluated from the spline's coefficients and its sparse basis, the radius and its
    derivatives are what the dense node-to-sample matrices give, rows picked or not."""
    cyl = surface.Cylinder(cyl.radius_mm, cyl.height_mm, creased)
    nu, nv, mu, mv = 16, 6, 64, 21
    h = rng.normal(size=(nu, nv))
    u = [surface.u_matrix(nu, mu, d, creased) for d in range(3)]
    z = [surface.open_matrix(nv, mv, d) / cyl.height_mm**d for d in range(3)]
    expected = [cyl.radius_mm + u[0] @ h @ z[0].T, u[1] @ h @ z[0].T, u[0] @ h @ z[1].T,
                u[2] @ h @ z[0].T, u[1] @ h @ z[1].T, u[0] @ h @ z[2].T]
    for got, want in zip(surface.radius_derivatives(cyl, h, mu, mv), expected, strict=True):
        assert np.allclose(got, want, rtol=1e-12, atol=1e-9)
    rows = np.array([0, 5, 63])
    for got, want in zip(surface.radius_derivatives(cyl, h, mu, mv, order=1, rows=rows), expected, strict=False):
        assert np.allclose(got, want[rows], rtol=1e-12, atol=1e-9)


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


@pytest.mark.parametrize("max_rise_deg", [None, 30.0])
def test_slope_penalty_gradient_matches_finite_differences(cyl, rng, max_rise_deg):
    heights = rng.normal(scale=3.0, size=(32, 9))
    penalty, grad = surface.slope_penalty(cyl, heights, 40.0, max_rise_deg)
    assert penalty > 0
    step = 1e-6
    for node in [(0, 0), (5, 3), (17, 8), (31, 4)]:
        up, down = heights.copy(), heights.copy()
        up[node] += step
        down[node] -= step
        numeric = (surface.slope_penalty(cyl, up, 40.0, max_rise_deg)[0]
                   - surface.slope_penalty(cyl, down, 40.0, max_rise_deg)[0]) / (2 * step)
        assert grad[node] == pytest.approx(numeric, rel=1e-4, abs=1e-10)


def test_slope_penalty_counts_overhangs_only_when_asked(cyl):
    # A cone widening upward at 35°: within a 40° tilt limit, past a 30° overhang limit.
    z = np.linspace(0.0, cyl.height_mm, 9)
    heights = np.tile((z - cyl.height_mm / 2) * np.tan(np.radians(35.0)), (32, 1))
    assert surface.slope_penalty(cyl, heights, 40.0)[0] == 0.0
    penalty, grad = surface.slope_penalty(cyl, heights, 40.0, 30.0)
    assert penalty > 0 and np.abs(grad).max() > 0
