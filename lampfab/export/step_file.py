"""STEP files (AP214, mm): the lamp written as one, any OCCT solid checked and written,
a file read back and measured.

``write_step`` fits the lamp's outer B-spline (``bspline``), assembles the solid around
it (``brep``) and writes it; the panel's STEP (``panel.brep``) goes through the
same ``check_and_write``.  The file's time stamp follows ``SOURCE_DATE_EPOCH`` where that
is set, so the same design can give the same bytes.
"""

from __future__ import annotations

import contextlib
import datetime
import os
import time
from pathlib import Path

import numpy as np

from .. import surface
from ..artifacts import atomic_path
from ..errors import GeometryError, LampfabError
from ..tolerances import OCC_VOLUME_REL, VOLUME_REL
from .brep import build_step_solid
from .bspline import fit_samples


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
               expected_volume_mm3: float | None = None, slots=None) -> dict:
    """Write the lens as a STEP (AP214, mm) solid to ``path`` atomically; return figures.

    cyl: plain cylinder (mm); heights: (nu, nv) float mm node offsets; inner_vertices
    (n, 3) float mm, inner_faces (m, 3) int: the closed inner layer with outward winding;
    mount_radius_mm: the bore radius (the bore is planned as in ``solid.plan_bore``);
    samples_u x samples_v: the most interpolation samples the B-spline may have (its pole
    counts); it gets the fewest that keep it within ``tolerances.BSPLINE_DEVIATION_MM``.
    If ``expected_volume_mm3`` (e.g. the STL solid's) is given, the STEP solid's volume
    must match it within ``tolerances.VOLUME_REL``.  ``slots`` (``slots.Slots``, or None)
    are pockets in its base.

    Returns dict(valid, closed, n_solids, volume_mm3, faces, poles_u, poles_v,
    deviation_mm (radial, between samples), deviation {...}, file_bytes, fit_s (the fit
    and its deviation, every grid tried), build_s, check_s, write_s).  Raises GeometryError if the solid is invalid, open, or has a
    non-positive or unexpected volume.
    """
    solid, info = build_step_solid(cyl, inner_vertices, inner_faces, mount_radius_mm,
                                   fit_samples(cyl, heights, samples_u, samples_v), slots)
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
