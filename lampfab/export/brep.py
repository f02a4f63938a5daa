"""The lamp as an OCCT solid: one smooth B-spline outer face, planar caps, a faceted cavity.

The solid is assembled from faces that share their edges, with no OCCT boolean and no
sewing: the outer face (``bspline.fit_samples``), the top cap and the bottom cap
(bounded by the outer face's own boundary edges; the bottom cap has the bore's circular
opening), the bore as an analytic cylinder from z = 0 up to the inner layer's flat
floor, and the inner layer's triangles merged into planar polygon faces (the floor gets
the bore's circle as a hole).  Units: mm.
"""

from __future__ import annotations

import time

import numpy as np

from .. import surface
from ..errors import GeometryError
from ..solid import BORE_LEDGE_MM, plan_bore
from ..tolerances import OCC_COINCIDENT_MM, OCC_TOLERANCE_MM, PLANAR_MM


def _edges_of(face) -> list:
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    ex = TopExp_Explorer(face, TopAbs_EDGE)
    while ex.More():
        out.append(TopoDS.Edge_s(ex.Current()))
        ex.Next()
    return out


def _boundary_edge(face, z_mm: float):
    """The non-seam edge of a periodic face lying at height ``z_mm``, oriented as the face uses it."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve

    for e in _edges_of(face):
        if BRep_Tool.IsClosed_s(e, face):
            continue
        c = BRepAdaptor_Curve(e)
        if abs(c.Value(0.5 * (c.FirstParameter() + c.LastParameter())).Z() - z_mm) < OCC_COINCIDENT_MM:
            return e
    raise GeometryError(f"STEP: no boundary edge at z = {z_mm} mm on a periodic face")


def _wire(edges):
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Wire

    builder = BRep_Builder()
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    for e in edges:
        builder.Add(wire, e)
    wire.Closed(True)
    return wire


def _planar_face(origin, normal, outer, holes=()):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.gp import gp_Dir, gp_Pln, gp_Pnt

    plane = gp_Pln(gp_Pnt(*map(float, origin)), gp_Dir(*map(float, normal)))
    mf = BRepBuilderAPI_MakeFace(plane, outer, True)
    for h in holes:
        mf.Add(h)
    if not mf.IsDone():
        raise GeometryError(f"STEP: planar face at {np.round(origin, 3).tolist()} failed ({mf.Error()})")
    return mf.Face()


def _facet_groups(vertices: np.ndarray, faces: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Split a closed mesh into planar regions: [(face indices, unit normal (3,))].

    Coplanar adjacent triangles (trimesh facets) form one region when all their
    vertices lie within PLANAR_MM of the plane; every other triangle is its own region.
    """
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    normals = np.asarray(mesh.face_normals)
    groups, used = [], np.zeros(len(faces), bool)
    for facet in mesh.facets:
        n = normals[facet].mean(axis=0)
        n /= np.linalg.norm(n)
        idx = np.unique(faces[facet])
        d = (vertices[idx] - vertices[idx[0]]) @ n
        if np.ptp(d) <= PLANAR_MM:
            groups.append((np.asarray(facet), n))
            used[facet] = True
    for k in np.flatnonzero(~used):
        groups.append((np.array([k]), normals[k]))
    return groups


def _loops(faces: np.ndarray) -> list[list[int]] | None:
    """Boundary loops of a set of triangles as vertex lists in the triangles' winding.

    None if the boundary is not a set of simple loops (a vertex with two outgoing edges).
    """
    directed = [(int(a), int(b)) for a, b in
                np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])]
    inside = set(directed)
    nxt = {}
    for a, b in directed:
        if (b, a) not in inside:
            if a in nxt:
                return None
            nxt[a] = b
    loops = []
    while nxt:
        start = next(iter(nxt))
        loop, cur = [start], nxt.pop(start)
        while cur != start:
            loop.append(cur)
            cur = nxt.pop(cur, None)
            if cur is None:
                return None
        loops.append(loop)
    return loops


def _signed_area(points: np.ndarray, normal: np.ndarray) -> float:
    """Area of a closed polygon (k, 3) projected on ``normal``, > 0 if counter-clockwise about it."""
    return 0.5 * float(np.dot(np.cross(points, np.roll(points, -1, axis=0)).sum(axis=0), normal))


