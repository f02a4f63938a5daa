import numpy as np
import pytest

from lampfab import lens, room, trace, transport
from lampfab.source import Source


def _dr(mi, a):
    return mi.Vector3f(*[mi.Float(a[:, k].astype(np.float32)) for k in range(3)])


def test_fresnel_and_snell_at_a_flat_interface(mi):
    n = 20000
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    down = np.tile([0.0, 0.0, -1.0], (n, 1))
    xi = mi.Float(np.linspace(0, 1, n, endpoint=False).astype(np.float32))
    out = trace.to_numpy(trace.refract_or_reflect(mi, _dr(mi, down), _dr(mi, normal), 1.5, xi))
    reflected = np.mean(out[:, 2] > 0)
    assert reflected == pytest.approx(((1.5 - 1) / (1.5 + 1)) ** 2, abs=1e-3)  # 4 % at normal incidence
    s30 = np.sin(np.radians(30))
    slanted = np.tile([s30, 0.0, -np.cos(np.radians(30))], (n, 1))
    ones = mi.Float(np.ones(n, np.float32))
    out = trace.to_numpy(trace.refract_or_reflect(mi, _dr(mi, slanted), _dr(mi, normal), 1.5, ones))
    assert out[0, 0] == pytest.approx(s30 / 1.5, abs=1e-6)  # Snell, entering glass


def test_snell_normals_send_light_where_asked(mi, rng):
    d_in = rng.normal(size=(500, 3)) * [0.2, 0.2, 0.2] + [1.0, 0.0, 0.0]
    d_in /= np.linalg.norm(d_in, axis=1, keepdims=True)
    d_out = rng.normal(size=(500, 3)) * [0.3, 0.3, 0.3] + [1.0, 0.0, 0.0]
    d_out /= np.linalg.norm(d_out, axis=1, keepdims=True)
    # Only deflections a glass-air interface can make (below ~48°, TIR beyond).
    feasible = np.degrees(np.arccos(np.sum(d_in * d_out, 1))) < 35
    d_in, d_out = d_in[feasible], d_out[feasible]
    assert len(d_in) > 300
    n = transport.snell_normals(d_in, d_out, 1.49)
    ones = mi.Float(np.ones(len(d_in), np.float32))
    got = trace.to_numpy(trace.refract_or_reflect(mi, _dr(mi, d_in), _dr(mi, n), 1.49, ones))
    assert np.allclose(got, d_out, atol=1e-5)


@pytest.fixture
def plain_room(mi, mid_design, cyl, inner_layer):
    """The plain lens (zero heights) in the default room: (scene, light, walls, shapes)."""
    walls = room.walls(mid_design)
    v, f = lens.optical_mesh(cyl, np.zeros((32, 9)), 2, *inner_layer)
    return (trace.MeshScene(v, f), room.light_position(mid_design), walls,
            [room.image_shape(w, 16) for w in walls])


def test_render_lights_each_wall_by_its_solid_angle_and_is_deterministic(plain_room):
    scene, light, walls, shapes = plain_room
    a, info = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3)
    b, _ = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert info["lost"] > 0 and info["trapped"] < 0.05
    # The plain lens's bore and outer side are coaxial cylinders: a ray from the light crosses
    # them as a slab and keeps its direction, and what one side reflects inwards leaves through
    # the opposite side in its own direction too.  So each wall gets the light of the solid
    # angle it fills, give or take the roof's and caps' few per cent.
    for share, wall in zip(info["shares"], walls):
        assert share == pytest.approx(_solid_angle_share(wall, light), rel=0.05), wall.name


def _solid_angle_share(wall, point) -> float:
    """The share of a sphere of directions from ``point`` that falls on the ``wall``'s
    rectangle: the exact sum over the four rectangles with a corner at the foot of the
    perpendicular (Omega = atan(x y / (d sqrt(d^2 + x^2 + y^2))) each)."""
    ex, ey = wall.right / np.linalg.norm(wall.right), wall.down / np.linalg.norm(wall.down)
    normal = np.cross(ex, ey)
    rel = wall.origin - point
    d = abs(float(rel @ normal))
    x0, y0 = float(rel @ ex), float(rel @ ey)
    x1, y1 = x0 + np.linalg.norm(wall.right), y0 + np.linalg.norm(wall.down)

    def corner(x, y):
        return np.arctan(x * y / (d * np.sqrt(d * d + x * x + y * y)))

    omega = corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
    return float(omega) / (4.0 * np.pi)


