"""Topology of the final solid's triangle mesh for the fabrication checks (see ``lamp``).

pymeshlab gives the authoritative counts (topological measures, self-intersecting
faces: on a lens of this project it found 180 self-intersecting faces where trimesh
said watertight); numpy edge bookkeeping here gives the places to point at and splits the
surface into shells, so that a sealed void (a closed shell facing inward) can be told
from a second body (a closed shell facing outward).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import tolerances


@dataclass
class MeshReport:
    """What the solid's mesh is made of (counts, and one place for each kind of defect).

    Places are (3,) mm points or None.  ``shell_volume`` (shells,) mm^3 is signed: a
    closed shell wound outward has positive volume, a void's shell (wound into the
    solid) negative.  ``shell_point`` (shells, 3) mm is a point on each shell: the
    centroid of its vertices for a void (the void's middle), else its lowest vertex.
    """
    vertices: int
    faces: int
    welded: int                      # vertices merged by the weld (0 for an indexed mesh)
    degenerate: int                  # faces that collapsed in the weld
    boundary_edges: int
    non_manifold_edges: int
    non_manifold_vertices: int
    self_intersecting_faces: int
    misoriented_edges: int           # edges used twice in the same direction
    shell_volume: np.ndarray
    shell_point: np.ndarray
    places: dict = field(default_factory=dict)


def weld(vertices: np.ndarray, faces: np.ndarray, tol_mm: float = tolerances.WELD_MM):
    """Merge vertices closer than ~tol (grid rounding) and drop faces that collapse.

    An STL arrives as a triangle soup, three vertices per face; slicers weld by position,
    so topology is judged after the same weld.  Returns ((n', 3) float64 mm, (m', 3)
    int64, merged count, collapsed face count).
    """
    q = np.round(np.asarray(vertices, np.float64) / tol_mm).astype(np.int64)
    _, first, inverse = np.unique(q, axis=0, return_index=True, return_inverse=True)
    f = inverse.reshape(-1)[faces]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    return vertices[first], f[ok], len(vertices) - len(first), int((~ok).sum())


def face_area_nz(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each triangle's area ((m,) mm^2) and the z part of its unit normal ((m,), by the
    faces' winding); vertices (n, 3) float mm, faces (m, 3) int."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    return area, cross[:, 2] / np.maximum(2 * area, 1e-300)  # a degenerate face: n_z 0


def inspect_mesh(vertices: np.ndarray, faces: np.ndarray, self_intersections: bool = True) -> MeshReport:
    """Count every defect of a triangle mesh (vertices (n, 3) mm, faces (m, 3) int).

    The mesh is welded first only if it has open edges as given (an indexed mesh from
    manifold3d is judged exactly as it is).
    """
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    welded = degenerate = 0
    key, counts, order, start = _edges(f, len(v))
    if (counts == 1).any():
        wv, wf, welded, degenerate = weld(v, f)
        if welded or degenerate:                     # else keep the caller's vertex order
            v, f = wv, wf
            key, counts, order, start = _edges(f, len(v))
    places: dict = {}

    boundary = counts == 1
    non_manifold = counts > 2
    if boundary.any():
        places["boundary_edges"] = _edge_place(v, key[boundary], len(v))
    if non_manifold.any():
        places["non_manifold_edges"] = _edge_place(v, key[non_manifold], len(v))
    # A consistently wound closed surface uses every edge once in each direction.
    directed = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    dkey = directed[:, 0] * len(v) + directed[:, 1]
    dk, dcount = np.unique(dkey, return_counts=True)
    mis = dk[dcount > 1]
    if len(mis):
        a, b = np.divmod(mis, len(v))
        places["misoriented_edges"] = _nearest_to_mean(0.5 * (v[a] + v[b]))

    labels, n_shells = _shells(f, order, start, counts)
    tri = v[f] - v.mean(axis=0)                                   # centred: better rounding
    vol_f = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    shell_volume = np.bincount(labels, weights=vol_f, minlength=n_shells)
    shell_point = np.zeros((n_shells, 3))
    for s in range(n_shells):
        ids = np.unique(f[labels == s])
        pts = v[ids]
        shell_point[s] = pts.mean(axis=0) if shell_volume[s] < 0 else pts[np.argmin(pts[:, 2])]

    topo, selected = _meshlab(v, f, self_intersections)
    if selected is not None and selected.any():
        places["self_intersecting_faces"] = _nearest_to_mean(v[f[selected]].mean(axis=1))
    if topo.get("non_two_manifold_vertices", 0) and "non_manifold_vertices" not in places:
        places["non_manifold_vertices"] = None
    return MeshReport(
        vertices=len(v), faces=len(f), welded=int(welded), degenerate=int(degenerate),
        boundary_edges=int(topo.get("boundary_edges", boundary.sum())),
        non_manifold_edges=int(topo.get("non_two_manifold_edges", non_manifold.sum())),
        non_manifold_vertices=int(topo.get("non_two_manifold_vertices", 0)),
        self_intersecting_faces=int(selected.sum()) if selected is not None else 0,
        misoriented_edges=int(len(mis)), shell_volume=shell_volume, shell_point=shell_point,
        places=places)


def _edges(f: np.ndarray, nv: int):
    """Undirected edges grouped: (keys (e,), use counts (e,), sort order (3m,), group starts (e,)).

    Edge i of face j is entry 3*j + i of ``order``'s domain.
    """
    e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    k = e[:, 0] * nv + e[:, 1]
    order = np.argsort(k, kind="stable")
    key, start, counts = np.unique(k[order], return_index=True, return_counts=True)
    return key, counts, order, start


def _shells(f, order, start, counts):
    """Connected components of faces across shared edges: ((m,) labels, count)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    # Link each face using an edge to the first face using it (enough for connectivity,
    # also across non-manifold edges used three or more times).
    grp = np.repeat(np.arange(len(start)), counts)
    first_face = order[start][grp] // 3
    this_face = order // 3
    m = len(f)
    graph = coo_matrix((np.ones(len(order)), (first_face, this_face)), shape=(m, m))
    n, labels = connected_components(graph, directed=False)
    return labels, n


def _edge_place(v, keys, nv):
    a, b = np.divmod(keys, nv)
    return _nearest_to_mean(0.5 * (v[a] + v[b]))


def _nearest_to_mean(pts: np.ndarray) -> np.ndarray:
    """The point of a defect cluster nearest its mean: on the defect, not between two."""
    c = pts.mean(axis=0)
    return pts[np.argmin(np.linalg.norm(pts - c, axis=1))].astype(np.float64)


def _meshlab(v, f, self_intersections):
    """pymeshlab's topological measures and self-intersecting faces ((m,) bool or None).

    Call it from the main thread: run in a worker thread pymeshlab 2025.7 corrupted the
    heap (glibc abort at interpreter exit, every time).
    """
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v, face_matrix=f.astype(np.int32)))
    topo = ms.get_topological_measures()
    selected = None
    if self_intersections:
        ms.compute_selection_by_self_intersections_per_face()
        selected = np.asarray(ms.current_mesh().face_selection_array(), bool)
    return topo, selected
