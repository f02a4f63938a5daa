"""The facet walk finds the facet a ray from inside the glass crosses, as a BVH does."""

import numpy as np

from lampfab import facetwalk, surface, trace


def _rough_lens(rng, nu=128, nv=33, tessellation=2):
    """A lens bumpy on the scale of its cells, its slopes up to ~40 degrees, as a
    refined lens's are at most."""
    cyl = surface.Cylinder(45.0, 90.0)
    heights = 3.0 + 0.4 * rng.normal(size=(nu, nv))
    verts, faces = surface.closed_outer_mesh(cyl, heights, tessellation)
    return cyl, heights, verts, faces, surface.fine_shape(nu, nv, tessellation)


def _rays(rng, n):
    """Origins inside the lens (radius < 20 mm, 5-85 mm up), directions over the sphere."""
    r, phi = 20.0 * np.sqrt(rng.random(n)), rng.random(n) * 2 * np.pi
    origins = np.stack([r * np.cos(phi), r * np.sin(phi), 5.0 + 80.0 * rng.random(n)], 1)
    directions = rng.normal(size=(n, 3))
    return origins, directions / np.linalg.norm(directions, axis=1)[:, None]


def _walk(mi, verts, cyl, heights, shape, origins, directions):
    hit, settled = facetwalk.first_hits(mi, trace.to_jit(mi, mi.Point3f, origins), trace.to_jit(mi, mi.Vector3f, directions),
                                        trace.to_jit(mi, mi.Point3f, verts), *shape, cyl.height_mm,
                                        cyl.radius_mm + float(heights.mean()))
    return hit.numpy().astype(np.int64), settled.numpy()


def test_the_walk_finds_the_facet_mitsubas_bvh_finds(mi, rng):
    cyl, heights, verts, faces, shape = _rough_lens(rng)
    origins, directions = _rays(rng, 200_000)
    met, face, _ = trace.first_hits(verts, faces, origins, directions)
    assert met.all()
    hit, settled = _walk(mi, verts, cyl, heights, shape, origins, directions)
    caps = face >= 2 * shape[0] * (shape[1] - 1)
    assert 0.05 < caps.mean() < 0.5  # the rays leave through the fans as well as the side
    assert settled.mean() > 0.9999
    # Rays through a shared edge or vertex may be given either facet: a few in 10^5.
    assert np.mean(hit[settled] == face[settled]) > 0.9999
    assert np.mean(hit[caps & settled] == face[caps & settled]) > 0.999


def test_a_settled_facet_holds_the_hit_point(mi, rng):
    cyl, heights, verts, faces, shape = _rough_lens(rng)
    origins, directions = _rays(rng, 20_000)
    hit, settled = _walk(mi, verts, cyl, heights, shape, origins, directions)
    a, b, c = (verts[faces[hit[settled], k]] for k in range(3))
    o, d = origins[settled], directions[settled]
    normal = np.cross(b - a, c - a)
    t = np.einsum("ij,ij->i", a - o, normal) / np.einsum("ij,ij->i", d, normal)
    p = o + t[:, None] * d
    assert (t > 0).all()
    # Each edge sees the hit on the facet's inner side (barycentric weights >= 0).
    for x, y in ((a, b), (b, c), (c, a)):
        side = np.einsum("ij,ij->i", np.cross(y - x, p - x), normal) / np.einsum("ij,ij->i", normal, normal)
        assert side.min() > -1e-4


def _facets(mi, mu, mv):
    i, j, second = np.meshgrid(np.arange(mu), np.arange(mv - 1), [False, True], indexing="ij")
    return mi.Int32(i.ravel()), mi.Int32(j.ravel()), mi.Bool(second.ravel())


def _index_of(mi, facet, mu, mv):
    """The vertex indices of facets (i, j, second), read back through their corners."""
    positions = mi.Point3f(mi.Float(np.arange(mu * mv, dtype=np.float32)), 0, 0)
    return np.stack([c.x.numpy() for c in facetwalk._corners(mi, positions, *facet, mu, mv)], 1).astype(np.int64)


def test_facets_are_numbered_and_wound_as_the_mesh_is(mi):
    mu, mv = 8, 5
    faces = surface.grid_faces(mu, mv)
    i, j, second = _facets(mi, mu, mv)
    corners = _index_of(mi, (i, j, second), mu, mv)
    prim = i.numpy() * (mv - 1) + j.numpy() + second.numpy() * mu * (mv - 1)
    assert np.array_equal(corners, faces[prim])


def test_each_step_across_an_edge_reaches_the_facet_on_its_other_side(mi):
    mu, mv = 8, 5
    facet = _facets(mi, mu, mv)
    corners = _index_of(mi, facet, mu, mv)
    for k in range(3):
        moved = facetwalk._across(mi, *facet, mi.Int32(k), mi.Bool(True), mu, mv)
        after = _index_of(mi, moved, mu, mv)
        edge = np.delete(corners, k, axis=1)
        # Across the grid's first or last row there is no facet: the walk stays in it.
        inside = ~((edge % mv == 0).all(1) | (edge % mv == mv - 1).all(1))
        for row in np.flatnonzero(inside):
            assert set(edge[row]) <= set(after[row]) and set(after[row]) != set(corners[row])
