"""Stage 5, solid: the lens as one watertight solid in mm (solid.npz)."""

from __future__ import annotations

from ..build import Build


def solid(build: Build) -> dict:
    """The refined heights made a closed solid (``kind.solid``): a lamp's outer shell
    minus its inner layer and LED bore, a panel's relief, sides and back face."""
    report = build.begin("solid", {"heightmap": build.heightmap_file})
    vertices, faces, figures = build.kind.solid(build, build.heights())
    build.save_solid(vertices, faces)
    report.figure(**figures)
    report.write(build.report_file("solid"))
    return report.data
