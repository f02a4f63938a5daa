"""The LED's blur: kernels from moments, the blur they apply, and the optics plan's
halving advice rests on (the blur grows with the emitter, shrinks with the lens)."""

import dataclasses

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from lampfab import inner, lens, room, sharpness, surface, trace
from lampfab.room import Wall
from lampfab.source import Source

WALL = Wall("front", np.array([-900.0, 1000.0, 720.0]), np.array([1800.0, 0, 0]), np.array([0, 0, -1350.0]))


def _moments(rng, sigma_mm, n_cells=20, per_cell=400):
    """Moments of photons through ``n_cells`` cells of a ring at z 0: each cell's point
    landings spread 5 mm around its own centre, and with ``sigma_mm`` more."""
    cells = sharpness.Cells(-1.0, 1.0, nu=n_cells, nz=1)
    m = sharpness.Moments(cells, 1)
    angles = (np.arange(n_cells) + 0.5) / n_cells * 2 * np.pi
    exits = np.repeat(np.stack([np.cos(angles), np.sin(angles), np.zeros(n_cells)], 1) * 40, per_cell, 0)
    centres = np.repeat(np.stack([np.linspace(200, 1600, n_cells), np.full(n_cells, 600.0)], 1), per_cell, 0)
    spread = np.hypot(5.0, sigma_mm)
    m.add(exits, np.zeros(len(exits), np.int64), centres + rng.normal(scale=spread, size=centres.shape))
    return m


def test_a_kernel_is_the_leds_spread_less_the_cells_own(rng):
    point, led = _moments(rng, 0.0), _moments(rng, 30.0)
    k = sharpness.Kernels.of(point, led)
    assert len(k.wall) == 20
    assert np.sqrt(np.median(k.cov_mm2[:, 0])) == pytest.approx(30.0, rel=0.1)
    assert np.sqrt(np.median(k.cov_mm2[:, 1])) == pytest.approx(30.0, rel=0.1)
    d = k.diameters_mm(0, WALL)
    assert d["horizontal"][1] == pytest.approx(4 * 30.0, rel=0.1)
    # A cell with too few photons has no kernel; one landing outside the picture is not on it.
    few = sharpness.Kernels.of(_moments(rng, 0.0, per_cell=10), _moments(rng, 30.0, per_cell=10))
    assert len(few.wall) == 0


def test_an_even_field_blurs_like_a_gaussian_and_keeps_the_light(rng):
    rows, cols = 24, 32
    image = np.zeros((rows, cols))
    image[8:16, 10:20] = 1.0
    sigma_px = 1.5
    sx = WALL.width_mm / cols
    field = np.zeros((rows, cols, 3))
    field[..., 0] = field[..., 1] = (sigma_px * sx) ** 2
    field[..., 1] = (sigma_px * WALL.height_mm / rows) ** 2
    out = sharpness.blur(image, field, WALL)
    assert out.sum() == pytest.approx(image.sum(), rel=1e-6)  # nothing reaches the edges
    assert np.abs(out - gaussian_filter(image, sigma_px, mode="constant", truncate=8)).max() < 0.02