def test_ghosts_are_the_reflected_part_of_the_light(plain_room):
    scene, light, walls, shapes = plain_room
    images, info = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3)
    for img, ghost in zip(images, info["ghosts"]):
        assert np.all(ghost <= img)
        # Two interfaces near normal incidence reflect ((n-1)/(n+1))^2 = 3.9 % each.
        assert 0.03 < ghost.sum() / img.sum() < 0.15
    # Glass that matches the air reflects only at grazing incidence: a photon or two of 200,000.
    matched_images, matched = trace.render_walls(scene, Source(light), 1.0 + 1e-6, walls, shapes, 200_000, seed=3)
    assert all(ghost.sum() < 1e-3 * img.sum() for img, ghost in zip(matched_images, matched["ghosts"]))


def test_ghosts_split_by_where_they_were_first_reflected(plain_room):
    import drjit as dr

    scene, light, walls, shapes = plain_room
    mi = scene.mi

    def inner_or_outer(p, n):  # 1: a facet facing the axis (the bore), 2: the rest
        return dr.select(p.x * n.x + p.y * n.y < 0, mi.UInt32(1), mi.UInt32(2))

    images, info = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3)
    same, split = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3,
                                     reflection_place=inner_or_outer)
    assert all(np.array_equal(a, b) for a, b in zip(images, same))
    assert sorted(split["ghosts_by_place"]) == [1, 2]
    for k, ghost in enumerate(split["ghosts"]):
        assert np.allclose(split["ghosts_by_place"][1][k] + split["ghosts_by_place"][2][k], ghost)
        # Near normal incidence both the bore and the outer surface reflect ~4 %.
        assert 0.2 < split["ghosts_by_place"][1][k].sum() / ghost.sum() < 0.8


def test_a_cavity_filled_to_the_glasss_index_stops_reflecting(plain_room):
    import drjit as dr

    scene, light, walls, shapes = plain_room
    mi = scene.mi

    def facing_the_axis(p, n):
        return p.x * n.x + p.y * n.y < 0

    def filled(p, n):  # the bore holds a medium of the glass's index; air outside
        return dr.select(facing_the_axis(p, n), mi.Float(1.0), mi.Float(1.49))

    def code(p, n):
        return dr.select(facing_the_axis(p, n), mi.UInt32(1), mi.UInt32(2))

    images, info = trace.render_walls(scene, Source(light), 1.49, walls, shapes, 200_000, seed=3, reflection_place=code)
    same, _ = trace.render_walls(scene, Source(light), lambda p, n: mi.Float(1.49) + 0.0 * p.x, walls, shapes,
                                 200_000, seed=3)
    assert all(np.array_equal(a, b) for a, b in zip(images, same))  # a per-facet index of 1.49 is the float's
    potted, split = trace.render_walls(scene, Source(light), filled, walls, shapes, 200_000, seed=3,
                                       reflection_place=code)
    for k in range(len(walls)):
        # The bore reflected a fair part of the ghosts; filled, a grazing photon at most.
        assert info["ghosts_by_place"][1][k].sum() > 0.2 * info["ghosts"][k].sum()
        assert split["ghosts_by_place"].get(1, [np.zeros(1)] * len(walls))[k].sum() < 1e-3 * potted[k].sum()
        assert 0.01 < split["ghosts_by_place"][2][k].sum() / potted[k].sum() < 0.1  # the outer surface's stay


def test_stratified_directions_cover_the_sphere_evenly(mi):
    directions, count = trace.stratified_sphere(mi, 10_000, seed=5)
    d = trace.to_numpy(directions)
    assert abs(count - 10_000) < 100 and len(d) == count
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    # Every equal-area band of height holds the same number of directions: independent
    # directions would put ~sqrt(count / bands) more or fewer in each.
    bands = np.histogram(d[:, 2], bins=8, range=(-1, 1))[0]
    assert bands.max() - bands.min() <= 0.01 * count / 8
    # Their mean is far closer to zero than independent directions' (~1 / sqrt(count)).
    assert np.linalg.norm(d.mean(axis=0)) < 0.1 / np.sqrt(count)
    again, _ = trace.stratified_sphere(mi, 10_000, seed=6)
    assert not np.allclose(trace.to_numpy(again), d)


