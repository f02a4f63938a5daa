"""Stage 3, init: the first lens (init.npz), the lens kind's way (``kind.first_design``)."""

from __future__ import annotations

from ..build import Build


def init(build: Build) -> dict:
    """The first lens: for a lamp transport-based (default) or the source's plain
    cylinder; for a panel its collimated transport."""
    report = build.begin("init", build.target_paths())
    heights, figures = build.kind.first_design(build)
    report.figure(**figures)
    build.save_init(heights, figures["slope_limit_deg"])
    report.write(build.report_file("init"))
    return report.data
