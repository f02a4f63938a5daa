"""settings.json, the prerequisite Make gives every stage, and the inputs read before it.

``snapshot`` rewrites settings.json only when the resolved profiles, the input images,
the inner layer's file or the target text changed, so editing one of them redoes what
depends on it, and nothing else.  Before it writes, every input is read as the stages
will read it (``check_inputs``): a bad one stops there, with one line and no files.
"""

from __future__ import annotations

import json
from pathlib import Path

from .. import artifacts
from ..errors import LampfabError
from .build import STAGES, TEXT_SOURCE, Build


def snapshot(build: Build, images: dict[str, str], text: str = "") -> bool:
    """Write ``build.settings_file`` if what it records changed; returns whether it wrote.

    ``images``: every input image by role (a wall's name, "all", "panorama"), "" where
    not given."""
    hashes = {}
    for wall, image_path in sorted(images.items()):
        if image_path:
            if not Path(image_path).is_file():
                raise LampfabError(f"{image_path}: image not found; give the path of a PNG or JPEG image")
            hashes[wall] = {"path": image_path, "sha256": artifacts.file_sha256(image_path)}
    inner_mesh = build.design.lens.inner_mesh
    if inner_mesh and Path(inner_mesh).is_file():
        hashes["inner_layer"] = {"path": inner_mesh, "sha256": artifacts.file_sha256(inner_mesh)}
    body = json.dumps({**build.settings(), "images": hashes, "text": text}, indent=2, sort_keys=True) + "\n"
    if artifacts.holds_text(build.settings_file, body):
        return False
    check_inputs(build, images, text)
    artifacts.write_text(build.settings_file, body)
    return True


def check_inputs(build: Build, images: dict[str, str], text: str) -> None:
    """Read the images and what the lens kind reads (a lamp's inner layer) as the stages
    will, and check that every stage fits in the memory that is free; raise LampfabError."""
    from .. import image, resources, targets

    per_wall = {w.name: images[w.name] for w in build.walls if images.get(w.name)}
    target_sources(build, images.get("all", ""), per_wall, text, images.get("panorama", ""))
    for stage in STAGES:
        resources.check_memory(stage, build.design)

    for key, image_path in images.items():
        if image_path:
            luminance = image.load_target(image_path)
            if key == "panorama":
                targets.check_panorama(luminance, image_path)
    build.kind.check_inputs(build)


def target_sources(build: Build, target: str, per_wall: dict[str, str], text: str,
                   panorama: str) -> tuple[str, dict[str, str]]:
    """(what the walls without an image of their own show, {wall: its source}); raises
    LampfabError where the walls' sources are missing or contradict each other."""
    if text and panorama:
        raise LampfabError("TEXT and PANORAMA both given: choose one (per-wall TARGET_<WALL> images may be added)")
    common = f"{TEXT_SOURCE}{text}" if text else f"panorama {panorama}" if panorama else target
    sources = {w.name: per_wall.get(w.name) or common for w in build.walls}
    if not all(sources.values()):
        raise LampfabError("no target image given: set TARGET=path/to/image.png (or TEXT=\"...\" or PANORAMA=...)")
    return common, sources
