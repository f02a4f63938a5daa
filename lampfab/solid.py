"""The lens solid: the closed outer surface minus the cavity (inner layer united with the bore).

The cavity is the inner layer (a closed mesh around the LED, see ``inner.py``) united
with a cylindrical bore on the lamp axis that runs from below the base (z < 0) up
through the inner layer's flat bottom, so the cavity opens through the base: resin
drains out of a print, and the LED goes in from below.

The bore only ever removes glass *below* the cavity's flat bottom face (its floor), so
it never widens the cavity's optical side walls.  Either it enters through the floor
and leaves a ledge of at least ``BORE_LEDGE_MM`` of it all around (a printed lens: the
LED board passes a bore narrower than the cavity), or it is a *counterbore*: at least
``BORE_LEDGE_MM`` wider than the whole floor, it opens the floor completely and ends
at its height, so a tool entering from below reaches every part of a cavity that does
not widen upward (a milled lens, see the cavity_access check).  A mount radius between
the two is a LampfabError that names the numbers.

Booleans run in manifold3d (exact, fast); every result's ``status()`` is checked and
the solid is verified: watertight, consistently wound, one connected boundary shell
(one body, cavity open to the outside), genus equal to the inner layer's, and a volume
equal to outer volume minus the cavity volume inside the outer surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import surface, tolerances
from .errors import GeometryError, LampfabError

# The floor ring the bore must leave between its wall and the cavity's side walls.  A
# zero ring would put the bore wall on the cavity wall (coincident, sliver-prone
# booleans) and cut the optical side wall; the minimum gap the optimizer keeps between
# the layers is also plenty for a ledge the LED mount can sit under.
BORE_LEDGE_MM = tolerances.MIN_GAP_MM

# How far the bore starts below the base (any negative z works; 1 mm keeps its
# bottom cap well away from the outer surface's bottom cap at z = 0).
BORE_BELOW_MM = 1.0

# How far the bore mesh reaches above the cavity floor into the cavity (capped at half
# the cavity's height), so its top cap lies inside the void and never on the floor.
BORE_OVERLAP_MM = 1.0


@dataclass(frozen=True)
class Bore:
    """The mount bore: a ``sections``-gon prism on the lamp axis (mm).

    Its polygon's vertices lie on the circle of ``radius_mm``; it spans
    ``z_bottom_mm`` (< 0) to ``z_top_mm`` (inside the cavity; for a counterbore the
    floor's height) and meets the cavity at the inner layer's floor ``z_floor_mm``.
    ``floor_reach_mm`` is the radius of the largest disk around the axis inside that
    floor, ``floor_extent_mm`` the farthest the floor reaches from the axis;
    ``counterbore``: the bore is wider than the whole floor and replaces it.
    """
    radius_mm: float
    sections: int
    z_bottom_mm: float
    z_floor_mm: float
    z_top_mm: float
    floor_reach_mm: float
    floor_extent_mm: float = 0.0
    counterbore: bool = False

    @property
    def polygon_area_mm2(self) -> float:
        """Area of the bore's cross-section polygon (mm^2)."""
        n = self.sections
        return 0.5 * n * self.radius_mm ** 2 * np.sin(2 * np.pi / n)


@dataclass(frozen=True)
class Solid:
    """The lens solid as a closed, consistently wound triangle mesh (mm).

    vertices: (n, 3) float64 mm; faces: (m, 3) int64, outward winding.
    """
    vertices: np.ndarray
    faces: np.ndarray
    volume_mm3: float
    genus: int
    bore: Bore


def mesh_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (mm^3) of a closed mesh: (n, 3) float mm, (m, 3) int; > 0 if outward."""
    v = np.asarray(vertices, np.float64)
    a, b, c = (v[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def edge_check(faces: np.ndarray) -> dict:
    """Topology of a triangle mesh from its (m, 3) int faces.

    Returns dict(watertight: every edge has exactly two faces, winding_consistent: the
    two faces use it in opposite directions, components: connected shells (by shared
    edges), euler: V - E + F over used vertices).
    """
    f = np.asarray(faces, np.int64)
    n = int(f.max()) + 1 if len(f) else 0
    a = np.concatenate([f[:, 0], f[:, 1], f[:, 2]])
    b = np.concatenate([f[:, 1], f[:, 2], f[:, 0]])
    # Integer keys and one argsort instead of np.unique(axis=0), which is ~10x slower here.
    undirected = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(undirected)
    keys = undirected[order]
    first = np.r_[True, keys[1:] != keys[:-1]]
    counts = np.diff(np.r_[np.flatnonzero(first), len(keys)])
    inverse = np.empty(len(keys), np.int64)
    inverse[order] = np.cumsum(first) - 1
    watertight = bool(np.all(counts == 2))
    # Watertight and no directed edge twice: the two faces of each edge run it opposite ways.
    directed = np.sort(a * n + b)
    winding = watertight and not np.any(directed[1:] == directed[:-1])
    n_vert = int(np.count_nonzero(np.bincount(f.ravel(), minlength=n)))
    euler = n_vert - len(counts) + len(f)
    components = _components(f, inverse, len(counts))
    return {"watertight": watertight, "winding_consistent": bool(winding),
            "components": components, "euler": int(euler)}


def _components(faces: np.ndarray, edge_of_halfedge: np.ndarray, n_edges: int) -> int:
    """Connected components of faces joined by shared edges."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(faces)
    face_of_halfedge = np.tile(np.arange(m), 3)
    graph = coo_matrix((np.ones(len(face_of_halfedge)), (face_of_halfedge, edge_of_halfedge)),
                       shape=(m, n_edges)).tocsr()
    adjacency = graph @ graph.T
    n, _ = connected_components(adjacency, directed=False)
    return int(n)


def plan_bore(inner_vertices: np.ndarray, inner_faces: np.ndarray, mount_radius_mm: float,
              sections: int = 128) -> Bore:
    """Place the bore under the inner layer's flat floor, or refuse with the numbers.

    inner_vertices (n, 3) float mm, inner_faces (m, 3) int with outward winding (normals
    into the glass, so the floor's normals point to -z).  The floor is the set of
    faces lying within ``tolerances.WELD_MM`` of the inner layer's lowest z with
    downward normals; the bore circle plus ``BORE_LEDGE_MM`` must fit inside it around
    the axis, or (a counterbore) the whole floor must lie inside the bore circle less
    ``BORE_LEDGE_MM``.
    """
    v = np.asarray(inner_vertices, np.float64)
    f = np.asarray(inner_faces, np.int64)
    r = float(mount_radius_mm)
    if not r > 0:
        raise LampfabError(f"mount_radius_mm must be positive, got {r}")
    if sections < 8:
        raise LampfabError(f"bore sections must be at least 8, got {sections}")
    z = v[:, 2]
    z0, z1 = float(z.min()), float(z.max())
    if z0 <= 0:
        raise LampfabError(f"inner layer reaches z = {z0:.3f} mm; it must lie above the base (z > 0)")
    tri = v[f]
    normal_z = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 2]
    on_floor = np.all(np.abs(tri[:, :, 2] - z0) <= tolerances.WELD_MM, axis=1) & (normal_z < 0)
    reach = _floor_reach(v[:, :2], f[on_floor])
    floor_vertices = np.unique(f[on_floor])
    extent = float(np.hypot(*v[floor_vertices, :2].T).max()) if len(floor_vertices) else 0.0
    # A counterbore must open the whole bottom: every vertex at the lowest z on the floor.
    whole = len(floor_vertices) and np.isin(np.flatnonzero(np.abs(z - z0) <= tolerances.WELD_MM),
                                            floor_vertices).all()
    if reach > 0 and whole and r >= extent + BORE_LEDGE_MM - tolerances.WELD_MM:
        return Bore(radius_mm=r, sections=int(sections), z_bottom_mm=-BORE_BELOW_MM, z_floor_mm=z0,
                    z_top_mm=z0, floor_reach_mm=reach, floor_extent_mm=extent, counterbore=True)
    need = r + BORE_LEDGE_MM
    if reach < need:
        where = (f"its flat bottom at z = {z0:.2f} mm reaches {reach:.2f} mm from the axis"
                 if reach > 0 else f"it has no flat bottom around the axis at its lowest z = {z0:.2f} mm")
        # The bounds named are rounded to 0.01 mm towards the side that is accepted, so
        # that the value a user copies from the message passes.
        wider = (f" or >= {math.ceil(100 * (extent + BORE_LEDGE_MM - tolerances.WELD_MM)) / 100:.2f} "
                 f"(a counterbore opening the whole floor, which reaches "
                 f"{extent:.2f} mm)" if reach > 0 and whole else "")
        raise LampfabError(
            f"mount_radius_mm {r:g} is too large for the inner layer: the bore enters the cavity through "
            f"the inner layer's flat bottom and needs it to reach {need:.2f} mm from the axis (bore radius + "
            f"{BORE_LEDGE_MM} mm ledge), but {where}; a bore in between would cut glass beside the cavity. "
            f"Use mount_radius_mm <= {max(math.floor(100 * (reach - BORE_LEDGE_MM)) / 100, 0):.2f}{wider}, "
            f"or give the inner layer a wider flat bottom centred on the axis")
    overlap = min(BORE_OVERLAP_MM, 0.5 * (z1 - z0))
    return Bore(radius_mm=r, sections=int(sections), z_bottom_mm=-BORE_BELOW_MM, z_floor_mm=z0,
                z_top_mm=z0 + overlap, floor_reach_mm=reach, floor_extent_mm=extent)