def test_light_blurred_past_the_edges_is_lost():
    """A lamp's light blurred past the picture's edge lands on the wall outside it: a
    bright picture's border comes out darker than its middle, as zero padding gives."""
    rows, cols = 24, 32
    image = np.ones((rows, cols))
    sigma_px = 1.5
    field = np.zeros((rows, cols, 3))
    field[..., 0] = (sigma_px * WALL.width_mm / cols) ** 2
    field[..., 1] = (sigma_px * WALL.height_mm / rows) ** 2
    out = sharpness.blur(image, field, WALL)
    expected = gaussian_filter(image, sigma_px, mode="constant", truncate=8)
    assert np.abs(out - expected).max() < 0.02
    assert out[0, 0] < 0.45 and out[rows // 2, cols // 2] == pytest.approx(1.0, abs=1e-3)


@pytest.fixture(scope="module")
def plain(mi):
    """A plain lens (outer radius 45 mm) with the bundled inner layer, its light, and the
    default room's front wall."""
    light = np.array([0.0, 0.0, 45.0])
    iv, if_ = inner.load_inner(None, 1.0, light, 45.0, 20.0, 90.0)
    return iv, if_, light


def _blur(plain, radius_mm, scale=1.0, photons=400_000):
    """The median LED blur (across, up) on the front wall of the plain lens scaled by ``scale``."""
    iv, if_, light = plain
    cyl = surface.Cylinder(45.0 * scale, 90.0 * scale)
    v, f = lens.optical_mesh(cyl, np.zeros((64, 17)), 2, (iv - [0, 0, 45.0]) * scale + [0, 0, 45.0 * scale], if_)
    scene = trace.MeshScene(v, f)
    moments = [sharpness.Moments(sharpness.Cells(0.0, 90.0 * scale, 128, 32), 1) for _ in range(2)]
    for k, r in enumerate((0.0, radius_mm)):
        trace.render_walls(scene, Source(light * scale, "sphere", r), 1.5, [WALL], [(12, 16)], photons, seed=5 + k,
                           kernel_moments=moments[k])
    d = sharpness.Kernels.of(*moments).diameters_mm(0, WALL)
    return np.array([d["horizontal"][1], d["vertical"][1]])


def test_the_blur_grows_with_the_led_and_shrinks_with_the_lens(plain):
    base = _blur(plain, 1.5)
    # The étendue estimate: LED diameter x wall distance / distance to the surface.
    assert base[0] == pytest.approx(3.0 * 1000 / 45, rel=0.25)
    assert _blur(plain, 0.75) / base == pytest.approx([0.5, 0.5], rel=0.12)
    assert _blur(plain, 1.5, scale=2.0) / base == pytest.approx([0.5, 0.5], rel=0.12)


def test_a_filament_glows_from_its_side_only(mi):
    o, d = trace.emit(mi, Source((0.0, 0.0, 45.0), "cylinder", 0.8, 26.0), 20_000, 3)
    o, d = trace.to_numpy(o), trace.to_numpy(d)
    assert np.allclose(np.hypot(o[:, 0], o[:, 1]), 0.8, atol=1e-4)
    assert np.abs(o[:, 2] - 45.0).max() <= 13.0 + 1e-4 and np.ptp(o[:, 2]) > 25.0
    outward = np.sum(d[:, :2] * o[:, :2], 1) / 0.8
    assert (outward > 0).all()
    assert np.mean(outward) == pytest.approx(2 / 3, abs=0.02)  # Lambertian: mean cosine 2/3


def test_mitsubas_light_tracer_sees_the_walls_trace_sees(mi, small_lens):
    from lampfab import metrics, mitsuba_reference

    light = np.array([0.0, 0.0, 40.0])
    walls = [Wall("front", np.array([-900.0, 1000.0, 715.0]), np.array([1800.0, 0, 0]), np.array([0, 0, -1350.0])),
             Wall("left", np.array([-1000.0, -900.0, 715.0]), np.array([0, 1800.0, 0]), np.array([0, 0, -1350.0]))]
    shapes = [(12, 16)] * 2
    post = Source(light, "post", 1.5, facing_deg=(90.0, 180.0), offset_mm=3.0)
    fins = dataclasses.replace(post, fin_radius_mm=11.0, fin_height_mm=50.0)
    for source in (Source(light), Source(light, "sphere", 1.5), Source(light, "disc", 1.5), post, fins):
        mine, _ = trace.render_walls(trace.MeshScene(small_lens.vertices, small_lens.faces), source, 1.5,
                                     walls, shapes, 1_000_000, seed=4)
        theirs = mitsuba_reference.render(small_lens.vertices, small_lens.faces, 1.5, source, walls,
                                          shapes, 1_000_000, seed=4)
        for a, b in zip(mine, theirs):
            assert metrics.pearson(a, b) > 0.97
