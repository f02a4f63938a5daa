"""A photon tracer through the lens's true facets, onto the walls.

Mitsuba intersects rays with the triangle mesh (its BVH) and Dr.Jit runs the optics
in wavefronts on the CPU or GPU: each hit refracts or reflects with the Fresnel
probability, using the hit triangle's geometric normal ``si.n`` (never an interpolated
shading normal: a printed or milled part has only its facets).  Photons that leave the
lens land on the wall rectangles; every photon counts (no camera connection), and the
per-pixel sums run in numpy in a fixed order, so a seed gives the same images.

The mesh must be a closed, consistently oriented solid (outward normals): the sign of
``dot(d, n)`` says whether a photon enters or leaves the glass.
"""

from __future__ import annotations

import math

import numpy as np

from . import fins, tolerances
from .mi_env import mitsuba
from .room import Wall
from .source import FLAT

BATCH = 4_000_000  # photons per Mitsuba call: ~300 MB of state, fits any laptop
NOWHERE_MM = 1e7  # far below the room, heading down: a photon sent from there meets nothing


class MeshScene:
    """A Mitsuba scene holding one triangle mesh, for ray intersection only.

    ``painted`` (m,) bool: the facets painted matt black (``paint``), where light ends."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, painted: np.ndarray | None = None):
        mi = mitsuba()
        self.mi = mi
        self.painted = None if painted is None or not painted.any() else mi.Bool(np.asarray(painted, bool))
        self.mesh = mi.Mesh("lens", len(vertices), len(faces), has_vertex_normals=False,
                            has_vertex_texcoords=False)
        params = mi.traverse(self.mesh)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
        params["faces"] = mi.UInt(np.ascontiguousarray(faces, np.uint32).ravel())
        params.update()
        self.scene = mi.load_dict({"type": "scene", "lens": self.mesh})


def first_hits(vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray,
               directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where rays first meet a mesh: ((n,) bool hit, (n,) int64 face index, (n,) float64
    distance along the unit direction, mm).  numpy in and out; Mitsuba's BVH in between."""
    scene = MeshScene(vertices, faces)
    mi = scene.mi
    si = scene.scene.ray_intersect(mi.Ray3f(to_jit(mi, mi.Point3f, origins), to_jit(mi, mi.Vector3f, directions)),
                                   mi.RayFlags.Minimal, False)
    return si.is_valid().numpy(), si.prim_index.numpy().astype(np.int64), si.t.numpy().astype(np.float64)


def to_jit(mi, cls, a: np.ndarray):
    """(n, 3) points or directions as a Dr.Jit 3-vector array of ``cls`` (float32)."""
    return cls(*(mi.Float(np.ascontiguousarray(a[:, k], np.float32)) for k in range(3)))


def to_numpy(v) -> np.ndarray:
    """A Dr.Jit 3-vector array (points, directions) as (n, 3) float64."""
    return np.stack([v.x.numpy(), v.y.numpy(), v.z.numpy()], 1).astype(np.float64)


