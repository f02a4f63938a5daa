"""The memory a stage needs, checked against the memory that is free before it starts.

A stage that runs out of memory is killed by the kernel with no word of why.  Instead,
each stage estimates its peak from what drives it (photons in flight, vertices of the
traced mesh) and stops with one line when that exceeds what the machine (or its
container) has free.  The costs per item are peak resident memory measured on this
project's machines (Linux, Dr.Jit's LLVM backend) at two sizes of each driver, rounded
up; the estimate is meant to catch settings that cannot fit, not to budget tightly.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import LampfabError
from .profile import Design

# Interpreter, numpy/scipy, Mitsuba and Dr.Jit, OCP: the tiny profile's stages peak at
# 120 to 330 MB resident.
BASE_BYTES = 400e6
# Bytes per photon in flight (origins, directions, intersection records, and for the
# splat refinement the AD graph).  Measured: 4 M against 50 k photons (the refinement's
# 4 M: 5 M traced, 2.58 GB against 0.29 GB, three gradient steps, 2026-12-02).
PER_PHOTON = {"plan": 130, "init": 240, "optimize": 480, "verify": 130}
# Bytes per vertex of the tessellated outer surface (grid x tessellation): numpy copies,
# Mitsuba's mesh and BVH, the solid's boolean and the checks' distance queries.
# Measured: 263 k against 1 k vertices.
PER_VERTEX = {"plan": 350, "init": 550, "optimize": 800, "solid": 2000, "fabcheck": 1500, "export": 1500,
              "verify": 2000}
# Photons traced per batch by the verify-style tracer (lampfab.trace.BATCH).
TRACE_BATCH = 4_000_000


def outer_vertices(design: Design) -> int:
    """Vertices of the tessellated outer surface (the traced mesh and the STL)."""
    opt = design.optimize
    return opt.grid_u * opt.tessellation * ((opt.grid_v - 1) * opt.tessellation + 1)


def in_flight(stage: str, design: Design) -> tuple[int, str]:
    """(photons or samples in flight at once, the profile keys that set it)."""
    opt, v = design.optimize, design.verify
    if stage == "plan":
        return min(v.photons, TRACE_BATCH), "[verify] photons"
    if stage == "init":
        return opt.transport_photons if opt.init == "transport" else 0, "[optimize] transport_photons"
    if stage == "optimize":
        if opt.method == "splat":
            from .splat import CAVITY_REFLECTIONS_EVERY, photons_per_step

            # into_glass follows every k-th photon across the cavity, the first included.
            most = max(photons_per_step(opt, level) for level in range(opt.levels))
            return (most + -(-most // CAVITY_REFLECTIONS_EVERY),
                    f"[optimize] splat_photons, fine_level_photons (1 in {CAVITY_REFLECTIONS_EVERY} also traced "
                    f"across the cavity)")
        views = len(design.room.walls) if opt.schedule == "joint" else 1
        return opt.spp * opt.sensor_px**2 * views, "[optimize] spp, sensor_px"
    if stage == "verify":
        return (max(min(max(v.photons, v.led_photons), TRACE_BATCH), v.scene_px**2 * v.scene_spp),
                "[verify] photons, led_photons, scene_px, scene_spp")
    return 0, ""


def need_bytes(stage: str, design: Design) -> tuple[float, str]:
    """(estimated peak bytes of ``stage``, what drives it, in words)."""
    photons, keys = in_flight(stage, design)
    vertices = outer_vertices(design)
    need = BASE_BYTES + PER_PHOTON.get(stage, 0) * photons + PER_VERTEX.get(stage, 0) * vertices
    drivers = [f"{vertices:,} surface vertices from [optimize] grid_u, grid_v, tessellation"]
    if photons:
        drivers.insert(0, f"{photons:,} photons from {keys}")
    return need, " and ".join(drivers)


def available_bytes() -> float | None:
    """Memory free for a new process: the kernel's MemAvailable, lowered to the
    container's limit (cgroup v2 or v1) when there is one.  None if unknown."""
    free = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                free = float(line.split()[1]) * 1024
    except OSError:
        try:
            free = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            limit = Path(limit_file).read_text().strip()
            usage = float(Path(usage_file).read_text().strip())
        except (OSError, ValueError):
            continue
        if limit.isdigit() and float(limit) < 2**60:  # "max" or a huge number: no limit
            room = float(limit) - usage
            free = room if free is None else min(free, room)
    return free


def check_memory(stage: str, design: Design) -> None:
    """Raise LampfabError, naming the profile keys to lower, if ``stage`` would not fit."""
    need, drivers = need_bytes(stage, design)
    free = available_bytes()
    if free is not None and need > free:
        raise LampfabError(f"{stage}: needs about {need / 1e9:.1f} GB of memory ({drivers}) but only "
                           f"{free / 1e9:.1f} GB is free; lower those settings in {design.path or 'the profile'} "
                           f"or close other programs")