def build_step_solid(cyl: surface.Cylinder, inner_vertices: np.ndarray, inner_faces: np.ndarray,
                     mount_radius_mm: float, fitted: dict, slots=None) -> tuple[object, dict]:
    """The lens as an OCCT solid (TopoDS_Solid) around the outer B-spline ``fitted``
    (``bspline.fit_samples``) and figures about it, with ``slots`` (``slots.Slots``, or
    None) as pockets in the base (``_slot_faces``).

    Returns (solid, dict(fit_s, build_s, poles_u, poles_v,
    faces, deviation dict, bore dict)).
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_CylindricalSurface
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt
    from OCP.TopoDS import TopoDS, TopoDS_Shell, TopoDS_Solid

    v = np.asarray(inner_vertices, np.float64)
    f = np.asarray(inner_faces, np.int64)
    bore = plan_bore(v, f, mount_radius_mm)
    height = cyl.height_mm
    fit, occ = fitted["fit"], fitted["surface"]

    t0 = time.perf_counter()
    u_first, u_last = float(fit["u_knots"][0]), float(fit["u_knots"][-1])
    outer = BRepBuilderAPI_MakeFace(occ, u_first, u_last, 0.0, height, OCC_TOLERANCE_MM)
    if not outer.IsDone():
        raise GeometryError(f"STEP: outer B-spline face failed ({outer.Error()})")
    outer = outer.Face()
    bore_mf = BRepBuilderAPI_MakeFace(Geom_CylindricalSurface(gp_Ax3(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)),
                                                              bore.radius_mm),
                                      0.0, 2 * np.pi, 0.0, bore.z_floor_mm, OCC_TOLERANCE_MM)
    if not bore_mf.IsDone():
        raise GeometryError(f"STEP: bore cylinder face failed ({bore_mf.Error()})")
    # The cylinder's natural normal points away from the axis, into the glass: reverse it.
    bore_face = TopoDS.Face_s(bore_mf.Face().Reversed())
    # An edge shared by two faces is used in opposite directions: the neighbour takes it reversed.
    pockets, openings = _slot_faces(slots)
    bottom = _planar_face((0, 0, 0), (0, 0, -1), _wire([_boundary_edge(outer, 0.0).Reversed()]),
                          [_wire([_boundary_edge(bore_face, 0.0).Reversed()]), *openings])
    top = _planar_face((0, 0, height), (0, 0, 1), _wire([_boundary_edge(outer, height).Reversed()]))
    faces = [outer, top, bottom, bore_face, *pockets]

    # Cavity: the inner layer's planar regions, normals flipped to point out of the glass.
    edge = _edges_between(v)

    # The bore's circle at the floor: a hole in the floor, or (a counterbore) the outer
    # boundary of the annular shoulder that replaces the floor.
    bore_circle = _wire([_boundary_edge(bore_face, bore.z_floor_mm).Reversed()])
    floor_done = False
    for group, n in _facet_groups(v, f):
        loops = _loops(f[group]) if len(group) > 1 else [list(map(int, f[group[0]]))]
        if loops is None:
            loops_per = [[list(map(int, f[k]))] for k in group]
            normals = [np.cross(v[f[k, 1]] - v[f[k, 0]], v[f[k, 2]] - v[f[k, 0]]) for k in group]
            parts = [(lp, nn / np.linalg.norm(nn)) for lp, nn in zip(loops_per, normals)]
        else:
            parts = [(loops, n)]
        for loops, n in parts:
            out_n = -n
            # Reversed loops run counter-clockwise about the outward normal -n.
            loops = [lp[::-1] for lp in loops]
            areas = [_signed_area(v[lp], out_n) for lp in loops]
            outers = [k for k, a in enumerate(areas) if a > 0]
            if len(outers) != 1:
                raise GeometryError(f"STEP: an inner-layer facet has {len(outers)} outer boundaries")
            wires = [_wire([edge(lp[k], lp[(k + 1) % len(lp)]) for k in range(len(lp))]) for lp in loops]
            outer_wire = wires[outers[0]]
            holes = [w for k, w in enumerate(wires) if k != outers[0]]
            on_floor = (not floor_done and out_n[2] > 1 - 1e-12
                        and abs(v[loops[0][0], 2] - bore.z_floor_mm) <= PLANAR_MM)
            if on_floor and bore.counterbore and not holes:
                # The counterbore opens the floor: glass faces down from the bore's circle in
                # to the floor's edge, whose edges it takes in the floor's own direction.
                faces.append(_planar_face((0, 0, bore.z_floor_mm), (0, 0, -1), bore_circle, [outer_wire]))
                floor_done = True
                continue
            if on_floor and _contains_disk(v[loops[outers[0]]][:, :2], bore.radius_mm + 0.5 * BORE_LEDGE_MM):
                holes.append(bore_circle)
                floor_done = True
            faces.append(_planar_face(v[np.concatenate(loops)].mean(axis=0), out_n, outer_wire, holes))
    if not floor_done:
        raise GeometryError(f"STEP: no single planar face of the inner layer's floor at z = {bore.z_floor_mm:.3f} mm "
                            f"holds the bore's circle (radius {bore.radius_mm:g} mm); the floor must be flat to "
                            f"{PLANAR_MM:g} mm and horizontal")

    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    for face in faces:
        builder.Add(shell, face)
    shell.Closed(True)
    solid = TopoDS_Solid()
    builder.MakeSolid(solid)
    builder.Add(solid, shell)
    t_build = time.perf_counter() - t0
    return solid, {"fit_s": fitted["seconds"], "build_s": t_build, "poles_u": int(fit["poles"].shape[0]),
                   "poles_v": int(fit["poles"].shape[1]), "faces": len(faces), "deviation": fitted["deviation"],
                   "bore": {"radius_mm": bore.radius_mm, "z_floor_mm": bore.z_floor_mm}}


def _contains_disk(polygon_xy: np.ndarray, radius: float) -> bool:
    """Whether a simple polygon (k, 2) contains the disk of ``radius`` around the origin."""
    p, q = polygon_xy, np.roll(polygon_xy, -1, axis=0)
    crossings = ((p[:, 1] > 0) != (q[:, 1] > 0)) & \
        (p[:, 0] + (0 - p[:, 1]) * (q[:, 0] - p[:, 0]) / np.where(q[:, 1] == p[:, 1], 1, q[:, 1] - p[:, 1]) > 0)
    if crossings.sum() % 2 == 0:
        return False
    d = q - p
    t = np.clip(-np.einsum("ij,ij->i", p, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    return bool(np.min(np.linalg.norm(p + t[:, None] * d, axis=1)) >= radius)


def _edges_between(points: np.ndarray):
    """``edge(a, b)``: the straight edge from ``points[a]`` to ``points[b]`` ((n, 3) mm),
    each vertex and edge made once, so that the faces on either side of an edge share
    it; run from b to a, it is the same edge reversed."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
    from OCP.gp import gp_Pnt

    vertices, edges = {}, {}

    def vertex(i):
        if i not in vertices:
            vertices[i] = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, points[i]))).Vertex()
        return vertices[i]

    def edge(a, b):
        key = (min(a, b), max(a, b))
        if key not in edges:
            edges[key] = BRepBuilderAPI_MakeEdge(vertex(key[0]), vertex(key[1])).Edge()
        return edges[key] if a == key[0] else edges[key].Reversed()
    return edge


