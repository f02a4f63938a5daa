"""The lens as a STEP solid: one smooth B-spline outer face, planar caps, a faceted cavity.

The outer surface is ONE periodic-in-u, degree-3 ``Geom_BSplineSurface`` that
interpolates the heightmap surface (``surface.py``) at ``samples_u x samples_v``
points.  Its poles are computed here: an interpolating not-a-knot cubic spline in v
(parameter v = z in mm; with ``samples_v == nv`` this reproduces surface.py's z spline
exactly), then in u (parameter u = angle in rad) the same basis the heightmap uses: the
uniform periodic cubic (a circulant solve), or for a creased lens one not-a-knot cubic
per sector, joined by knots of multiplicity 3 (C0) at the sector seams.  OCCT's
``GeomAPI_PointsToBSplineSurface`` is not used: its periodic interpolation is wrong
between samples near the seam (shared fabrication facts).

The solid is assembled from faces that share their edges, with no OCCT boolean and no
sewing: the outer face, the top cap and the bottom cap (bounded by the outer face's own
boundary edges; the bottom cap has the bore's circular opening), the bore as an analytic
cylinder from z = 0 up to the inner layer's flat floor, and the inner layer's triangles
merged into planar polygon faces (the floor gets the bore's circle as a hole).
Units: mm (the STEP file says so).
"""

from __future__ import annotations

import contextlib
import datetime
import os
import time
from pathlib import Path

import numpy as np

from . import surface
from .artifacts import atomic_path
from .errors import GeometryError, LampfabError
from .solid import BORE_LEDGE_MM, plan_bore
from .tolerances import OCC_COINCIDENT_MM, OCC_TOLERANCE_MM, OCC_VOLUME_REL, PLANAR_MM, VOLUME_REL


# ---------------------------------------------------------------- the B-spline fit

def bspline_poles(cyl: surface.Cylinder, heights: np.ndarray, samples_u: int,
                  samples_v: int) -> dict:
    """Poles and knots of the degree-3 B-spline through the surface samples (pure numpy).

    Samples: ``surface.points(cyl, surface.sample(cyl, heights, samples_u, samples_v))``,
    (samples_u, samples_v, 3) mm at u = 2*pi*k/samples_u, z = H*j/(samples_v - 1).
    In u the spline is periodic: the uniform cubic (smooth surface), or (creased) one
    not-a-knot cubic per sector with knots of multiplicity 3 at the seams, where it is
    C0, starting at the first seam.  Returns dict(poles (samples_u, samples_v, 3) float64
    mm, u_knots (k,) rad and u_mults (k,) int (periodic), v_knots (k,) mm and v_mults (k,)
    int (clamped), samples (samples_u, samples_v, 3) mm).
    """
    from scipy.interpolate import make_interp_spline

    mu, mv = int(samples_u), int(samples_v)
    if mu < 8 or mv < 4 or (cyl.creased and mu % 8):
        raise LampfabError(f"STEP samples {mu} x {mv}: need at least 8 around (a multiple of 8 for a creased "
                           f"surface) and 4 up")
    pts = surface.points(cyl, surface.sample(cyl, heights, mu, mv))
    z = cyl.node_z(mv)
    # v: not-a-knot cubic through the rows; its coefficients are clamped B-spline poles.
    spl = make_interp_spline(z, pts.transpose(1, 0, 2).reshape(mv, -1), k=3)
    rows = spl.c.reshape(mv, mu, 3).transpose(1, 0, 2)
    v_knots, v_mults = np.unique(spl.t, return_counts=True)
    # u: the same B-spline basis the heightmap uses, on the samples as nodes.  OCCT's
    # periodic poles start at the first knot: 0 (smooth) or the first seam (creased).
    basis = surface.u_basis(mu, cyl.creased)
    coef = np.einsum("ij,jvk->ivk", basis.coef_from_nodes, rows)
    if cyl.creased:
        first = basis.first_node(0)
        poles = np.roll(coef, -first, axis=0)
        inner = basis.local.t[4:-4]                      # one sector's interior knots on [0, 1]
        quarter = np.pi / 2
        u_knots = [np.radians(surface.SEAMS_DEG[0]) + quarter * np.concatenate([[s], s + inner]) for s in range(4)]
        u_knots = np.append(np.concatenate(u_knots), np.radians(surface.SEAMS_DEG[0]) + 2 * np.pi)
        u_mults = np.ones(len(u_knots), np.int64)
        u_mults[np.isin(np.arange(len(u_knots)), np.arange(0, len(u_knots), len(inner) + 1))] = 3
    else:
        # OCCT's uniform periodic basis gives the value at knot k as (P[k] + 4 P[k+1] + P[k+2]) / 6.
        poles = np.roll(coef, 1, axis=0)
        u_knots = np.arange(mu + 1) * (2 * np.pi / mu)
        u_mults = np.ones(mu + 1, np.int64)
    return {"poles": poles, "u_knots": u_knots, "u_mults": u_mults, "v_knots": v_knots,
            "v_mults": v_mults.astype(np.int64), "samples": pts}


