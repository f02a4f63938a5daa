"""Stage 1, prepare: one linear-luminance target per wall (targets/)."""

from __future__ import annotations

from ... import room
from ..build import Build
from ..settings import target_sources

TARGET_PX = 256  # prepared targets: 256 px wide, enough for every stage's resolution


def prepare(build: Build, target: str, per_wall: dict[str, str], text: str = "", panorama: str = "") -> dict:
    """One linear-luminance target per wall, letterboxed to the wall's aspect ratio.

    Each wall takes its own image if given, else ``text``, else its slice of
    ``panorama``, else ``target``."""
    from ... import image, targets

    common, sources = target_sources(build, target, per_wall, text, panorama)
    inputs = {f"image_{k}": v for k, v in sources.items()}  # text is no file: the report leaves it out
    report = build.begin("prepare", {**inputs, "panorama": panorama})
    loaded, prepared = {}, {}
    if panorama:
        loaded[common] = image.load_target(panorama)
        targets.check_panorama(loaded[common], panorama)
    for wall in build.walls:
        src = sources[wall.name]
        shape = room.image_shape(wall, TARGET_PX)
        if src == common and text:
            img = targets.text_image(text, *shape)
        elif src == common and panorama:
            d = build.design.room
            img = targets.panorama_slice(loaded[common], wall, build.light, d.wall_distance_mm,
                                         d.target_center_z_mm, *shape)
        else:
            if src not in loaded:
                loaded[src] = image.load_target(src)
            img = image.letterbox(loaded[src], *shape)
        prepared[wall.name] = img
        report.figure(**{f"{wall.name}_mean_luminance": float(img.mean()),
                         f"{wall.name}_source": str(src)})
    # Written only once every wall's image has been read: a bad one leaves no files.
    build.save_targets(prepared)
    report.write(build.report_file("prepare"))
    return report.data
