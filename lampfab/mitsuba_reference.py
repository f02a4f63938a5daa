"""A second opinion from a renderer lampfab did not write: Mitsuba's light tracer.

verify traces the exported lens with lampfab's own photon tracer (``trace``).  Here
Mitsuba's ``ptracer`` renders the same ``design.json`` instead: the lens read back from
its STL as a ``dielectric`` of the design's refractive index with flat facet normals
(what is made), the LED as an emitter of its real shape and size (a sphere, a
filament's cylinder, a flat disc facing up; or its point light), one diffuse wall at a
time.  Mitsuba handles Fresnel at every surface, total internal reflection and every
bounce in its own code, so agreement says the walls verify shows are the walls the lamp
will light, not an artefact of one tracer.

Each wall is seen by a perspective camera on the wall's axis, facing it squarely from
the lamp's side, just clear of the lens (``ptracer`` connects light paths to a
perspective sensor, never to an orthographic one).  Its film is the wall's picture:
for a camera facing a plane squarely, the plane maps onto the film by a uniform scale,
so film pixel (i, j) is wall pixel (i, j), with a box filter as verify bins photons.  A
diffuse wall's radiance is proportional to its irradiance, so the film holds the flux
per pixel up to one factor, which the comparison (Pearson r) ignores.  One wall per
scene: light the other walls would scatter onto it is no part of verify's picture.
"""

from __future__ import annotations

import numpy as np

from .room import Wall
from .source import FLAT, Source

# The camera stands this far on the lamp's side of the lens's nearest point: the lens
# must lie wholly behind it, out of its view.
CAMERA_CLEARANCE_MM = 10.0

# Interactions followed per light path: verify follows 8 interface crossings; a path
# then needs one more vertex on the wall and room to spare for internal reflections.
MAX_DEPTH = 12

# A flat LED's point light, as a disc this small: its blur on a wall 1 m away (about
# 0.01 mm x 1000 / 45) is a thousandth of a 28 mm pixel.
POINT_DISC_RADIUS_MM = 0.01


def _lens(mi, vertices: np.ndarray, faces: np.ndarray, ior: float, painted: np.ndarray | None = None) -> dict:
    """The lens as Mitsuba meshes of flat facets (no vertex normals), by scene key: its
    glass, and its ``painted`` facets ((m,) bool) as a black diffuse mesh, which ends
    the light that meets it from either side."""
    painted = np.zeros(len(faces), bool) if painted is None else painted
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    out = {"lens": _mesh(mi, "lens", vertices, faces[~painted],
                         {"type": "dielectric", "int_ior": float(ior), "ext_ior": 1.0})}
    if painted.any():
        out["lens_paint"] = _mesh(mi, "lens_paint", vertices, faces[painted], black)
    return out


def _mesh(mi, name: str, vertices: np.ndarray, faces: np.ndarray, bsdf: dict):
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf)
    mesh = mi.Mesh(name, len(vertices), len(faces), props=props, has_vertex_normals=False,
                   has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.ascontiguousarray(vertices, np.float32).ravel())
    params["faces"] = mi.UInt(np.ascontiguousarray(faces, np.uint32).ravel())
    params.update()
    return mesh


def lights(mi, source: Source, radiance: float = 1.0) -> dict:
    """The LED ``source`` as Mitsuba emitters, by scene key: a point light (a ball's or a
    filament's point), a glowing sphere, a glowing cylinder on the lamp axis (a filament;
    open ends, as ``trace.emit``'s), or glowing discs (a disc facing up, a post's facing
    out: Mitsuba's area lights shine from the front only, as a Lambertian disc does; a
    point is a disc of ``POINT_DISC_RADIUS_MM``: Mitsuba has no point light with a cosine
    beam), with a post's fins.  Their surfaces are black: light coming back to them is
    absorbed."""
    centre = source.position
    body = {"bsdf": {"type": "diffuse", "reflectance": 0.0},
            "emitter": {"type": "area", "radiance": {"type": "spectrum", "value": radiance}}}
    if source.shape in FLAT:
        r = max(source.radius_mm, POINT_DISC_RADIUS_MM)
        out = {}
        for k, n in enumerate(source.normals):
            across = _across(n)
            out[f"light_{k}"] = {"type": "disk", "to_world": placed(mi, centre + source.offset_mm * n, r * across,
                                                                      r * np.cross(n, across)), **body}
        return out | _fins(mi, source) if source.fins else out
    return {"light": _light(mi, source, centre, body, radiance)}