def _occ_surface(fit: dict):
    from OCP.Geom import Geom_BSplineSurface
    from OCP.gp import gp_Pnt
    from OCP.TColgp import TColgp_Array2OfPnt
    from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal

    poles = fit["poles"]
    mu, mv, _ = poles.shape
    arr = TColgp_Array2OfPnt(1, mu, 1, mv)
    for i in range(mu):
        for j in range(mv):
            x, y, z = poles[i, j]
            arr.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(z)))

    def reals(values):
        out = TColStd_Array1OfReal(1, len(values))
        for k, x in enumerate(values):
            out.SetValue(k + 1, float(x))
        return out

    def ints(values):
        out = TColStd_Array1OfInteger(1, len(values))
        for k, x in enumerate(values):
            out.SetValue(k + 1, int(x))
        return out

    return Geom_BSplineSurface(arr, reals(fit["u_knots"]), reals(fit["v_knots"]), ints(fit["u_mults"]),
                               ints(fit["v_mults"]), 3, 3, True, False)


def deviation(cyl: surface.Cylinder, heights: np.ndarray, occ_surface, samples_u: int,
              samples_v: int) -> dict:
    """How far the B-spline is from the heightmap surface, at and between the samples (mm).

    Evaluates the OCCT surface on the doubled grid (u at samples and midpoints, v
    likewise).  ``interpolation_mm``: largest distance to the sample points;
    ``radial_mm``: largest |radius of the B-spline point - (R + s(angle, z))| at the
    points between samples (s evaluated at the B-spline point's own angle and z: the
    surface's radial error, an upper bound on the distance to the surface);
    ``parametric_mm``: largest |B(u, v) - X(u, v)| there (also an upper bound).
    """
    from OCP.gp import gp_Pnt

    mu, mv = int(samples_u), int(samples_v)
    u = np.arange(2 * mu) * (np.pi / mu)
    z = np.linspace(0.0, cyl.height_mm, 2 * mv - 1)
    out = np.empty((len(u), len(z), 3))
    p = gp_Pnt()
    for i, ui in enumerate(u):
        row = out[i]
        for j, zj in enumerate(z):
            occ_surface.D0(float(ui), float(zj), p)
            row[j] = (p.X(), p.Y(), p.Z())
    uu, zz = np.meshgrid(u, z, indexing="ij")
    r_true = cyl.radius_mm + surface.sample(cyl, heights, 2 * mu, 2 * mv - 1)  # the grid above
    true = np.stack([r_true * np.cos(uu), r_true * np.sin(uu), zz], axis=-1)
    at_sample = np.zeros(out.shape[:2], bool)
    at_sample[::2, ::2] = True
    err = np.linalg.norm(out - true, axis=-1)
    between = out[~at_sample]
    phi = np.arctan2(between[:, 1], between[:, 0])
    radial = np.hypot(between[:, 0], between[:, 1]) - (cyl.radius_mm + surface.evaluate(cyl, heights, phi, between[:, 2]))
    k = int(np.argmax(np.abs(radial)))
    return {"interpolation_mm": float(err[at_sample].max()), "radial_mm": float(np.abs(radial).max()),
            "radial_at_mm": np.round(between[k], 3).tolist(), "parametric_mm": float(err[~at_sample].max())}


# ---------------------------------------------------------------- topology helpers

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


# ---------------------------------------------------------------- the solid