def emit(mi, source, n: int, seed: int):
    """About ``n`` photons from the LED ``source`` (a ``source.Source``): a point with
    its shape's beam (``radius_mm`` 0), a Lambertian sphere, a Lambertian cylinder (a
    filament standing on the lamp axis, centred on the position; its ends do not glow),
    a Lambertian disc facing up, or a post's Lambertian discs facing out.

    Stratified, not independent: a pixel's count then varies far less than Poisson's
    sqrt(count) (the clock's SSIM at 4 M photons: 0.77-0.81 stratified, 0.63-0.65
    independent; 0.82-0.86 at 64 M stratified), and the images' expectation is the
    same.  A sphere's photons keep the point light's stratified directions: a glowing
    ball sends the same light in every direction, from points spread evenly over its disc
    as seen from that direction, so each photon starts at a random point of its
    direction's disc, lifted onto the sphere.  Neighbouring photons then fly side by side
    and trace as fast as the point light's (random directions per point took the
    refinement's steps from 1.1 to 2 s).  A filament, brightest seen side-on, takes its
    points stratified over its surface (azimuth and height from the stratified
    direction, whose z is uniform over [-1, 1]) and cosine-weighted directions.  Flat
    emitters: ``_emit_flat``.  Returns Dr.Jit (origins, unit directions) of about ``n`` photons.
    """
    import drjit as dr

    o = mi.Point3f(*source.position_mm)
    if source.shape in FLAT:
        return _emit_flat(mi, source, n, seed)
    d, count = stratified_sphere(mi, n, seed)
    if source.radius_mm <= 0:
        return dr.zeros(mi.Point3f, count) + o, d
    rng = direction_rng(mi, count, seed)
    sample = mi.Point2f(rng.next_float32(), rng.next_float32())
    radius = source.radius_mm
    if source.shape == "sphere":
        disc = mi.warp.square_to_uniform_disk_concentric(sample)
        lift = dr.safe_sqrt(1.0 - dr.squared_norm(disc))
        return o + radius * mi.Frame3f(d).to_world(mi.Vector3f(disc.x, disc.y, lift)), d
    normal = dr.normalize(mi.Vector3f(d.x, d.y, 0.0))
    origin = o + radius * normal + mi.Vector3f(0.0, 0.0, 0.5 * source.length_mm * d.z)
    # Cosine-weighted about the surface's normal: a Lambertian emitter.
    local = mi.warp.square_to_cosine_hemisphere(sample)
    return origin, mi.Frame3f(normal).to_world(local)


def _emit_flat(mi, source, n: int, seed: int):
    """``emit`` for flat Lambertian faces (a disc, a post's LEDs): each face takes an
    equal share of the photons, their directions stratified and cosine-weighted about
    its normal, each from a random point of its disc (every point of a flat Lambertian
    emitter sends the same beam); a post's fins stop those that would cross into a
    neighbour's sector."""
    import drjit as dr

    normals = source.normals
    faces = len(normals)
    square, count = stratified_square(mi, n, float(faces), seed)
    strip = square.x * faces
    face = dr.minimum(mi.UInt32(strip), faces - 1)
    local = mi.warp.square_to_cosine_hemisphere(mi.Point2f(strip - mi.Float(face), square.y))
    table = mi.Vector3f(*(normals[:, k].astype(np.float32) for k in range(3)))
    frame = mi.Frame3f(dr.gather(mi.Vector3f, table, face))
    origin = mi.Point3f(*source.position_mm) + source.offset_mm * frame.n
    if source.radius_mm > 0:
        rng = direction_rng(mi, count, seed)
        disc = mi.warp.square_to_uniform_disk_concentric(mi.Point2f(rng.next_float32(), rng.next_float32()))
        origin = origin + source.radius_mm * (disc.x * frame.s + disc.y * frame.t)
    direction = frame.to_world(local)
    if source.fins:
        stopped = fins.stops(mi, source, origin, direction)
        # A photon a fin stops still counts as emitted: it is sent where nothing is.
        origin = dr.select(stopped, mi.Point3f(0.0, 0.0, -NOWHERE_MM), origin)
        direction = dr.select(stopped, mi.Vector3f(0.0, 0.0, -1.0), direction)
    return origin, direction


