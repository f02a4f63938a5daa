"""Stage 7, export: lens.stl, lens.step and lens.glb, each read back and checked,
design.json, and for a post with fins the fins' part, fins.stl."""

from __future__ import annotations

import numpy as np

from ... import artifacts
from ...errors import LampfabError
from ..build import Build
from ..progress import log


def export(build: Build) -> dict:
    """lens.stl and lens.step, both read back and checked, lens.glb, design.json and
    fins.stl (``_fins``)."""
    from ... import paint, solid
    from ...export import gltf, step_file, stl
    from ...tolerances import VOLUME_REL

    fab = build.fab
    report = build.begin("export", {"solid": build.solid_file, "heightmap": build.heightmap_file})
    stl_bytes = stl.write_stl(build.lens_stl, *build.solid_mesh())
    rv, rf = stl.read_stl(build.lens_stl)
    stl_volume = solid.mesh_volume(rv, rf)
    paint_info = build.kind.paint_json(build)
    glb_bytes = gltf.write_glb(build.lens_glb, rv, rf, fab.ior, paint.painted_from_json(rv, rf, paint_info))
    edges = solid.edge_check(rf)
    if not _one_closed_solid(edges):
        raise LampfabError(f"{build.lens_stl}: read back it is not one closed, consistently wound "
                           f"solid ({edges})")
    slicer = stl.admesh_check(build.lens_stl)         # None where admesh is not installed
    if slicer is not None and (slicer["repairs"] or slicer["parts"] != 1):
        raise LampfabError(f"{build.lens_stl}: admesh would repair it ({slicer}); a slicer would too")
    step_info = build.kind.write_step(build, stl_volume)
    back = step_file.read_step(build.lens_step)
    rel = abs(back["volume_mm3"] - stl_volume) / stl_volume
    if not (back["n_solids"] == 1 and back["valid"] and back["closed"] and rel <= VOLUME_REL):
        raise LampfabError(f"{build.lens_step}: read back it is not one valid closed solid matching the "
                           f"STL within {VOLUME_REL:.1%} ({back}, volume difference {rel:.3%})")
    artifacts.write_json(build.design_file, {
        "units": "mm",
        "light": build.kind.light_json(build),
        "material": {"name": fab.material, "ior": fab.ior},
        "lens": {"stl": build.lens_stl.name, "step": build.lens_step.name, "glb": build.lens_glb.name,
                 **paint_info},
        "walls": [w.to_json(build.target_file(w.name).relative_to(build.out).as_posix()) for w in build.walls],
    })
    report.figure(stl_bytes=stl_bytes, stl_volume_mm3=stl_volume, stl_triangles=int(len(rf)), glb_bytes=glb_bytes,
                  step_bytes=step_info["file_bytes"], step_volume_mm3=back["volume_mm3"],
                  step_stl_volume_rel=rel, step_faces=back["faces"],
                  bspline_deviation_mm=step_info["deviation_mm"],
                  bspline_poles=[step_info["poles_u"], step_info["poles_v"]], admesh=slicer)
    if build.source.fins:
        report.figure(fins_stl_bytes=_fins(build))
    else:  # a fins.stl left by an earlier build with another LED
        build.fins_stl.unlink(missing_ok=True)
    log(f"export: lens.stl {stl_bytes / 1e6:.1f} MB, lens.step {step_info['file_bytes'] / 1e6:.1f} MB, "
        f"B-spline deviation {step_info['deviation_mm'] * 1000:.3g} µm, volumes agree to {rel:.2e}")
    report.write(build.report_file("export"))
    return report.data


def _fins(build: Build) -> int:
    """Write a post's fins' part (``led_post.fin_part``) as fins.stl, read it back and
    check it is one closed solid that passes the bore; returns the file's size."""
    from ... import led_post, solid
    from ...export import stl

    source = build.source
    size = stl.write_stl(build.fins_stl, *led_post.fin_part(build.led, float(build.light[2]),
                                                            source.fin_azimuths_deg()))
    v, f = stl.read_stl(build.fins_stl)
    edges = solid.edge_check(f)
    reach = float(np.hypot(v[:, 0], v[:, 1]).max())
    if not _one_closed_solid(edges) or reach >= build.fab.mount_radius_mm:
        raise LampfabError(f"{build.fins_stl}: read back it is not one closed solid that passes the "
                           f"{2 * build.fab.mount_radius_mm:g} mm bore ({edges}, {2 * reach:.2f} mm across)")
    return size


def _one_closed_solid(edges: dict) -> bool:
    """Whether ``solid.edge_check``'s figures describe one closed, consistently wound solid."""
    return edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1