def build_step_solid(cyl: surface.Cylinder, inner_vertices: np.ndarray, inner_faces: np.ndarray,
                     mount_radius_mm: float, fitted: dict) -> tuple[object, dict]:
    """The lens as an OCCT solid (TopoDS_Solid) around the outer B-spline ``fitted``
    (``fit_samples``) and figures about it.

    Returns (solid, dict(fit_s, build_s, poles_u, poles_v,
    faces, deviation dict, bore dict)).
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeVertex
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
    bottom = _planar_face((0, 0, 0), (0, 0, -1), _wire([_boundary_edge(outer, 0.0).Reversed()]),
                          [_wire([_boundary_edge(bore_face, 0.0).Reversed()])])
    top = _planar_face((0, 0, height), (0, 0, 1), _wire([_boundary_edge(outer, height).Reversed()]))
    faces = [outer, top, bottom, bore_face]

    # Cavity: the inner layer's planar regions, normals flipped to point out of the glass.
    vertex_cache, edge_cache = {}, {}

    def vertex(i):
        if i not in vertex_cache:
            vertex_cache[i] = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, v[i]))).Vertex()
        return vertex_cache[i]

    def edge(a, b):
        key = (min(a, b), max(a, b))
        if key not in edge_cache:
            edge_cache[key] = BRepBuilderAPI_MakeEdge(vertex(key[0]), vertex(key[1])).Edge()
        e = edge_cache[key]
        return e if a == key[0] else e.Reversed()

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


def shape_figures(shape) -> dict:
    """dict(n_solids, valid (BRepCheck_Analyzer), closed (every shell), volume_mm3, faces)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    def count(kind):
        ex, n, items = TopExp_Explorer(shape, kind), 0, []
        while ex.More():
            n += 1
            items.append(ex.Current())
            ex.Next()
        return n, items

    n_solids, _ = count(TopAbs_SOLID)
    n_faces, _ = count(TopAbs_FACE)
    _, shells = count(TopAbs_SHELL)
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props, OCC_VOLUME_REL)
    return {"n_solids": n_solids, "valid": bool(BRepCheck_Analyzer(shape).IsValid()),
            "closed": bool(shells) and all(BRep_Tool.IsClosed_s(s) for s in shells),
            "volume_mm3": float(props.Mass()), "faces": n_faces}


@contextlib.contextmanager
def _quiet():
    """Silence OCCT's default messenger (the STEP writer prints transfer statistics)."""
    from OCP.Message import Message

    messenger = Message.DefaultMessenger_s()
    printers = messenger.Printers()
    saved = [printers.Value(i) for i in range(1, printers.Size() + 1)]
    for p in saved:
        messenger.RemovePrinter(p)
    try:
        yield
    finally:
        for p in saved:
            messenger.AddPrinter(p)


def write_step(path, cyl: surface.Cylinder, heights: np.ndarray, inner_vertices: np.ndarray,
               inner_faces: np.ndarray, mount_radius_mm: float, samples_u: int, samples_v: int,
               expected_volume_mm3: float | None = None) -> dict:
    """Write the lens as a STEP (AP214, mm) solid to ``path`` atomically; return figures.

    cyl: plain cylinder (mm); heights: (nu, nv) float mm node offsets; inner_vertices
    (n, 3) float mm, inner_faces (m, 3) int: the closed inner layer with outward winding;
    mount_radius_mm: the bore radius (the bore is planned as in ``solid.plan_bore``);
    samples_u x samples_v: the most interpolation samples the B-spline may have (its pole
    counts); it gets the fewest that keep it within ``tolerances.BSPLINE_DEVIATION_MM``.
    If ``expected_volume_mm3`` (e.g. the STL solid's) is given, the STEP solid's volume
    must match it within ``tolerances.VOLUME_REL``.

    Returns dict(valid, closed, n_solids, volume_mm3, faces, poles_u, poles_v,
    deviation_mm (radial, between samples), deviation {...}, file_bytes, fit_s (the fit
    and its deviation, every grid tried), build_s, check_s, write_s).  Raises GeometryError if the solid is invalid, open, or has a
    non-positive or unexpected volume.
    """
    solid, info = build_step_solid(cyl, inner_vertices, inner_faces, mount_radius_mm,
                                   fit_samples(cyl, heights, samples_u, samples_v))
    info.update(check_and_write(path, solid, "the lens solid", expected_volume_mm3))
    info["deviation_mm"] = info["deviation"]["radial_mm"]
    return info


def check_and_write(path, solid, what: str, expected_volume_mm3: float | None) -> dict:
    """Write ``solid`` as STEP once it is one valid closed solid of positive volume, within
    ``tolerances.VOLUME_REL`` of ``expected_volume_mm3`` when that is given.

    Returns ``shape_figures`` plus check_s, write_s and file_bytes.  Raises GeometryError
    naming ``what`` and the failing figures.
    """
    t0 = time.perf_counter()
    figs = shape_figures(solid)
    figs["check_s"] = time.perf_counter() - t0
    if not (figs["valid"] and figs["closed"] and figs["n_solids"] == 1 and figs["volume_mm3"] > 0):
        raise GeometryError(f"STEP: {what} fails its checks: {figs}")
    if expected_volume_mm3 is not None:
        rel = abs(figs["volume_mm3"] - expected_volume_mm3) / expected_volume_mm3
        if rel > VOLUME_REL:
            raise GeometryError(f"STEP: {what}'s volume {figs['volume_mm3']:.3f} mm^3 differs from the expected "
                                f"{expected_volume_mm3:.3f} by {rel:.2%} (limit {VOLUME_REL:.1%})")
    figs["write_s"] = write_shape(path, solid)
    figs["file_bytes"] = Path(path).stat().st_size
    return figs


