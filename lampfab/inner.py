"""The inner layer: a fixed closed mesh around the LED, imported from a file.

Blender exports arrive as triangle soups split along UV and normal seams; they are
welded (``tolerances.WELD_MM``), repaired where that is safe (duplicate and degenerate
faces, winding) and refused with a reason where it is not (holes, faces crossing each
other (pymeshlab), not enclosing the light, crossing the outer layer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import tolerances
from .checks.mesh import inspect_mesh
from .errors import LampfabError
from .profile import DEFAULT_HOLLOW_RADIUS_MM

DEFAULT_INNER = Path(__file__).resolve().parent / "data" / "inner_default.obj"
FORMATS = (".obj", ".ply", ".stl", ".glb", ".off")


def default_inner_mesh(radius_mm: float = DEFAULT_HOLLOW_RADIUS_MM, z0_mm: float = 10.0, z1_mm: float = 86.0,
                       sections: int = 1024):
    """The bundled inner layer: a cylinder with a 45° conical roof, 1024 facets around (mm).

    Slim and tall (r 16 mm by default, side wall up to 25 mm above the LED): light
    through the side wall covers 57° above the LED's level to 65° below, and light
    through the roof leaves by the top cap.  Wide enough for the default post's fins to
    reach 14.5 mm, which keeps most of the next wall's LED off a sector's edge (a 12 mm
    hollow, with fins 10.5 mm out, left words 0.02-0.04 of SSIM softer: bench/log).  A
    wide, low cavity would make the roof bend light onto the same part of the outer
    surface as the side wall, from another direction: no surface can send both to one
    place.

    1024 facets: at 256 their edges throw visible stripes on the walls (the source's
    "dark bands"); at 1024 the gaps are ~3 mm at 1 m, below a wall pixel.  The conical
    roof is self-supporting when printed upright (a flat one would be a 36 mm
    overhang inside the part, where supports cannot be removed).  The flat floor is
    where the LED bore enters.
    """
    import trimesh

    profile = [[0.0, z0_mm], [radius_mm, z0_mm], [radius_mm, z1_mm - radius_mm], [0.0, z1_mm]]
    return trimesh.creation.revolve(profile, sections=sections)


def inner_file(path: str | Path | None, hollow_radius_mm: float = DEFAULT_HOLLOW_RADIUS_MM) -> Path | None:
    """The file ``load_inner`` reads for ``path`` (None: the bundled layer): the bundled
    one at its own hollow (the recipe written out, so a maker can open the layer the
    designs use), or None where it makes the bundled layer with another hollow."""
    if path:
        return Path(path)
    return DEFAULT_INNER if hollow_radius_mm == DEFAULT_HOLLOW_RADIUS_MM else None


def load_inner(path: str | Path | None, scale: float, light_mm: np.ndarray,
               outer_radius_mm: float, max_offset_mm: float, height_mm: float,
               hollow_radius_mm: float = DEFAULT_HOLLOW_RADIUS_MM):
    """Read, weld, repair and validate the inner layer: the file at ``path``, or with
    none the bundled one, ``default_inner_mesh`` with a hollow of ``hollow_radius_mm``.

    Returns (vertices (n, 3) float64 mm, faces (m, 3) int64), outward winding
    (normals point away from the light, into the glass).
    """
    import trimesh

    path = inner_file(path, hollow_radius_mm)
    if path:
        where = f"inner layer {path}"
        loaded = _read_mesh(path, where)
        vertices = np.asarray(loaded.vertices, np.float64)
        if path.suffix.lower() == ".glb":  # glTF is metres with Y up, by its specification
            vertices = 1000.0 * np.stack([vertices[:, 0], -vertices[:, 2], vertices[:, 1]], axis=1)
    else:
        where = f"the bundled inner layer (hollow_radius_mm {hollow_radius_mm:g})"
        loaded = default_inner_mesh(radius_mm=hollow_radius_mm)
        vertices = np.asarray(loaded.vertices, np.float64)
    mesh = trimesh.Trimesh(vertices * scale, loaded.faces, process=False)
    mesh.merge_vertices(digits_vertex=int(-np.log10(tolerances.WELD_MM)))
    mesh.update_faces(mesh.unique_faces())
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    if not mesh.is_watertight:
        raise LampfabError(f"{where}: not closed ({_open_edges(mesh)} open edges after welding "
                           f"at {tolerances.WELD_MM} mm); close the holes in Blender")
    if mesh.body_count != 1:
        raise LampfabError(f"{where}: has {mesh.body_count} separate parts; expected one closed shell")
    crossing = inspect_mesh(mesh.vertices, mesh.faces)
    if crossing.self_intersecting_faces:
        place = np.round(crossing.places["self_intersecting_faces"], 2).tolist()
        raise LampfabError(f"{where}: {crossing.self_intersecting_faces} faces cross other faces (near {place} mm); "
                           f"a lens cannot be made around a surface that passes through itself: fix it in Blender "
                           f"(Select > Select All by Trait > Interior Faces, or Mesh > Clean Up)")
    trimesh.repair.fix_normals(mesh)
    if mesh.volume < 0:
        mesh.invert()
    if abs(winding_number(mesh.vertices, mesh.faces, light_mm) - 1.0) > 0.5:
        raise LampfabError(f"{where}: does not enclose the light at {np.round(light_mm, 2).tolist()} mm (the "
                           f"LED must sit inside the cavity); move [lens] light_height_mm or the mesh")
    r = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])
    limit = outer_radius_mm - max_offset_mm - tolerances.MIN_GAP_MM
    if r.max() > limit:
        worst = mesh.vertices[np.argmax(r)]
        raise LampfabError(f"{where}: reaches radius {r.max():.2f} mm at {np.round(worst, 2).tolist()}; "
                           f"the outer layer may come in to {limit:.2f} mm (outer_radius_mm - max_offset_mm - gap)")
    z = mesh.vertices[:, 2]
    if z.min() <= 0.0 or z.max() >= height_mm:
        raise LampfabError(f"{where}: spans z {z.min():.2f} to {z.max():.2f} mm; it must stay inside the "
                           f"lens (0 to {height_mm} mm) so the caps close it")
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


def _read_mesh(path: Path, where: str):
    """The triangles of the file at ``path`` as one trimesh, or a one-line error."""
    import trimesh

    if path.suffix.lower() not in FORMATS:
        raise LampfabError(f"{where}: unsupported format; use one of {', '.join(FORMATS)}")
    if not path.is_file():
        raise LampfabError(f"{where}: file not found")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except FileNotFoundError:
        raise LampfabError(f"{where}: file not found") from None
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types on bad files
        raise LampfabError(f"{where}: cannot read it ({type(exc).__name__}: {exc})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise LampfabError(f"{where}: holds no triangles")
    return loaded


def check_led_inside(vertices: np.ndarray, faces: np.ndarray, source, where: str) -> None:
    """Refuse an LED whose glowing part pokes out of the cavity: a filament's ends, a
    ball's poles and sides, a disc's rim, a post's faces' rims and its fins' corners
    (``source``: a ``source.Source``; ``vertices`` (n, 3) mm and ``faces`` as
    ``load_inner`` returns them)."""
    r = source.radius_mm
    up = {"cylinder": source.length_mm / 2, "sphere": r, "post": r}.get(source.shape, 0.0)
    rims = np.array([[0, 0, up], [0, 0, -up], [r, 0, 0], [-r, 0, 0], [0, r, 0], [0, -r, 0]])
    centres = source.face_centres
    part = {"sphere": "ball", "cylinder": f"{source.length_mm:g} mm filament"}.get(source.shape, "face")
    parts = [(f"glowing {part} ({r:g} mm radius) reaches", c + rim) for c in centres for rim in rims]
    if source.fins:
        fins = f"fins ({source.fin_radius_mm:g} mm out, {source.fin_height_mm:g} mm tall) reach"
        for a in np.radians(source.fin_azimuths_deg()):
            tip = source.position + source.fin_radius_mm * np.array([np.cos(a), np.sin(a), 0.0])
            parts += [(fins, tip + [0.0, 0.0, dz * source.fin_height_mm]) for dz in (-0.5, 0.5)]
    for what, point in parts:
        if abs(winding_number(vertices, faces, point) - 1.0) > 0.5:
            raise LampfabError(f"{where}: the LED's {what} {np.round(point, 2).tolist()} mm, outside the cavity; "
                               f"move [lens] light_height_mm or choose a smaller LED")


def winding_number(vertices: np.ndarray, faces: np.ndarray, point: np.ndarray) -> float:
    """Generalized winding number of a closed mesh around ``point`` (1 inside, 0 outside).

    Van Oosterom & Strackee's solid angle per triangle; exact for closed meshes and
    needs no spatial index.
    """
    a, b, c = (vertices[faces[:, k]] - point for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2 * np.arctan2(det, den)) / (4 * np.pi))


def _open_edges(mesh) -> int:
    import trimesh

    groups = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    return len(groups)