def stratified_square(mi, n: int, aspect: float, seed: int):
    """About ``n`` points of the unit square, one jittered inside each cell of a grid
    whose cells are square once the square is stretched ``aspect`` times as wide as
    high.  Returns (Dr.Jit Point2f, their count)."""
    import drjit as dr

    rows = max(1, int(round(np.sqrt(n / aspect))))
    cols = max(1, n // rows)
    count = rows * cols
    rng = mi.PCG32(count, dr.opaque(mi.UInt64, seed), dr.opaque(mi.UInt64, 0))
    i = dr.arange(mi.UInt32, count)
    return mi.Point2f((mi.Float(i % cols) + rng.next_float32()) / cols,
                      (mi.Float(i // cols) + rng.next_float32()) / rows), count


def direction_rng(mi, count: int, seed: int):
    """A random stream for an emitter's second sample (an LED's or a beam's spread),
    independent of ``stratified_square``'s (stream 0) and ``propagate``'s (from 1 << 48)."""
    import drjit as dr

    return mi.PCG32(count, dr.opaque(mi.UInt64, seed), dr.opaque(mi.UInt64, 1 << 40))


def stratified_sphere(mi, n: int, seed: int):
    """About ``n`` unit directions, one jittered inside each cell of an equal-area
    (azimuth, height) grid on the sphere.  Returns (Dr.Jit directions, their count)."""
    # A cell spans 2 pi / cols of azimuth and 2 / rows of height: about square at the
    # equator with pi times as many columns as rows.
    square, count = stratified_square(mi, n, np.pi, seed)
    return mi.warp.square_to_uniform_sphere(square), count


def _take(cls, v, index):
    """Rows ``index`` of a Dr.Jit 3-vector array (stream compaction)."""
    import drjit as dr

    return cls(*(dr.gather(type(c), c, index) for c in (v.x, v.y, v.z)))


def interface(d, n, ior):
    """What happens at a dielectric interface (glass of ``ior`` in air, or ``ior`` the
    glass's index over that of the medium beyond the facet: a float or, per photon, a
    Dr.Jit Float), ``n`` the hit facets' outward normals: (unpolarized Fresnel
    reflectance, 1 under total internal reflection; reflected unit directions; refracted
    unit directions)."""
    import drjit as dr

    cos_dn = dr.dot(d, n)
    entering = cos_dn < 0
    eta = dr.select(entering, ior, 1.0 / ior)  # n_transmitted / n_incident
    facing = dr.select(entering, n, -n)
    cos_i = dr.abs(cos_dn)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = dr.safe_sqrt(1.0 - sin2_t)
    rs = dr.square((cos_i - eta * cos_t) / (cos_i + eta * cos_t))
    rp = dr.square((eta * cos_i - cos_t) / (eta * cos_i + cos_t))
    fresnel = dr.select(sin2_t >= 1.0, 1.0, 0.5 * (rs + rp))
    return (fresnel, dr.normalize(d + 2.0 * cos_i * facing),
            dr.normalize(d / eta + (cos_i / eta - cos_t) * facing))


def refract_or_reflect(mi, d, n, ior, xi):
    """New unit directions at a dielectric interface (see ``interface``): reflected
    where ``xi`` (uniform in [0, 1)) falls below the Fresnel reflectance."""
    import drjit as dr

    fresnel, reflected, refracted = interface(d, n, ior)
    return dr.select(xi < fresnel, reflected, refracted)


def into_glass(mi, cavity, o, d, ior: float, reflected_every: int, stops=None):
    """Photons from inside the cavity into the glass around it, with their flux.

    ``cavity`` is the inner layer as a Mitsuba scene with its normals into the cavity.
    Each photon refracts into the glass where it meets the cavity's wall, with the
    Fresnel transmittance as its weight.  Every ``reflected_every``-th one also follows
    the light reflected there: across the cavity and into the glass on its far side,
    weighted reflectance x transmittance x ``reflected_every``.  Those reflections are
    about 4 % of the light, and the outer surface steers them like the rest: the light
    a sector's wall reflects enters the opposite sector close to the height where light
    from the LED enters it, so the outer surface focuses it onto a band across the
    middle of that sector's wall (on the apple a third of the reflected light on each
    wall, in the 12 rows around the light's height).  Weights, not a random choice
    between the two: a choice adds binomial noise to every pixel (the refinement wrote
    it into the clock's flat grey: SSIM 0.81 -> 0.77 on its front wall, 0.82 weighted).
    ``stops`` (see ``propagate``) zeroes the weight of reflections it stops on their way.

    Returns Dr.Jit (points just inside the glass, unit directions, weights): first the
    refracted photons in order, then the reflected ones.
    """
    import drjit as dr

    si = cavity.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
    reflectance, reflected, refracted = interface(d, si.n, ior)
    # One kernel for the intersection: each later use of a lazy result would re-run it.
    dr.eval(si.p, reflectance, reflected, refracted)
    some = dr.arange(mi.UInt32, 0, dr.width(d), reflected_every)
    start = _take(mi.Point3f, si.p, some)
    back = _take(mi.Vector3f, reflected, some)
    across = cavity.ray_intersect(mi.Ray3f(start + tolerances.RAY_EPSILON_MM * back, back),
                                  mi.RayFlags.Minimal, False)
    far_reflectance, _, far_refracted = interface(back, across.n, ior)
    far_transmitted = 1.0 - far_reflectance
    if stops is not None:
        far_transmitted = dr.select(stops(start, back, across.t), 0.0, far_transmitted)
    dr.eval(across.p, far_transmitted, far_refracted)
    p = _concat(mi.Point3f, si.p, across.p)
    d_glass = _concat(mi.Vector3f, refracted, far_refracted)
    weight = dr.concat([1.0 - reflectance, dr.gather(mi.Float, reflectance, some) * far_transmitted
                        * float(reflected_every)])
    return p + tolerances.RAY_EPSILON_MM * d_glass, d_glass, weight


def _concat(cls, a, b):
    """Dr.Jit 3-vector arrays ``a`` then ``b``."""
    import drjit as dr

    return cls(*(dr.concat([x, y]) for x, y in ((a.x, b.x), (a.y, b.y), (a.z, b.z))))


def propagate(mi, scene, o, d, ior, seed: int, max_bounces: int, on_escape, place=None, stops=None,
              painted=None) -> int:
    """Follow photons through the lens until they leave it.

    One wavefront per interface, compacted so finished photons cost nothing.
    ``scene`` holds one closed solid with outward normals; refraction uses the hit
    facet's geometric normal ``si.n``.  ``ior``: the glass's refractive index in air, or
    ``ior(points, outward normals)`` -> Dr.Jit Float, the glass's index over that of the
    medium beyond each hit facet (a cavity filled with something else than air).
    ``on_escape(o, d, reflected)`` receives each wavefront's escaping photons (Dr.Jit
    arrays), ``reflected`` a Dr.Jit UInt32: 0 if the photon was never reflected, else
    where it was first reflected (a Fresnel ghost): ``place(points, outward normals)``
    -> Dr.Jit UInt32 codes from 1, or 1 without ``place``.  ``stops(o, d, t_max)`` ->
    Dr.Jit Bool: the photons something opaque stops before their next interface
    (``fins.stopper``); they end there, as do those whose next facet is ``painted``
    (a Dr.Jit Bool per facet: ``MeshScene.painted``).  Returns how many are still
    inside after ``max_bounces`` interfaces.
    """
    import drjit as dr

    reflected = dr.zeros(mi.UInt32, dr.width(d))
    for bounce in range(max_bounces):
        n = dr.width(d)
        if n == 0:
            return 0
        si = scene.ray_intersect(mi.Ray3f(o, d), mi.RayFlags.Minimal, False)
        valid = si.is_valid()
        left, inside = ~valid, valid
        if stops is not None:
            ended = stops(o, d, si.t)
            left, inside = left & ~ended, inside & ~ended
        if painted is not None:
            inside &= ~dr.gather(mi.Bool, painted, si.prim_index, valid)
        # One kernel for the intersection; gathers below would otherwise re-run it.
        dr.eval(left, inside, si.p, si.n, o, d)
        gone = dr.compress(left)
        if dr.width(gone):
            on_escape(_take(mi.Point3f, o, gone), _take(mi.Vector3f, d, gone), dr.gather(mi.UInt32, reflected, gone))
        live = dr.compress(inside)
        if dr.width(live) == 0:  # every photon left (a flat panel's light can all be out by now)
            return 0
        # Opaque seeds: a literal would be baked into the kernel and force a recompile.
        rng = mi.PCG32(dr.width(live), dr.opaque(mi.UInt64, seed), dr.opaque(mi.UInt64, (bounce + 1) << 48))
        p = _take(mi.Point3f, si.p, live)
        d_in = _take(mi.Vector3f, d, live)
        normal = _take(mi.Vector3f, si.n, live)
        d = refract_or_reflect(mi, d_in, normal, ior(p, normal) if callable(ior) else ior, rng.next_float32())
        # A reflected photon turns back to the side of the facet it came from.
        reflected = dr.gather(mi.UInt32, reflected, live)
        first = (dr.dot(d_in, normal) * dr.dot(d, normal) < 0) & (reflected == 0)
        reflected = dr.select(first, place(p, normal) if place else mi.UInt32(1), reflected)
        o = p + tolerances.RAY_EPSILON_MM * d
        dr.eval(o, d, reflected)
    return dr.width(d)


def pixel_hits(mi, walls: list[Wall], shapes: list[tuple[int, int]], o, d):
    """Where escaped photons land first: per photon a global pixel index (walls' images
    concatenated in order), or -1 for none.  Dr.Jit in, (n,) int64 numpy out."""
    import drjit as dr

    best_t = dr.full(mi.Float, dr.inf, dr.width(d))
    pixel = dr.full(mi.Int32, -1, dr.width(d))
    offset = 0
    for wall, (rows, cols) in zip(walls, shapes):
        normal = mi.Vector3f(*wall.normal.tolist())
        origin = mi.Point3f(*wall.origin.tolist())
        denom = dr.dot(d, normal)
        t = dr.dot(origin - o, normal) / denom
        rel = o + t * d - origin
        a = dr.dot(rel, mi.Vector3f(*wall.right.tolist())) / wall.width_mm**2
        b = dr.dot(rel, mi.Vector3f(*wall.down.tolist())) / wall.height_mm**2
        hit = (denom < 0) & (t > 0) & (t < best_t) & (a >= 0) & (a < 1) & (b >= 0) & (b < 1)
        col = dr.minimum(mi.Int32(a * cols), cols - 1)
        row = dr.minimum(mi.Int32(b * rows), rows - 1)
        best_t = dr.select(hit, t, best_t)
        pixel = dr.select(hit, offset + row * cols + col, pixel)
        offset += rows * cols
    return pixel.numpy().astype(np.int64)


def wall_landings(mi, walls: list[Wall], o, d, margin: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Where escaped photons land first on the walls' planes, within ``margin`` (a share
    of the picture's width and height) around each picture: ((n,) int64 wall index or
    -1, (n, 2) float64 mm along the wall's right and down from its picture's corner).
    Dr.Jit in, numpy out."""
    import drjit as dr

    best_t = dr.full(mi.Float, dr.inf, dr.width(d))
    index = dr.full(mi.Int32, -1, dr.width(d))
    x, y = dr.zeros(mi.Float, dr.width(d)), dr.zeros(mi.Float, dr.width(d))
    for k, wall in enumerate(walls):
        normal = mi.Vector3f(*wall.normal.tolist())
        denom = dr.dot(d, normal)
        t = dr.dot(mi.Point3f(*wall.origin.tolist()) - o, normal) / denom
        rel = o + t * d - mi.Point3f(*wall.origin.tolist())
        a = dr.dot(rel, mi.Vector3f(*(wall.right / wall.width_mm).tolist()))
        b = dr.dot(rel, mi.Vector3f(*(wall.down / wall.height_mm).tolist()))
        hit = ((denom < 0) & (t > 0) & (t < best_t) & (a >= -margin * wall.width_mm)
               & (a < (1 + margin) * wall.width_mm) & (b >= -margin * wall.height_mm) & (b < (1 + margin) * wall.height_mm))
        best_t = dr.select(hit, t, best_t)
        index = dr.select(hit, k, index)
        x, y = dr.select(hit, a, x), dr.select(hit, b, y)
    return index.numpy().astype(np.int64), np.stack([x.numpy(), y.numpy()], 1).astype(np.float64)


def _noise_sample(counts_by_parity: np.ndarray, traced_by_parity: list[int]) -> np.ndarray:
    """(pixels,) float64, in photons like the pooled counts: the halves' difference
    a - b (a, b = a half's counts over its photons, variances s/na and s/nb) times
    sqrt(na nb), whose variance s (na + nb) is the pooled counts'; zeros if a half is
    empty."""
    na, nb = traced_by_parity
    if not (na and nb):
        return np.zeros(counts_by_parity.shape[1])
    return math.sqrt(na * nb) * (counts_by_parity[0] / na - counts_by_parity[1] / nb)


def render_walls(scene: MeshScene, source, ior, walls: list[Wall], shapes: list[tuple[int, int]],
                 photons: int, seed: int, max_bounces: int = 8, emitter=None, reflection_place=None,
                 kernel_moments=None) -> tuple[list[np.ndarray], dict]:
    """Trace about ``photons`` photons from the LED through the lens onto the walls.

    The LED ``source`` (a ``source.Source``) is traced as ``emit`` says, a post's fins
    stopping photons wherever they cross them (``fins``); ``ior`` is ``propagate``'s; ``emitter(mi, n, seed)`` -> Dr.Jit (origins, unit directions) of
    about ``n`` photons replaces it with another light, e.g. a panel's collimated beam
    (``source`` is then unused).  ``kernel_moments`` (a ``sharpness.Moments``) receives where each
    photon that was never reflected left the lens and landed.

    Returns (per-wall flux images (rows, cols) float64, {"shares": [...], "lost": f,
    "trapped": f, "ghosts": [...], "photons": the count traced}) with flux as a
    fraction of the emitted light;
    ``ghosts`` are the part of each image that was reflected inside the lens at least
    once (Fresnel ghosts: the refinement traces only the cavity's, see ``into_glass``).
    With ``reflection_place`` (see ``propagate``) the info also holds
    "ghosts_by_place": {code: per-wall images of the ghosts first reflected there}.
    ``direct_noise`` is a sample of the photon noise in the images' direct (never
    reflected) light: per wall, zero-mean, with the images' noise variance per pixel (the
    difference of the even and the odd batches' direct light, scaled to the whole count;
    every render traces two batches at least).  Added to a noise-free image, it makes that
    image as noisy as these renders, to score both alike.
    The per-pixel sums run in numpy in a fixed order, so a seed gives the same images
    every time.
    """
    import drjit as dr

    mi = scene.mi
    sizes = [r * c for r, c in shapes]
    pixels = sum(sizes)
    ghost_counts: dict[int, np.ndarray] = {}
    direct_by_parity = np.zeros((2, pixels), np.int64)  # never-reflected landings, even and odd batches
    traced_by_parity = [0, 0]
    trapped = 0
    traced = 0
    batches = max(-(-photons // BATCH), min(photons, 2))  # two at least: the halves of ``direct_noise``
    for batch in range(batches):
        batch_seed = seed * 1_000_003 + batch
        n = photons // batches + (batch < photons % batches)
        o, d = (emitter(mi, n, batch_seed) if emitter
                else emit(mi, source, n, batch_seed))

        def land(o_out, d_out, reflected):
            pixel = pixel_hits(mi, walls, shapes, o_out, d_out)
            place = reflected.numpy()
            if kernel_moments is not None:
                wall, xy = wall_landings(mi, walls, o_out, d_out)
                keep = (wall >= 0) & (place == 0)
                kernel_moments.add(to_numpy(o_out)[keep], wall[keep], xy[keep])
            direct_by_parity[batch % 2] += np.bincount(pixel[(pixel >= 0) & (place == 0)], minlength=pixels)
            for code in np.unique(place[(pixel >= 0) & (place > 0)]):
                ghost_counts.setdefault(int(code), np.zeros(pixels, np.int64))
                ghost_counts[code] += np.bincount(pixel[(pixel >= 0) & (place == code)], minlength=pixels)

        traced += dr.width(d)
        traced_by_parity[batch % 2] += dr.width(d)
        trapped += propagate(mi, scene.scene, o, d, ior, batch_seed, max_bounces, land, reflection_place,
                             fins.stopper(mi, source), scene.painted)

    def per_wall(c):
        return [img.reshape(s) for img, s in zip(np.split(c / traced, np.cumsum(sizes)[:-1]), shapes)]

    ghosts = sum(ghost_counts.values(), np.zeros(pixels, np.int64))
    images = per_wall(direct_by_parity.sum(axis=0) + ghosts)
    shares = [float(img.sum()) for img in images]
    info = {"shares": shares, "lost": 1.0 - sum(shares) - trapped / traced, "trapped": trapped / traced,
            "ghosts": per_wall(ghosts), "photons": traced,
            "direct_noise": per_wall(_noise_sample(direct_by_parity, traced_by_parity))}
    if reflection_place:
        info["ghosts_by_place"] = {code: per_wall(c) for code, c in sorted(ghost_counts.items())}
    return images, info