def test_stratified_photons_vary_less_than_poisson_per_pixel(plain_room):
    """Two renders with different seeds differ by far less than independent photons'
    counting noise: verify's figures are not limited by its own photon noise."""
    scene, light, walls, shapes = plain_room
    photons = 200_000
    a, info = trace.render_walls(scene, Source(light), 1.49, walls, shapes, photons, seed=3)
    b, _ = trace.render_walls(scene, Source(light), 1.49, walls, shapes, photons, seed=4)
    assert abs(info["photons"] - photons) < 0.01 * photons
    counts_a, counts_b = (np.concatenate([img.ravel() for img in x]) * info["photons"] for x in (a, b))
    # Independent photons: each pixel's count is Poisson, var(a - b) = a + b.
    ratio = np.var(counts_a - counts_b) / np.mean(counts_a + counts_b)
    assert ratio < 0.3


def test_light_reflected_by_the_cavity_enters_the_glass_across_it(mi, inner_layer, mid_design):
    """into_glass: the light meeting the cavity's wall head-on enters the glass there
    (96 %), and every 4th photon also carries the 4 % reflected across the cavity into
    the glass on the far side, still travelling straight."""
    v, f = inner_layer
    cavity = trace.MeshScene(v, f[:, ::-1])  # normals into the cavity
    light = room.light_position(mid_design)
    n = 2_000
    o = _dr(mi, np.tile(light, (n, 1)))
    d = _dr(mi, np.tile([1.0, 0.0, 0.0], (n, 1)))
    p, d_glass, w = trace.into_glass(mi, cavity.scene, o, d, 1.5, 4)
    p, d_glass, w = trace.to_numpy(p), trace.to_numpy(d_glass), w.numpy()
    assert len(w) == n + n // 4
    near, far = slice(0, n), slice(n, None)
    assert np.all(p[near, 0] > 0) and np.all(p[far, 0] < 0)
    radius = np.hypot(p[:, 0], p[:, 1])
    assert np.allclose(radius, radius[0], atol=0.05) and 14 < radius[0] < 18  # on the hollow's wall (r 16 mm)
    # Within the tilt of the bore's facets (1024 around: 0.35° each).
    assert np.allclose(d_glass[near], [1.0, 0.0, 0.0], atol=0.02)
    assert np.allclose(d_glass[far], [-1.0, 0.0, 0.0], atol=0.02)
    r = ((1.5 - 1) / (1.5 + 1)) ** 2
    assert np.allclose(w[near], 1 - r, atol=1e-4)
    assert np.allclose(w[far], 4 * r * (1 - r), atol=1e-4)
    _, _, matched = trace.into_glass(mi, cavity.scene, o, d, 1.0 + 1e-6, 4)
    assert np.allclose(matched.numpy(), np.r_[np.ones(n), np.zeros(n // 4)], atol=1e-6)


def test_direct_noise_sample_is_as_noisy_as_the_render(plain_room, monkeypatch):
    scene, light, walls, shapes = plain_room
    monkeypatch.setattr(trace, "BATCH", 50_000)  # four batches: two halves to compare

    def render(seed):
        images, info = trace.render_walls(scene, Source(light, "sphere", 1.5), 1.49, walls, shapes, 200_000, seed=seed)
        return np.concatenate([(i - g).ravel() for i, g in zip(images, info["ghosts"])]), info

    a, info = render(3)
    b, _ = render(4)
    noise = np.concatenate([n.ravel() for n in info["direct_noise"]])
    lit = (a + b) > 0
    # Two renders' difference over sqrt(2) has one render's noise: the sample must match
    # its spread (thousands of pixels: a few per cent) and average out to nothing.
    assert np.std(noise[lit]) == pytest.approx(np.std((a - b)[lit]) / np.sqrt(2), rel=0.15)
    assert abs(noise.sum()) < 3.0 * np.sqrt(np.sum(noise**2))  # a sum of zero-mean terms: within 3 sigma
    # Photons that fit one batch are traced as two, so that there are halves to compare.
    monkeypatch.setattr(trace, "BATCH", 1_000_000)
    _, whole = trace.render_walls(scene, Source(light, "sphere", 1.5), 1.49, walls, shapes, 200_000, seed=3)
    spread = np.std(np.concatenate([n.ravel() for n in whole["direct_noise"]])[lit])
    assert spread == pytest.approx(np.std((a - b)[lit]) / np.sqrt(2), rel=0.15)