def _fins(mi, source: Source) -> dict:
    """A post's fins as black rectangles, by scene key: vertical, from the axis out to
    ``fin_radius_mm``, ``fin_height_mm`` tall about the LEDs."""
    out = {}
    for k, a in enumerate(np.radians(source.fin_azimuths_deg())):
        half = np.array([np.cos(a), np.sin(a), 0.0]) * source.fin_radius_mm / 2
        out[f"fin_{k}"] = {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": 0.0},
                           "to_world": placed(mi, source.position + half, half, [0.0, 0.0, source.fin_height_mm / 2])}
    return out


def placed(mi, centre, half_x, half_y):
    """The to_world of Mitsuba's unit rectangle ([-1, 1]^2) or disk, normal +z, onto the
    flat shape at ``centre`` (3,) mm spanning ``half_x`` and ``half_y`` (3,) mm (its half
    width and half height, or its radii) from it, facing half_x x half_y."""
    m = np.eye(4)
    normal = np.cross(half_x, half_y)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = half_x, half_y, normal / np.linalg.norm(normal), centre
    return mi.ScalarTransform4f(m)


def _across(normal: np.ndarray) -> np.ndarray:
    """(3,) a unit vector square to ``normal`` (3,), for look_at's up."""
    other = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return np.cross(normal, other) / np.linalg.norm(np.cross(normal, other))


def _light(mi, source: Source, centre: np.ndarray, body: dict, radiance: float) -> dict:
    """``lights``' one emitter of a ball or a filament (or their point)."""
    if source.radius_mm <= 0:
        return {"type": "point", "position": centre.tolist(), "intensity": {"type": "spectrum", "value": radiance}}
    if source.shape == "cylinder":
        half = np.array([0.0, 0.0, source.length_mm / 2])
        return {"type": "cylinder", "p0": (centre - half).tolist(), "p1": (centre + half).tolist(),
                "radius": float(source.radius_mm), **body}
    return {"type": "sphere", "center": centre.tolist(), "radius": float(source.radius_mm), **body}


def wall_camera(mi, wall: Wall, vertices: np.ndarray, shape: tuple[int, int], spp: int) -> dict:
    """A perspective sensor facing ``wall`` squarely from the lamp's side, just clear
    of the lens (``vertices`` (n, 3) mm), whose (rows, cols) film is the wall's picture."""
    rows, cols = shape
    nearest = float(((vertices - wall.origin) @ wall.normal).min())
    distance = nearest - CAMERA_CLEARANCE_MM
    if distance <= 0:
        raise ValueError(f"the {wall.name} wall is no farther than the lens: no camera fits between them")
    eye = wall.centre + wall.normal * distance
    up = -wall.down / wall.height_mm
    return {"type": "perspective", "fov_axis": "x",
            "fov": float(np.degrees(2 * np.arctan(wall.width_mm / 2 / distance))),
            "to_world": mi.ScalarTransform4f().look_at(eye.tolist(), wall.centre.tolist(), up.tolist()),
            "film": {"type": "hdrfilm", "width": cols, "height": rows, "pixel_format": "luminance",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp}}


def render(vertices: np.ndarray, faces: np.ndarray, ior: float, source: Source, walls: list[Wall],
           shapes: list[tuple[int, int]], photons: int, seed: int, painted: np.ndarray | None = None
           ) -> list[np.ndarray]:
    """Mitsuba's ptracer picture of each wall: (rows, cols) float64 per wall, proportional
    to its flux per pixel.  ``vertices`` (n, 3) mm and ``faces`` (m, 3): the closed lens
    with outward normals, its ``painted`` facets ((m,) bool) black; the LED as
    ``lights``'; about ``photons`` light paths per wall."""
    from .mi_env import mitsuba

    mi = mitsuba()
    lens = _lens(mi, vertices, faces, ior, painted)
    images = []
    for k, (wall, shape) in enumerate(zip(walls, shapes)):
        spp = max(1, int(round(photons / (shape[0] * shape[1]))))
        scene = mi.load_dict({
            "type": "scene", "integrator": {"type": "ptracer", "max_depth": MAX_DEPTH, "hide_emitters": True},
            **lens, **lights(mi, source),
            "wall": {"type": "rectangle", "to_world": _rectangle(mi, wall),
                     "bsdf": {"type": "diffuse", "reflectance": 1.0}},
            "camera": wall_camera(mi, wall, vertices, shape, spp)})
        images.append(np.asarray(mi.render(scene, spp=spp, seed=seed + k), np.float64)[..., 0])
    return images


def _rectangle(mi, wall: Wall):
    """Mitsuba's rectangle onto the wall's picture, facing the lamp."""
    return placed(mi, wall.centre, wall.right / 2, -wall.down / 2)
