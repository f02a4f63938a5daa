"""Binary STL out and back in (mm, the lamp frame: Z up, base on z = 0).

STL stores every triangle with its own three float32 corners: a triangle soup.
``read_stl`` welds corners whose float32 coordinates are identical, which restores
the closed mesh that was written (a shared vertex is written with the same bits every
time) without merging distinct vertices that merely lie close together.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..artifacts import write_bytes
from ..errors import LampfabError


def write_stl(path, vertices: np.ndarray, faces: np.ndarray) -> int:
    """Write (n, 3) float mm vertices and (m, 3) int faces as a binary STL, atomically.

    Returns the file size in bytes.
    """
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, np.float64), np.asarray(faces, np.int64), process=False)
    data = mesh.export(file_type="stl")
    write_bytes(path, data)
    return len(data)


def read_stl(path) -> tuple[np.ndarray, np.ndarray]:
    """Read an STL and weld it: ((n, 3) float64 mm vertices, (m, 3) int64 faces).

    Corners with bit-identical float32 coordinates become one vertex; triangles that
    collapse (two equal corners) are dropped.  Raises LampfabError if the file is
    missing, unreadable or holds no triangles.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise LampfabError(f"{path}: not found")
    try:
        loaded = trimesh.load(path, file_type="stl", force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types on bad files
        raise LampfabError(f"{path}: cannot read it as STL ({type(exc).__name__}: {exc})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise LampfabError(f"{path}: holds no triangles")
    corners = np.ascontiguousarray(np.asarray(loaded.vertices, np.float32)[np.asarray(loaded.faces)].reshape(-1, 3))
    # Exact weld on the float32 bit patterns (-0.0 folded onto 0.0); a lexsort is ~10x
    # faster than np.unique(axis=0) on a million corners.
    bits = (corners + np.float32(0.0)).view(np.uint32)
    order = np.lexsort((bits[:, 2], bits[:, 1], bits[:, 0]))
    ordered = bits[order]
    first = np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]
    ids = np.empty(len(order), np.int64)
    ids[order] = np.cumsum(first) - 1
    unique = corners[order[first]]
    faces = ids.reshape(-1, 3)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])
    return unique.astype(np.float64), faces[keep]


# ADMesh's repair counters (its labels): any non-zero one is a repair a slicer would make.
ADMESH_REPAIRS = ("Degenerate facets", "Edges fixed", "Facets removed", "Facets added", "Facets reversed",
                  "Backwards edges", "Normals fixed")


def admesh_check(path) -> dict | None:
    """Ask ADMesh (``admesh``; PrusaSlicer's and Slic3r's STL repair is a fork of it) what it
    would repair in an STL: {"degenerate_facets": int, ... one per ADMESH_REPAIRS label,
    "disconnected_facets": int, "parts": int, "repairs": their sum (0: a slicer takes the
    file as it is)}.  None if ``admesh`` is not installed.  It only reads the file."""
    import re
    import shutil
    import subprocess

    exe = shutil.which("admesh")
    if exe is None:
        return None
    run = subprocess.run([exe, str(path)], capture_output=True, text=True, timeout=600)
    out = {}
    for label in ADMESH_REPAIRS + ("Number of parts", "Total disconnected facets"):
        m = re.search(rf"^{label}\s*:\s*(\d+)", run.stdout, re.M)
        if run.returncode != 0 or m is None:
            raise LampfabError(f"{path}: admesh failed or printed no {label!r} (exit {run.returncode}): "
                               f"{(run.stderr or run.stdout)[-300:]}")
        out[label.lower().replace(" ", "_")] = int(m.group(1))
    out["parts"] = out.pop("number_of_parts")
    out["disconnected_facets"] = out.pop("total_disconnected_facets")
    out["repairs"] = sum(v for k, v in out.items() if k != "parts")
    return out
