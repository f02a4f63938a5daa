"""The flat panel of the source's prior work (the Mitsuba caustics tutorial's glass slab).

A collimated beam enters the panel's flat back face head-on and leaves through its
relief, which faces the front wall.  In the STL frame (mm, Z up) the panel stands on
its lower edge: x across (-W/2 to W/2), z up (0 to H), the back face on y = 0 and the
relief at

    y(x, z) = T + s(x, z)

where ``s`` is the bicubic spline through the heightmap's nodes (not-a-knot cubic in
both x and z, ends included: ``surface.open_matrix``), T the panel's thickness to the
relief's middle plane.  Heights are (nx, nz) arrays, axis 0 along x, axis 1 along z.
The beam travels +y; the front wall stands at y = wall distance (``room.walls``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..surface import open_matrix


@dataclass(frozen=True)
class PanelShape:
    """The plain panel the relief displaces (mm)."""
    width_mm: float
    height_mm: float
    thickness_mm: float

    def node_x(self, n: int) -> np.ndarray:
        """(n,) float64 mm, both edges included."""
        return np.linspace(-self.width_mm / 2, self.width_mm / 2, n)

    def node_z(self, n: int) -> np.ndarray:
        """(n,) float64 mm, both edges included."""
        return np.linspace(0.0, self.height_mm, n)

    @property
    def beam_centre(self) -> np.ndarray:
        """(3,) mm: the middle of the back face, where the beam's axis enters."""
        return np.array([0.0, 0.0, self.height_mm / 2])


def sample(shape: PanelShape, heights: np.ndarray, mx: int, mz: int, dx: int = 0, dz: int = 0) -> np.ndarray:
    """(nx, nz) mm at the nodes -> (mx, mz) samples of the spline or of its derivative
    d^(dx+dz) s / dx^dx dz^dz (mm per mm^(dx+dz)), edges included."""
    nx, nz = heights.shape
    ax = open_matrix(nx, mx, dx) / shape.width_mm ** dx
    az = open_matrix(nz, mz, dz) / shape.height_mm ** dz
    return ax @ heights @ az.T


def fine_shape(nx: int, nz: int, tessellation: int) -> tuple[int, int]:
    """Vertex counts of a tessellation with ``tessellation`` vertices per cell edge."""
    return (nx - 1) * tessellation + 1, (nz - 1) * tessellation + 1


def points(shape: PanelShape, fine: np.ndarray) -> np.ndarray:
    """(mx, mz) mm relief offsets -> (mx, mz, 3) float64 mm points of the relief."""
    mx, mz = fine.shape
    x = np.broadcast_to(shape.node_x(mx)[:, None], fine.shape)
    z = np.broadcast_to(shape.node_z(mz)[None, :], fine.shape)
    return np.stack([x, shape.thickness_mm + fine, z], axis=-1)


def tilt_deg(shape: PanelShape, heights: np.ndarray, mx: int, mz: int) -> np.ndarray:
    """(mx, mz) deg: the relief normal's tilt from the panel normal (+y), from the
    spline's exact derivatives."""
    gx = sample(shape, heights, mx, mz, dx=1)
    gz = sample(shape, heights, mx, mz, dz=1)
    return np.degrees(np.arctan(np.hypot(gx, gz)))


def _perimeter(mx: int, mz: int) -> np.ndarray:
    """Grid indices (i * mz + j) around the edge: along the bottom (z = 0) with x, up
    the right edge, back along the top, down the left edge.  (2 (mx + mz) - 4,) int64."""
    i_bottom = np.arange(mx - 1)
    j_right = np.arange(mz - 1)
    i_top = np.arange(mx - 1, 0, -1)
    j_left = np.arange(mz - 1, 0, -1)
    return np.concatenate([i_bottom * mz, (mx - 1) * mz + j_right, i_top * mz + mz - 1, j_left]).astype(np.int64)


