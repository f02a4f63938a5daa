"""report.html: the page verify ends with, assembled from the stage reports, verify's
renders and the page's own pictures (``report`` writes the HTML)."""

from __future__ import annotations

from .. import artifacts, room
from .build import Build

_NEXT_STEPS_BLENDER = (
    "<p>For a beauty render, import <code>lens.glb</code> into Blender (File › Import › glTF): it arrives "
    "at its real size with a glass material of the same refractive index. <code>design.json</code> gives "
    "the light and the walls in the same frame.</p>")


def pictures(build: Build) -> dict:
    """The report's own pictures: the glass lamp in its room, the bumpy lens, the
    unrolled heightmap.  Returns their paths by name (room, lens, heightmap)."""
    from .. import beauty
    from ..export import stl

    v = build.design.verify
    design = artifacts.read_json(build.design_file)
    vertices, faces = stl.read_stl(build.lens_stl)
    walls = [room.Wall.from_json(w) for w in design["walls"]]
    flux = [artifacts.read_npz(build.verify_pictures(w.name)[2])["led"] for w in walls]
    paths = {name: build.report_picture(name) for name in ("room", "lens", "heightmap")}
    light_mm, light_radius_mm = build.kind.report_light(build, design)
    artifacts.write_png(paths["room"], beauty.room_scene(
        vertices, faces, build.fab.ior, light_mm, light_radius_mm, walls, flux, v.scene_px, v.scene_spp,
        build.design.optimize.seed), normalize=False)
    artifacts.write_png(paths["lens"], beauty.bumpy_lens(vertices, faces, v.scene_px, 4), normalize=False)
    build.kind.heightmap_picture(build, [w.name for w in walls], paths["heightmap"])
    return paths


def write(build: Build, figures: dict, pics: dict) -> None:
    """report.html from verify's ``figures`` and the report's ``pics`` (``pictures``)."""
    from .. import report
    from ..checks import CheckResult
    from ..checks.result import short

    walls = []
    for name, f in figures["walls"].items():
        render_png, blur_png, _ = build.verify_pictures(name)
        walls.append({"name": name, "target_png": build.target_preview(name), "render_png": render_png,
                      "blur_png": blur_png, "pearson": f["pearson"], "ssim": f["ssim"], "share": f["share"],
                      "ghost_share": f["ghost_share"], "direct_ssim": f["direct_ssim"],
                      "blur_pearson": f["led_pearson"], "blur_ssim": f["led_ssim"], "blur_share": f["led_share"],
                      **({"r_vs_optimizer": f["optimizer_pearson"]} if "optimizer_pearson" in f else {})})
    stage_figures = {}
    for stage in ("init", "optimize", "solid", "export"):
        data = build.stage_report(stage)
        if data is not None:
            flat = {k: v for k, v in data["figures"].items() if not isinstance(v, (dict, list))}
            flat["wall_time_s"] = data.get("wall_time_s")
            stage_figures[stage] = flat
    fig = report.figure_html
    first, sections = build.kind.lens_sections(build, pics, fig)
    if build.gif_file.exists():
        sections.append(("Optimization", fig("The walls during optimization", build.gif_file,
                                             "one frame per preview step (loss per step: loss.csv)")))
    checks = build.checks_report()
    if checks is not None:
        results = [CheckResult.from_json(c) for c in checks["figures"]["checks"]]
        rows = "".join(
            f"<tr><td>{r.name}</td><td class=\"{'ok' if r.passed else 'fail'}\">"
            f"{'pass' if r.passed else 'FAIL'}</td><td>{short(r.value)} {r.unit}</td>"
            f"<td>{short(r.limit)}</td></tr>" for r in results if r.applies)
        picture = fig("Checks on the unrolled lens", build.checks_picture, "red: where a check fails") \
            if build.checks_picture.exists() else ""
        sections.append((f"Fabrication checks ({build.fab.name})",
                         f"<table><tr><th>check</th><th>result</th><th>value</th><th>limit</th></tr>{rows}</table>"
                         f"{picture}"))
    if "guidance" in figures:
        from .. import guidance

        sections.append(("Finishing and tolerances", guidance.html(figures["guidance"], figures["tolerance"])))
    sections.append(("Next steps", build.kind.next_steps(build) + _NEXT_STEPS_BLENDER))
    report.write_report(build.report_html, f"lampfab: {build.out.name}", walls, stage_figures, sections, first)