def _slot_faces(slots) -> tuple[list, list]:
    """The faces of ``slots``'s pockets (``slots.Slots``, or None: none) and their
    openings in the base as wires, built on shared edges as the rest of the solid is:
    an OCCT boolean cut of the same boxes took 8-13 s, each box's walls meeting the
    B-spline face's bounding box.

    Each pocket's outline runs counter-clockwise about +z (``Slots.outlines``); its faces
    point out of the glass, into the pocket, so each takes its loop clockwise as seen
    from inside the glass, and the base takes the opening the other way round.
    """
    if slots is None:
        return [], []
    faces, openings = [], []
    for outline in slots.outlines():
        n = len(outline)
        # Corner k of the outline at the base is point k, under the roof point n + k.
        edge = _edges_between(np.vstack([np.column_stack([outline, np.full(n, z)]) for z in (0.0, slots.top_mm)]))
        for k in range(n):
            j = (k + 1) % n
            a, b = outline[k], outline[j]
            inward = np.array([-(b[1] - a[1]), b[0] - a[0], 0.0])  # into the pocket: left of a -> b
            loop = [(k, n + k), (n + k, n + j), (n + j, j), (j, k)]
            faces.append(_planar_face((*(0.5 * (a + b)), 0.5 * slots.top_mm), inward / np.linalg.norm(inward),
                                      _wire([edge(p, q) for p, q in loop])))
        faces.append(_planar_face((*outline.mean(axis=0), slots.top_mm), (0, 0, -1),
                                  _wire([edge(n + (k + 1) % n, n + k) for k in reversed(range(n))])))
        openings.append(_wire([edge(k, (k + 1) % n) for k in range(n)]))
    return faces, openings
