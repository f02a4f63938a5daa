"""``lens.glb``: the lens for a beauty render in Blender (or any glTF viewer).

A binary glTF 2.0 file with one mesh and a glass material: clear base colour, no
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


def write_glb(path, vertices_mm: np.ndarray, faces: np.ndarray, ior: float, name: str = "lens") -> int:
    """Write the mesh ((n, 3) float64 mm, (m, 3) int) as ``path``; returns its size in bytes."""
    positions = to_gltf_frame(vertices_mm)
    indices = np.ascontiguousarray(faces, dtype=np.uint32).ravel()
    pos_bytes, idx_bytes = positions.tobytes(), indices.tobytes()
    pad = (-len(pos_bytes)) % 4
    binary = pos_bytes + b"\0" * pad + idx_bytes
    binary += b"\0" * ((-len(binary)) % 4)
    size = float(np.linalg.norm(positions.max(0) - positions.min(0)))
    doc = {
        "asset": {"version": "2.0", "generator": "lampfab"},
        "extensionsUsed": _EXTENSIONS,
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{
            "name": "lampfab glass",
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0,
                                     "roughnessFactor": 0.0},
            "doubleSided": False,
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                           "KHR_materials_ior": {"ior": float(ior)},
                           "KHR_materials_volume": {"thicknessFactor": size}}}],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(pos_bytes), "target": _ARRAY_BUFFER},
            {"buffer": 0, "byteOffset": len(pos_bytes) + pad, "byteLength": len(idx_bytes),
             "target": _ELEMENT_ARRAY_BUFFER}],
        "accessors": [
            {"bufferView": 0, "componentType": _FLOAT, "count": len(positions), "type": "VEC3",
             "min": positions.min(0).tolist(), "max": positions.max(0).tolist()},
            {"bufferView": 1, "componentType": _UINT, "count": len(indices), "type": "SCALAR",
             "min": [int(indices.min())], "max": [int(indices.max())]}],
    }
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * ((-len(text)) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    write_bytes(path, struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON") + text
                + struct.pack("<I4s", len(binary), b"BIN\0") + binary)
    return total
