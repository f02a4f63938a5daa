"""``lens.glb``: the lens for a beauty render in Blender (or any glTF viewer).

A binary glTF 2.0 file with one mesh: its glass, and the faces to be painted black
(``paint``) as a second primitive of matt black.  The glass is a clear base colour, no
metal, no roughness, full transmission (KHR_materials_transmission), the design's
refractive index (KHR_materials_ior) and a thick volume (KHR_materials_volume), which
Blender's importer turns into a Principled BSDF glass.  glTF is in metres with Y up:
the STL's millimetres with Z up are scaled by 1/1000 and turned (x, y, z) -> (x, z, -y);
Blender's importer turns it back, so the lens stands upright at its real size.  No
normals are stored, so viewers shade the true flat facets, as verify traced them.
"""

from __future__ import annotations

import json
import struct

import numpy as np

from ..artifacts import write_bytes

_FLOAT, _UINT = 5126, 5125            # glTF component types
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_EXTENSIONS = ["KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_volume"]


def to_gltf_frame(vertices_mm: np.ndarray) -> np.ndarray:
    """(n, 3) mm, Z up -> (n, 3) float32 m, Y up."""
    v = np.asarray(vertices_mm, np.float64) / 1000.0
    return np.stack([v[:, 0], v[:, 2], -v[:, 1]], axis=1).astype(np.float32)


def write_glb(path, vertices_mm: np.ndarray, faces: np.ndarray, ior: float, painted: np.ndarray | None = None,
              name: str = "lens") -> int:
    """Write the mesh ((n, 3) float64 mm, (m, 3) int) as ``path``, its ``painted`` facets
    ((m,) bool, ``paint``) as a second primitive of matt black; returns the size in bytes."""
    positions = to_gltf_frame(vertices_mm)
    painted = np.zeros(len(faces), bool) if painted is None else painted
    parts = [faces[~painted]] + ([faces[painted]] if painted.any() else [])
    pos_bytes = positions.tobytes()
    binary = pos_bytes + b"\0" * ((-len(pos_bytes)) % 4)
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos_bytes), "target": _ARRAY_BUFFER}]
    accessors = [{"bufferView": 0, "componentType": _FLOAT, "count": len(positions), "type": "VEC3",
                  "min": positions.min(0).tolist(), "max": positions.max(0).tolist()}]
    for part in parts:
        indices = np.ascontiguousarray(part, dtype=np.uint32).ravel()
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": indices.nbytes,
                      "target": _ELEMENT_ARRAY_BUFFER})
        accessors.append({"bufferView": len(views) - 1, "componentType": _UINT, "count": len(indices),
                          "type": "SCALAR", "min": [int(indices.min())], "max": [int(indices.max())]})
        binary += indices.tobytes()
    size = float(np.linalg.norm(positions.max(0) - positions.min(0)))
    glass = {"name": "lampfab glass",
             "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                      "roughnessFactor": 0.0},
             "doubleSided": False,
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                            "KHR_materials_ior": {"ior": float(ior)},
                            "KHR_materials_volume": {"thicknessFactor": size}}}
    black = {"name": "lampfab matt black paint",
             "pbrMetallicRoughness": {"baseColorFactor": [0.02, 0.02, 0.02, 1.0], "metallicFactor": 0.0,
                                      "roughnessFactor": 0.9}}
    primitives = [{"attributes": {"POSITION": 0}, "indices": k + 1, "material": k} for k in range(len(parts))]
    doc = {
        "asset": {"version": "2.0", "generator": "lampfab"},
        "extensionsUsed": _EXTENSIONS,
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": primitives}],
        "materials": [glass, black][:len(parts)],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": views,
        "accessors": accessors,
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * ((-len(text)) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    write_bytes(path, struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON") + text
                + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
    return total
