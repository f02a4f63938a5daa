"""The panel as a STEP solid: the relief as one B-spline face, five planar faces.

The relief's B-spline is the heightmap's own spline: a degree-3 surface through the
points (x_i, T + h_ij, z_j) at the nodes with not-a-knot end conditions in both
directions, which is exactly what ``surface.open_matrix`` samples (parameters: u = x,
v = z in mm; x and z being linear in them, the interpolant reproduces them exactly).
The sides and the back face are planar, each side bounded above by the relief's
boundary curve; the six faces are sewn into one closed shell.  Units: mm.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import GeometryError
from ..export.bspline import evaluate, interpolating_cubic, occ_surface
from ..export.step_file import check_and_write
from ..tolerances import OCC_COINCIDENT_MM, OCC_TOLERANCE_MM
from . import geometry as panel


def bspline(shape: panel.PanelShape, heights: np.ndarray):
    """(the relief as an OCCT ``Geom_BSplineSurface`` (mm) interpolating the nodes, its
    pole counts (x, z))."""
    nx, nz = heights.shape
    pts = panel.points(shape, heights)                                    # (nx, nz, 3)
    in_z, z_knots, z_mults = interpolating_cubic(shape.node_z(nz), pts.transpose(1, 0, 2))
    poles, x_knots, x_mults = interpolating_cubic(shape.node_x(nx), in_z.transpose(1, 0, 2))
    return occ_surface(poles, x_knots, x_mults, z_knots, z_mults, False), poles.shape


def deviation_mm(shape: panel.PanelShape, heights: np.ndarray, surface) -> float:
    """Largest distance between the B-spline and the heightmap's spline, at the nodes and
    half-way between them (mm)."""
    nx, nz = heights.shape
    mx, mz = 2 * nx - 1, 2 * nz - 1
    true = panel.points(shape, panel.sample(shape, heights, mx, mz))
    gap = evaluate(surface, shape.node_x(mx), shape.node_z(mz)) - true
    return max(float(np.linalg.norm(d)) for d in gap.reshape(-1, 3))


def build_solid(shape: panel.PanelShape, heights: np.ndarray):
    """(TopoDS_Solid, figures): the relief face, four sides and the back face, sewn."""
    from OCP.BRepBuilderAPI import (BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakePolygon,
                                    BRepBuilderAPI_MakeSolid, BRepBuilderAPI_MakeWire, BRepBuilderAPI_Sewing)
    from OCP.BRepLib import BRepLib
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    t0 = time.perf_counter()
    surface, poles = bspline(shape, heights)
    x0, x1 = -shape.width_mm / 2, shape.width_mm / 2
    z0, z1 = 0.0, shape.height_mm
    relief = BRepBuilderAPI_MakeFace(surface, x0, x1, z0, z1, OCC_TOLERANCE_MM)
    if not relief.IsDone():
        raise GeometryError(f"STEP: the relief's B-spline face failed ({relief.Error()})")
    faces = [relief.Face()]

    # Each side: the relief's boundary curve above, straight edges down to the back face.
    sides = ((surface.UIso(x0), x0, None), (surface.UIso(x1), x1, None),
             (surface.VIso(z0), None, z0), (surface.VIso(z1), None, z1))
    for curve, x, z in sides:
        top = BRepBuilderAPI_MakeEdge(curve).Edge()
        lo, hi = (z0, z1) if x is not None else (x0, x1)
        a = surface.Value(x, lo) if x is not None else surface.Value(lo, z)
        b = surface.Value(x, hi) if x is not None else surface.Value(hi, z)
        a0, b0 = gp_Pnt(a.X(), 0.0, a.Z()), gp_Pnt(b.X(), 0.0, b.Z())
        wire = BRepBuilderAPI_MakeWire(top, BRepBuilderAPI_MakeEdge(b, b0).Edge(),
                                       BRepBuilderAPI_MakeEdge(b0, a0).Edge(),
                                       BRepBuilderAPI_MakeEdge(a0, a).Edge())
        face = BRepBuilderAPI_MakeFace(wire.Wire(), True)
        if not face.IsDone():
            raise GeometryError(f"STEP: a side face of the panel failed ({face.Error()})")
        faces.append(face.Face())
    back = BRepBuilderAPI_MakePolygon(gp_Pnt(x0, 0, z0), gp_Pnt(x1, 0, z0), gp_Pnt(x1, 0, z1), gp_Pnt(x0, 0, z1),
                                      True)
    back_face = BRepBuilderAPI_MakeFace(back.Wire(), True)
    if not back_face.IsDone():
        raise GeometryError(f"STEP: the panel's back face failed ({back_face.Error()})")
    faces.append(back_face.Face())
    sewing = BRepBuilderAPI_Sewing(OCC_COINCIDENT_MM)
    for face in faces:
        sewing.Add(face)
    sewing.Perform()
    explorer = TopExp_Explorer(sewing.SewedShape(), TopAbs_SHELL)
    if not explorer.More():
        raise GeometryError("STEP: sewing the panel's faces gave no shell")
    made = BRepBuilderAPI_MakeSolid(TopoDS.Shell_s(explorer.Current()))
    if not made.IsDone():
        raise GeometryError("STEP: the panel's sewn shell did not make a solid")
    solid = made.Solid()
    BRepLib.OrientClosedSolid_s(solid)
    build_s = time.perf_counter() - t0
    return solid, {"build_s": build_s, "poles_u": int(poles[0]), "poles_v": int(poles[1]), "faces": len(faces),
                   "deviation_mm": deviation_mm(shape, heights, surface)}


def write_step(path, shape: panel.PanelShape, heights: np.ndarray, expected_volume_mm3: float) -> dict:
    """Write the panel as a STEP (AP214, mm) solid; figures as ``step_file.write_step``'s.

    Raises GeometryError if the solid is not one valid closed solid of the expected
    volume (within ``tolerances.VOLUME_REL``)."""
    solid, info = build_solid(shape, heights)
    info.update(check_and_write(path, solid, "the panel solid", expected_volume_mm3))
    return info