def fit_samples(cyl: surface.Cylinder, heights: np.ndarray, max_u: int, max_v: int) -> dict:
    """The B-spline through the coarsest interpolation grid, from the heightmap's own nodes
    doubling up to (max_u, max_v), that stays within ``tolerances.BSPLINE_DEVIATION_MM`` of
    the heightmap surface between its samples: a CAM program handles fewer poles faster.

    Returns dict(samples (mu, mv), fit (``bspline_poles``), surface (OCCT), deviation
    (``deviation``), seconds).  Raises GeometryError if even the finest allowed grid does
    not stay within it."""
    from .tolerances import BSPLINE_DEVIATION_MM

    t0 = time.perf_counter()
    nu, nv = heights.shape
    mu, mv = nu, nv
    while True:
        mu_, mv_ = min(mu, max_u), min(mv, max_v)
        fit = bspline_poles(cyl, heights, mu_, mv_)
        occ = _occ_surface(fit)
        dev = deviation(cyl, heights, occ, mu_, mv_)
        if dev["radial_mm"] <= BSPLINE_DEVIATION_MM:
            return {"samples": (mu_, mv_), "fit": fit, "surface": occ, "deviation": dev,
                    "seconds": time.perf_counter() - t0}
        if (mu_, mv_) == (max_u, max_v) or (mu >= max_u and mv >= max_v):
            raise GeometryError(f"STEP: the B-spline through {mu_} x {mv_} samples deviates "
                                f"{dev['radial_mm'] * 1000:.2f} µm from the heightmap surface (limit "
                                f"{BSPLINE_DEVIATION_MM * 1000:g} µm); raise [export] step_samples_u / step_samples_v")
        mu, mv = 2 * mu, 2 * (mv - 1) + 1


def write_shape(path, solid) -> float:
    """Write an OCCT solid to ``path`` as STEP (AP214, mm) atomically; returns seconds.

    The header's time stamp is ``SOURCE_DATE_EPOCH`` where that is set (the
    reproducible-builds convention), so the same design can give the same bytes."""
    from OCP.APIHeaderSection import APIHeaderSection_MakeHeader
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.Interface import Interface_Static
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
    from OCP.TCollection import TCollection_HAsciiString

    t0 = time.perf_counter()
    writer = STEPControl_Writer()  # registers the write.step statics
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    with _quiet(), atomic_path(path, suffix=".step") as tmp:
        if writer.Transfer(solid, STEPControl_AsIs) != IFSelect_RetDone:
            raise GeometryError("STEP: transferring the solid to the writer failed")
        _name_product(writer.Model(), Path(path).stem)
        header = APIHeaderSection_MakeHeader(writer.Model())
        header.SetName(TCollection_HAsciiString(Path(path).name))
        if os.environ.get("SOURCE_DATE_EPOCH"):
            stamp = _source_date()
            header.SetTimeStamp(TCollection_HAsciiString(stamp.strftime("%Y-%m-%dT%H:%M:%S")))
        if writer.Write(str(tmp)) != IFSelect_RetDone:
            raise GeometryError(f"STEP: writing {path} failed")
    return time.perf_counter() - t0


def _name_product(model, name: str) -> None:
    """Name the STEP product ``name``: OCCT names it after itself plus a per-process
    counter, which would change the file from run to run and tell a CAM program nothing."""
    from OCP.StepBasic import StepBasic_Product
    from OCP.TCollection import TCollection_HAsciiString

    for i in range(1, model.NbEntities() + 1):
        entity = model.Value(i)
        if isinstance(entity, StepBasic_Product):
            entity.SetName(TCollection_HAsciiString(name))
            entity.SetId(TCollection_HAsciiString(name))


def _source_date() -> datetime.datetime:
    value = os.environ["SOURCE_DATE_EPOCH"]
    if not value.isdigit():
        raise LampfabError(f"SOURCE_DATE_EPOCH={value!r}: give whole seconds since 1970 (or unset it)")
    return datetime.datetime.fromtimestamp(int(value), datetime.timezone.utc)


def read_step(path) -> dict:
    """Import a STEP file and check it: dict(n_solids, valid, volume_mm3, closed, faces).

    Raises LampfabError if the file is missing or cannot be read.
    """
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    if not Path(path).is_file():
        raise LampfabError(f"{path}: not found")
    reader = STEPControl_Reader()
    with _quiet():
        if reader.ReadFile(str(path)) != IFSelect_RetDone:
            raise LampfabError(f"{path}: not a readable STEP file")
        reader.TransferRoots()
    return shape_figures(reader.OneShape())
