"""Stage 8, verify: the exported STL traced with its true facets, compared with the
targets (verify.json, verify/), and report.html."""

from __future__ import annotations

from ..build import Build
from ..progress import PartsBar, log


def verify(build: Build) -> dict:
    """Render the exported STL (true facets) from design.json; compare; write report.html."""
    from ... import verify as verify_mod
    from ...tolerances import OPTIMIZER_MATCH_R
    from .. import report_page

    v = build.design.verify
    report = build.begin("verify", {"design": build.design_file, "stl": build.lens_stl})
    # Its parts take a minute together with nothing to print between them: a bar by part.
    texts = _ocr_texts(build)
    bar = PartsBar("verify", ["tracing the exported lens", "tolerance study", "the lamp's renders", "report.html"])
    bar.begin("tracing the exported lens")
    # The design and its STL (26 MB at the default grid) read and made a scene once, for
    # the figures and the report's pictures.
    loaded = verify_mod.load(build.design_file)
    figures = verify_mod.verify(loaded, build.verify_dir, v.image_px, v.photons,
                                build.design.optimize.seed + 7, v.max_bounces, v.mitsuba_photons, texts,
                                v.led_photons)
    read = {n: f for n, f in figures["walls"].items() if "words" in f}
    if read:
        def counts(key):
            return ", ".join(f"{n} {f[key]}/{f['words']}" for n, f in read.items())
        log(f"verify: words read back by OCR (Tesseract) with the {figures['real_light']}: {counts('led_words_read')}"
            f"; with a point light: {counts('point_words_read')}; the sharp target: {counts('target_words_read')}")
    bar.begin("tolerance study")
    if build.optimizer_render_file.exists():
        agree = verify_mod.optimizer_agreement(build.verify_dir, build.optimizer_render_file, list(figures["walls"]))
        for name, a in agree.items():
            figures["walls"][name].update(optimizer_pearson=a["r"], optimizer_raw_pearson=a["raw_r"],
                                          optimizer_render_reliability=a["reliability"])
        figures["optimizer_match_min"] = min(a["r"] for a in agree.values())
        figures["optimizer_match_limit"] = OPTIMIZER_MATCH_R
    for name, f in figures["walls"].items():
        log(f"verify: {name}: with the {figures['real_light']} r {f['led_pearson']:.3f}, SSIM {f['led_ssim']:.3f}, "
            f"{f['led_share']:.1%} of the light"
            + (f" (a perfect outer surface: SSIM {f['led_ssim_ceiling']:.3f})" if "led_ssim_ceiling" in f else "")
            + (f", contrast on black {f['led_contrast_ratio']:.0f}:1" if f.get("led_contrast_ratio") else "")
            + f"; with a point light r {f['pearson']:.3f}, SSIM {f['ssim']:.3f}, {f['ghost_share']:.1%} of it "
              f"reflected inside the lens"
            + (f"; its slots left empty: SSIM {f['led_ssim_slots_empty']:.3f}, "
               f"{f['led_ghost_share_slots_empty']:.1%} reflected inside" if "led_ssim_slots_empty" in f else "")
            + (f"; Mitsuba r {f['mitsuba_pearson']:.3f}" if "mitsuba_pearson" in f else "")
            + (f"; r {f['optimizer_pearson']:.3f} against the optimizer's render" if "optimizer_pearson" in f else ""))
    if figures.get("optimizer_match_min", 1.0) < OPTIMIZER_MATCH_R:
        log(f"verify: WARNING: the exported lens's render matches the optimizer's only to r "
            f"{figures['optimizer_match_min']:.3f} (< {OPTIMIZER_MATCH_R})")
    figures.update(build.kind.finishing(build, figures["walls"]))
    bar.begin("the lamp's renders")
    report.figure(**figures)
    pictures = report_page.pictures(build, loaded)
    bar.begin("report.html")
    report.write(build.report_file("verify"))
    report_page.write(build, figures, pictures)
    bar.close()
    return report.data


def _ocr_texts(build: Build) -> dict[str, str]:
    """The walls' phrases for verify to read back ({} without words or without Tesseract)."""
    texts = build.texts_to_read()
    if not texts and build.wall_texts():
        log("verify: install tesseract-ocr (make setup does) to have the walls' words read back")
    return texts