def _floor_reach(xy: np.ndarray, floor_faces: np.ndarray) -> float:
    """Radius of the largest disk around (0, 0) inside the union of floor triangles (mm).

    0 if no triangle contains the axis.  The union's boundary is its edges used once.
    """
    if len(floor_faces) == 0:
        return 0.0
    a, b, c = (xy[floor_faces[:, k]] for k in range(3))
    # The axis lies in a triangle when it is on the same side of all three edges.
    def side(p, q):
        return (q[:, 0] - p[:, 0]) * (0.0 - p[:, 1]) - (q[:, 1] - p[:, 1]) * (0.0 - p[:, 0])
    s1, s2, s3 = side(a, b), side(b, c), side(c, a)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    if not inside.any():
        return 0.0
    edges = np.sort(np.concatenate([floor_faces[:, [0, 1]], floor_faces[:, [1, 2]],
                                    floor_faces[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = uniq[counts == 1]
    p, q = xy[boundary[:, 0]], xy[boundary[:, 1]]
    d = q - p
    t = np.clip(-np.einsum("ij,ij->i", p, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0.0, 1.0)
    closest = p + t[:, None] * d
    return float(np.min(np.hypot(closest[:, 0], closest[:, 1])))


def _check(m, what: str):
    """Raise GeometryError unless manifold3d's status is NoError; return ``m``."""
    import manifold3d

    status = m.status()
    if status != manifold3d.Error.NoError:
        raise GeometryError(f"manifold3d: {what} failed with status {status.name}")
    return m


def _manifold(vertices: np.ndarray, faces: np.ndarray, what: str):
    import manifold3d

    mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(vertices, np.float64),
                             tri_verts=np.ascontiguousarray(faces, np.uint64))
    return _check(manifold3d.Manifold(mesh), f"{what} (mesh to manifold)")


def _arrays(m) -> tuple[np.ndarray, np.ndarray]:
    mesh = m.to_mesh64()
    verts = np.asarray(mesh.vert_properties, np.float64)[:, :3].copy()
    return verts, np.asarray(mesh.tri_verts, np.int64).copy()


def _bore_manifold(bore: Bore):
    import manifold3d

    prism = manifold3d.Manifold.cylinder(height=bore.z_top_mm - bore.z_bottom_mm, radius_low=bore.radius_mm,
                                         radius_high=-1.0, circular_segments=bore.sections, center=False)
    return _check(prism.translate((0.0, 0.0, bore.z_bottom_mm)), "bore prism")


def _cavity(inner_vertices, inner_faces, bore: Bore):
    """(manifold of inner ∪ bore, inner manifold), with the bore checked to add only glass below the floor."""
    inner = _manifold(inner_vertices, inner_faces, "inner layer")
    v_inner = inner.volume()
    if not v_inner > 0:
        raise GeometryError(f"inner layer has volume {v_inner:.6g} mm^3; expected outward winding and > 0")
    cavity = _check(inner + _bore_manifold(bore), "cavity union (inner layer + bore)")
    if len(cavity.decompose()) != 1:
        raise GeometryError("cavity (inner layer + bore) is not one connected body")
    expected = v_inner + bore.polygon_area_mm2 * (bore.z_floor_mm - bore.z_bottom_mm)
    if abs(cavity.volume() - expected) > tolerances.MANIFOLD_VOLUME_REL * expected:
        raise LampfabError(
            f"the bore (radius {bore.radius_mm:g} mm) reaches glass beside the cavity above its floor at "
            f"z = {bore.z_floor_mm:.2f} mm: cavity volume {cavity.volume():.3f} mm^3, expected {expected:.3f} "
            f"(inner {v_inner:.3f} + bore below the floor); lower mount_radius_mm")
    return cavity, inner


def build_solid(cyl: surface.Cylinder, heights: np.ndarray, tessellation: int,
                inner_vertices: np.ndarray, inner_faces: np.ndarray, mount_radius_mm: float,
                bore_sections: int = 128, slots=None) -> Solid:
    """The lens solid: ``closed_outer_mesh`` minus (inner layer ∪ bore) and ``slots``
    (``slots.Slots``, or None), verified.

    cyl: the plain cylinder (mm); heights: (nu, nv) float mm radial offsets at the
    nodes; tessellation: vertices per heightmap cell edge; inner_vertices (n, 3) float
    mm and inner_faces (m, 3) int: the closed inner layer, outward winding (as
    ``inner.load_inner`` returns it); mount_radius_mm: bore radius; bore_sections: the
    bore polygon's sides.

    Raises LampfabError if the bore does not fit the inner layer's floor or the
    cavity or a slot is not inside the outer surface, GeometryError if manifold3d reports a bad
    status or the result fails a check.
    """
    import manifold3d  # noqa: F401 - fail early with ImportError if missing

    bore = plan_bore(inner_vertices, inner_faces, mount_radius_mm, bore_sections)
    ov, of = surface.closed_outer_mesh(cyl, heights, tessellation)
    radius = np.hypot(ov[:-2, 0], ov[:-2, 1])
    near_base = ov[:-2, 2] <= bore.z_top_mm
    if radius[near_base].min() < bore.radius_mm + BORE_LEDGE_MM:
        raise LampfabError(f"the bore (radius {bore.radius_mm:g} mm) comes within {BORE_LEDGE_MM} mm of the outer "
                           f"surface, which comes in to {radius[near_base].min():.2f} mm near the base")
    outer = _manifold(ov, of, "outer surface")
    v_outer = outer.volume()
    if not v_outer > 0:
        raise GeometryError(f"outer surface has volume {v_outer:.6g} mm^3; expected > 0")
    cavity, inner = _cavity(inner_vertices, inner_faces, bore)
    solid = _check(outer - cavity, "outer minus cavity")
    slot_glass = 0.0
    if slots is not None:
        solid = _check(solid - _check(slots.manifold(), "slots"), "lens minus slots")
        slot_glass = slots.glass_mm3

    # The cavity inside the outer surface: all of it but the bore below z = 0.  Each slot
    # lies in the glass above the base, so it takes its whole box there.
    v_cavity_in = cavity.volume() - bore.polygon_area_mm2 * (0.0 - bore.z_bottom_mm)
    expected = v_outer - v_cavity_in - slot_glass
    volume = solid.volume()
    if not volume > 0 or abs(volume - expected) > tolerances.MANIFOLD_VOLUME_REL * v_outer:
        raise LampfabError(
            f"lens solid has volume {volume:.3f} mm^3 but outer {v_outer:.3f} - cavity {v_cavity_in:.3f} - slots "
            f"{slot_glass:.3f} = {expected:.3f}: the inner layer, the bore or a slot crosses the outer surface")
    bodies = len(solid.decompose())
    if bodies != 1:
        raise GeometryError(f"lens solid has {bodies} bodies; expected one")
    verts, faces = _arrays(solid)
    topo = edge_check(faces)
    if not (topo["watertight"] and topo["winding_consistent"]):
        raise GeometryError(f"lens solid mesh is not closed and consistently wound: {topo}")
    if topo["components"] != 1:
        raise GeometryError(f"lens solid has {topo['components']} boundary shells; expected one "
                            f"(the cavity must open through the base)")
    genus = solid.genus()
    if genus != inner.genus() or topo["euler"] != 2 - 2 * genus:
        raise GeometryError(f"lens solid has genus {genus} (Euler {topo['euler']}); expected the inner layer's "
                            f"genus {inner.genus()}")
    v_arrays = mesh_volume(verts, faces)
    if abs(v_arrays - volume) > tolerances.MANIFOLD_VOLUME_REL * v_outer:
        raise GeometryError(f"lens solid volume from its mesh {v_arrays:.3f} mm^3 != manifold3d's {volume:.3f}")
    return Solid(vertices=verts, faces=faces, volume_mm3=float(volume), genus=int(genus), bore=bore)