def closed_mesh(shape: PanelShape, heights: np.ndarray, tessellation: int) -> tuple[np.ndarray, np.ndarray]:
    """The panel solid: the tessellated relief, its four sides and the flat back face.

    Returns ((n, 3) float64 mm vertices, (m, 3) int64 faces, outward winding).  The
    relief's vertices come first, vertex (i, j) of the (mx, mz) grid at i * mz + j.
    The STL is this very mesh, and the tracer traces its flat facets.
    """
    mx, mz = fine_shape(*heights.shape, tessellation)
    top = points(shape, sample(shape, heights, mx, mz)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(mx - 1), np.arange(mz - 1), indexing="ij")
    i, j = i.ravel(), j.ravel()
    a = i * mz + j
    b, c, d = a + mz, a + mz + 1, a + 1
    # Diagonals alternate with i + j so the facets have no preferred direction; either
    # way (x across, z up) the triangles wind to the +y normal.
    flip = ((i + j) % 2).astype(bool)[:, None]
    t1 = np.where(flip, np.stack([a, c, b], 1), np.stack([a, d, b], 1))
    t2 = np.where(flip, np.stack([a, d, c], 1), np.stack([b, d, c], 1))
    ring = _perimeter(mx, mz)
    n_top, k = len(top), len(ring)
    back = top[ring] * [1.0, 0.0, 1.0]  # the same (x, z) on the back face y = 0
    centre = n_top + k
    t_k, t_n = ring, np.roll(ring, -1)
    b_k = n_top + np.arange(k)
    b_n = np.roll(b_k, -1)
    sides = np.concatenate([np.stack([t_k, b_n, b_k], 1), np.stack([t_k, t_n, b_n], 1)])
    fan = np.stack([np.full(k, centre), b_k, b_n], 1)
    vertices = np.vstack([top, back, shape.beam_centre])
    return vertices, np.concatenate([t1, t2, sides, fan]).astype(np.int64)


def collimated_emitter(shape: PanelShape, divergence_deg: float = 0.0, behind_mm: float = 1.0):
    """The beam: photons spread uniformly over the back face (stratified, as the LED's
    directions are in ``trace.emit``), ``behind_mm`` behind it, travelling +y, each
    within a uniform cone of half-angle ``divergence_deg``.

    Returns ``emit(mi, n, seed)`` -> Dr.Jit (origins, unit directions) of about ``n``
    photons, for ``trace.render_walls``.
    """
    def emit(mi, n, seed):
        import drjit as dr

        from ..trace import direction_rng, stratified_square

        square, count = stratified_square(mi, n, shape.width_mm / shape.height_mm, seed)
        o = mi.Point3f((square.x - 0.5) * shape.width_mm, -behind_mm, square.y * shape.height_mm)
        axis = mi.Vector3f(0.0, 1.0, 0.0)
        if divergence_deg <= 0:
            return o, dr.zeros(mi.Vector3f, count) + axis
        rng = direction_rng(mi, count, seed)
        local = mi.warp.square_to_uniform_cone(mi.Point2f(rng.next_float32(), rng.next_float32()),
                                               float(np.cos(np.radians(divergence_deg))))
        return o, mi.Frame3f(axis).to_world(local)

    return emit


def light_json(shape: PanelShape, divergence_deg: float) -> dict:
    """design.json's ``light`` for the panel's beam: what ``verify`` needs to rebuild it.

    ``position`` is the beam's centre on the back face, ``radius`` 0 (no LED); the beam
    fills the back face rectangle (``width``, ``height``) and travels along ``direction``.
    """
    return {"type": "collimated", "position": shape.beam_centre.tolist(), "radius": 0.0,
            "direction": [0.0, 1.0, 0.0], "width": shape.width_mm, "height": shape.height_mm,
            "thickness": shape.thickness_mm, "divergence_deg": float(divergence_deg)}


def emitter_from_json(light: dict, divergence: bool):
    """The beam described by design.json's ``light`` (see ``light_json``): parallel, or
    with its real spread when ``divergence``."""
    shape = PanelShape(float(light["width"]), float(light["height"]), float(light["thickness"]))
    return collimated_emitter(shape, float(light["divergence_deg"]) if divergence else 0.0)
