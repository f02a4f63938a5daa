"""Nothing lost, nothing cryptic: bad inputs through the real command line, interrupted
and faulty runs, bit-for-bit reproducibility."""

import dataclasses
import hashlib
import io
import json
import os
import signal
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lampfab import optimize, resources, room, surface
from lampfab.errors import LampfabError
from lampfab.limits import Limits
from lampfab.source import Source

from tests.helpers import ROOT, cli, make


def files_under(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


def assert_one_clear_line(run, *words):
    """Non-zero exit, exactly one ``lampfab:`` line on stderr holding ``words``, no traceback."""
    assert run.returncode != 0
    lines = [ln for ln in run.stderr.splitlines() if ln.startswith("lampfab:")]
    assert len(lines) == 1, run.stderr[-2000:]
    assert "Traceback" not in run.stderr + run.stdout
    for word in words:
        assert word in lines[0], lines[0]


# -- the corpus of bad inputs ------------------------------------------------------------
def _disk(side: int = 32) -> np.ndarray:
    y, x = np.mgrid[:side, :side]
    return np.where((x - side / 2) ** 2 + (y - side / 2) ** 2 < (side / 3) ** 2, 255, 0).astype(np.uint8)


def _png(path: Path, array: np.ndarray) -> Path:
    Image.fromarray(array).save(path, format="PNG")
    return path


def _bomb(path: Path, side: int = 12000) -> Path:
    """A valid 1-bit PNG whose header declares side x side pixels (a few kB on disk)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")

    ihdr = side.to_bytes(4, "big") * 2 + bytes([1, 0, 0, 0, 0])
    rows = zlib.compress(bytes(side * ((side + 7) // 8 + 1)), 9)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", rows) + chunk(b"IEND", b""))
    return path


def _write(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _encoded(array: np.ndarray, fmt: str) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(array).save(buffer, format=fmt)
    return buffer.getvalue()


def _noise(path: Path) -> bytes:
    return _png(path, np.random.default_rng(3).integers(0, 256, (64, 64), np.uint8)).read_bytes()


def _truncated(path: Path) -> Path:
    data = _noise(path)
    path.write_bytes(data[: len(data) // 2])
    return path


def _corrupt(path: Path) -> Path:
    data = bytearray(_noise(path))
    data[len(data) // 2: len(data) // 2 + 16] = bytes(16)
    path.write_bytes(bytes(data))
    return path


def _inner_stl(path: Path, make_mesh) -> Path:
    make_mesh().export(path)
    return path


def _open_sphere():
    import trimesh

    s = trimesh.creation.icosphere(radius=8)
    return trimesh.Trimesh(s.vertices + [0, 0, 45], s.faces[:-3])


def _crossed_sphere():
    """A closed sphere with one vertex pushed through the far side: it passes through itself."""
    sphere = _sphere(8, [0, 0, 45])
    vertices = sphere.vertices.copy()
    vertices[0] += 2.2 * ([0, 0, 45] - vertices[0])
    import trimesh

    return trimesh.Trimesh(vertices, sphere.faces, process=False)


def _sphere(radius, centre):
    import trimesh

    return trimesh.creation.icosphere(radius=radius).apply_translation(centre)


IMAGE_CASES = {
    "missing": (lambda t: t / "no such image.png", ["no such image.png", "not found", "PNG or JPEG"]),
    "empty": (lambda t: _write(t / "empty.png", b""), ["empty.png", "empty", "PNG or JPEG"]),
    "truncated": (lambda t: _truncated(t / "cut.png"), ["cut.png", "truncated or corrupt"]),
    "corrupt": (lambda t: _corrupt(t / "noise.png"), ["noise.png", "truncated or corrupt"]),
    "text named png": (lambda t: _write(t / "notes.png", b"hello"), ["notes.png", "not an image", "PNG or JPEG"]),
    "bmp": (lambda t: _write(t / "disk.bmp", _encoded(_disk(), "BMP")), ["disk.bmp", "BMP", "convert it to PNG"]),
    "decompression bomb": (lambda t: _bomb(t / "bomb.png"), ["bomb.png", "too large", "144 megapixels", "50 megapixels"]),
    "all black": (lambda t: _png(t / "black.png", np.zeros((20, 30), np.uint8)), ["black.png", "uniform"]),
    "all white": (lambda t: _png(t / "white.png", np.full((20, 30), 255, np.uint8)), ["white.png", "uniform"]),
    "constant grey": (lambda t: _png(t / "grey.png", np.full((20, 30, 3), 128, np.uint8)), ["grey.png", "uniform"]),
    "fully transparent": (lambda t: _png(t / "clear.png", np.dstack([_disk()] * 3 + [np.zeros((32, 32), np.uint8)])),
                          ["clear.png", "uniform", "transparency over black"]),
}


@pytest.mark.parametrize("case", IMAGE_CASES)
def test_bad_image_one_line_and_no_files(tmp_path, case, tiny_profile):
    make_target, words = IMAGE_CASES[case]
    target = make_target(tmp_path)
    build = tmp_path / "build"
    run = make("prepare", f"BUILD={build}", "NAME=bad", f"PROFILE={tiny_profile}", f"TARGET={target}")
    assert_one_clear_line(run, *words)
    assert files_under(build) == []


@pytest.mark.parametrize("variables, words", [
    (["TEXT=Hi", "PANORAMA=examples/panorama.png"], ["TEXT and PANORAMA both given", "choose one"]),
    (["NAME=nothing", "TARGET=", "TARGET_FRONT=examples/apple.png"], ["no target image given", "TARGET=", "TEXT="]),
], ids=["text and panorama", "TARGET emptied, one wall given"])
def test_contradicting_or_missing_targets_one_line_and_no_files(tmp_path, variables, words, tiny_profile):
    build = tmp_path / "build"
    run = make("prepare", f"BUILD={build}", f"PROFILE={tiny_profile}", *variables)
    assert_one_clear_line(run, *words)
    assert files_under(build) == []


PROFILE_CASES = {
    "unknown key": (dict(lens="outer_radius = 40"), ["[lens] outer_radius", "unknown key", "allowed"]),
    "wrong type": (dict(replace=(("height_mm = 90.0", "height_mm = 'tall'"),)), ["height_mm", "expected a number"]),
    "negative size": (dict(replace=(("outer_radius_mm = 45.0", "outer_radius_mm = -45.0"),)),
                      ["outer_radius_mm", "out of range", "10.0 to 300.0"]),
    "zero size": (dict(replace=(("height_mm = 90.0", "height_mm = 0"),)), ["height_mm", "out of range"]),
    "light outside the lens": (dict(replace=(("light_height_mm = 45.0", "light_height_mm = 95.0"),)),
                               ["light_height_mm", "inside the lens"]),
    "light outside the cavity": (dict(replace=(("light_height_mm = 45.0", "light_height_mm = 5.0"),)),
                                 ["inner layer", "does not enclose the light", "light_height_mm"]),
    "walls behind the lamp": (dict(room_="wall_distance_mm = 100.0", replace=(("outer_radius_mm = 45.0",
                                                                              "outer_radius_mm = 60.0"),)),
                              ["wall_distance_mm", "walls behind or inside the lamp"]),
    "inner layer not closed": (dict(inner=_open_sphere), ["inner layer", "not closed", "open edges"]),
    "inner layer crosses itself": (dict(inner=_crossed_sphere), ["inner layer", "faces cross other faces", "Blender"]),
    "inner layer crosses the outer layer": (dict(inner=lambda: _sphere(30, [0, 0, 45])),
                                            ["reaches radius", "outer layer may come in"]),
    "more memory than there is": (dict(replace=(("grid_u = 32", "grid_u = 8192"), ("grid_v = 9", "grid_v = 4096"),
                                                ("tessellation = 4", "tessellation = 16"))),
                                  ["needs about", "GB of memory", "grid_u", "tessellation", "is free"]),
}


@pytest.mark.parametrize("case", PROFILE_CASES)
def test_bad_profile_one_line_and_no_files(tmp_path, case, tiny_with):
    spec, words = PROFILE_CASES[case]
    lens = spec.get("lens", "")
    if "inner" in spec:
        lens = f"inner_mesh = '{_inner_stl(tmp_path / 'inner.stl', spec['inner'])}'"
    bad = tiny_with("bad profile é.toml", lens, spec.get("room_", ""), spec.get("replace", ()))
    build = tmp_path / "build"
    run = make("prepare", f"BUILD={build}", "NAME=bad", f"PROFILE={bad}",
               f"TARGET={_png(tmp_path / 'disk.png', _disk())}")
    assert_one_clear_line(run, *words)
    assert files_under(build) == []


def test_bad_fabrication_profile(tmp_path, tiny_profile):
    fab = tmp_path / "my printer.toml"
    fab.write_text((ROOT / "profiles" / "fab" / "sla_resin.toml").read_text() + "\nnozzle_mm = 0.4\n")
    build = tmp_path / "build"
    run = make("prepare", f"BUILD={build}", f"PROFILE={tiny_profile}", f"FAB={fab}",
               f"TARGET={_png(tmp_path / 'disk.png', _disk())}")
    assert_one_clear_line(run, str(fab), "nozzle_mm", "unknown key")
    assert files_under(build) == []


def test_unicode_spaces_16bit_and_palette_targets_are_accepted(tmp_path, tiny_profile):
    """The alpha, 16-bit and palette rules of lampfab.image, through make with awkward paths."""
    folder = tmp_path / "my pictures ü"
    folder.mkdir()
    main = _png(folder / "zoë's lamp.png", _disk())
    deep = _png(folder / "sixteen bit.png", _disk().astype(np.uint16) * 257)
    palette = folder / "palette.png"
    Image.fromarray(_disk()).convert("P").save(palette)
    build = tmp_path / "build"
    run = make("prepare", f"BUILD={build}", f"PROFILE={tiny_profile}", f"TARGET={main}", f"TARGET_LEFT={deep}",
               f"TARGET_RIGHT={palette}")
    assert run.returncode == 0, run.stderr[-2000:]
    out = build / "zoë's_lamp"
    report = json.loads((out / "prepare.json").read_text())
    assert report["figures"]["front_source"] == str(main) and report["figures"]["left_source"] == str(deep)
    assert report["inputs"]["image_right"]["sha256"] == hashlib.sha256(palette.read_bytes()).hexdigest()
    assert report["seed"] == 0
    for wall in ("front", "left", "right"):
        assert 0.05 < report["figures"][f"{wall}_mean_luminance"] < 0.5
        assert (out / "targets" / f"{wall}.png").is_file()


def test_memory_check_names_the_keys(monkeypatch, tiny_design):
    design = tiny_design
    monkeypatch.setattr(resources, "available_bytes", lambda: 1e6)
    with pytest.raises(LampfabError, match=r"optimize: needs about .* GB of memory \(25,000 photons from "
                                           r"\[optimize\] splat_photons, fine_level_photons \(1 in 4 also traced "
                                           r"across the cavity\) and 4,224 surface vertices"):
        resources.check_memory("optimize", design)
    finer = dataclasses.replace(design, optimize=dataclasses.replace(design.optimize, levels=2, fine_level_photons=2.0))
    assert resources.in_flight("optimize", finer)[0] == 50_000  # the fine level's photons set the peak
    monkeypatch.setattr(resources, "available_bytes", lambda: 64e9)
    resources.check_memory("optimize", design)
    monkeypatch.setattr(resources, "available_bytes", lambda: None)  # unknown: never a reason to stop
    resources.check_memory("optimize", design)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/meminfo is Linux's")
def test_available_memory_is_read_on_linux():
    meminfo = {line.split(":")[0]: float(line.split()[1]) * 1024
               for line in Path("/proc/meminfo").read_text().splitlines()}
    free = resources.available_bytes()
    assert free is not None and 1e7 < free <= meminfo["MemTotal"]


@pytest.mark.parametrize("files, free", [
    ({}, 8e9),
    ({"sys/fs/cgroup/memory.max": "4000000000", "sys/fs/cgroup/memory.current": "1000000000"}, 3e9),
    ({"sys/fs/cgroup/memory.max": "max", "sys/fs/cgroup/memory.current": "1000000000"}, 8e9),
    ({"sys/fs/cgroup/memory/memory.limit_in_bytes": "2000000000",
      "sys/fs/cgroup/memory/memory.usage_in_bytes": "500000000"}, 1.5e9),
    ({"sys/fs/cgroup/memory/memory.limit_in_bytes": str(2**63 - 4096),
      "sys/fs/cgroup/memory/memory.usage_in_bytes": "500000000"}, 8e9),
], ids=["no container", "cgroup v2 limit", "cgroup v2 without limit", "cgroup v1 limit", "cgroup v1 without limit"])
def test_a_container_limit_lowers_the_available_memory(monkeypatch, tmp_path, files, free):
    """MemAvailable, lowered to what a container's limit leaves (the files as the kernel
    writes them, under a stand-in root)."""
    files = {"proc/meminfo": "MemTotal:       16000000 kB\nMemAvailable:    7812500 kB\n", **files}
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text + "\n")
    monkeypatch.setattr(resources, "Path", lambda path: tmp_path / str(path).lstrip("/"))
    assert resources.available_bytes() == pytest.approx(free)


# -- numerical faults --------------------------------------------------------------------
class Quadratic(optimize.Optimizer):
    """Pulls every node to 1 mm; ``faults`` maps a call number to the loss it returns."""

    def __init__(self, design, faults, **changes):
        opt = dataclasses.replace(design.optimize, **{"levels": 1, "update_rule": "gd", "learning_rate": 0.1, **changes})
        super().__init__(surface.Cylinder(45.0, 90.0), None, None, None, 1.49, room.walls(design), [], opt,
                         Limits(20.0, 45.0))
        self.faults, self.calls = faults, 0

    def gradient(self, heights, views, seed, level=-1):
        self.calls += 1
        r = heights - 1.0
        if self.calls in self.faults:
            return self.faults[self.calls], 2 * r
        return float(np.sum(r**2)), 2 * r


def _run(opt, state=None):
    grid = (opt.opt.grid_u, opt.opt.grid_v)
    messages, checkpoints = [], []
    state = opt.run(state or optimize.State(np.zeros(grid), 0, 0), lambda s: checkpoints.append(s.step),
                    lambda s: None, lambda s, loss, m: m and messages.append(m))
    return state, messages, checkpoints


def test_finer_levels_step_at_their_rate(tiny_design):
    runner = Quadratic(tiny_design, {})
    runner.opt = dataclasses.replace(runner.opt, levels=2, fine_level_rate=0.5)
    nu, nv = runner.opt.grid_u, runner.opt.grid_v
    state = optimize.State(np.zeros((nu, nv)), 0, 0)
    assert runner.step_delta(state, np.ones((nu // 4, nv // 4))) == pytest.approx(-0.1)
    assert runner.step_delta(state, np.ones((nu, nv))) == pytest.approx(-0.1 * 0.5 / 4)  # spacing 4, rate 0.5


def test_the_finest_level_anneals_its_step_to_the_last(tiny_design):
    runner = Quadratic(tiny_design, {})
    runner.opt = dataclasses.replace(runner.opt, levels=2, iterations=14, fine_level_anneal=True)
    nu, nv = runner.opt.grid_u, runner.opt.grid_v

    def step_at(step, grid):
        return runner.step_delta(optimize.State(np.zeros((nu, nv)), level=0, step=step), np.ones(grid))

    coarse = (nu // 4, nv // 4)
    assert step_at(0, coarse) == pytest.approx(-0.1) and step_at(6, coarse) == pytest.approx(-0.1)
    assert step_at(7, (nu, nv)) == pytest.approx(-0.1 / 4)             # the fine level's first step: whole
    assert step_at(13, (nu, nv)) == pytest.approx(-0.1 / 4 * 2 / 7)    # its last of 7: two sevenths
    factors = [optimize.anneal_factor(runner.opt, k) for k in range(14)]
    assert factors == pytest.approx([1] * 7 + [1, 1, 1, 1, 6 / 7, 4 / 7, 2 / 7])
    without = dataclasses.replace(runner.opt, fine_level_anneal=False)
    assert [optimize.anneal_factor(without, k) for k in range(14)] == [1.0] * 14


@pytest.mark.parametrize("bad_loss, words", [(float("nan"), "the loss is nan"), (float("inf"), "the loss is inf"),
                                              (1e9, "the loss exploded")])
def test_a_fault_falls_back_to_the_last_checkpoint_with_a_smaller_step(tiny_design, bad_loss, words):
    clean, _, _ = _run(Quadratic(tiny_design, {}, iterations=8, checkpoint_every=3))
    faulty, messages, checkpoints = _run(Quadratic(tiny_design, {5: bad_loss}, iterations=8, checkpoint_every=3))
    assert len(messages) == 1 and messages[0].startswith(f"step 4: {words}")
    assert "back to the last good checkpoint (step 3) with the learning rate x0.5" in messages[0]
    assert faulty.step == 8 and faulty.lr_scale == 0.5 and faulty.faults == [(4, 0.5)]
    assert [row[0] for row in faulty.log] == list(range(8))  # steps 3.. redone, none lost
    assert np.all(np.isfinite(faulty.heights))
    assert np.abs(faulty.heights - 1).max() > np.abs(clean.heights - 1).max()  # the smaller step shows
    assert checkpoints == [3, 6]


def test_the_loss_explodes_past_20_times_its_best():
    no_gradient = np.zeros(3)
    assert optimize._fault(2.01, no_gradient, best=0.1).startswith("the loss exploded (2.01, over 20x")
    assert optimize._fault(1.99, no_gradient, best=0.1) is None


def test_a_nan_gradient_is_a_fault_too(tiny_design):
    opt = Quadratic(tiny_design, {}, iterations=4, checkpoint_every=2)
    real = opt.gradient
    opt.gradient = lambda h, v, seed, level: ((real(h, v, seed)[0], np.full_like(h, np.nan)) if opt.calls == 2
                                              else real(h, v, seed))
    state, messages, _ = _run(opt)
    assert len(messages) == 1 and messages[0].startswith("step 2: the gradient has") and "NaN or Inf" in messages[0]
    assert state.step == 4 and np.all(np.isfinite(state.heights))


def test_backtracking_halves_a_step_that_raises_the_loss(tiny_design):
    # Plain descent on sum((h - 1)^2) at rate 1.5 overshoots (h - 1 -> -2 (h - 1)) and
    # diverges; at 0.75 it converges.
    changes = dict(iterations=8, checkpoint_every=100, learning_rate=1.5, schedule="joint")
    plain, _, _ = _run(Quadratic(tiny_design, {}, **changes))
    guarded, messages, _ = _run(Quadratic(tiny_design, {}, backtrack=True, **changes))
    assert plain.faults  # the loss exploded
    assert not guarded.faults and not messages
    assert guarded.backtracks[0] == (1, 0.5)
    assert [row[0] for row in guarded.log] == list(range(8))  # the rejected evaluation is a step too
    losses = [row[3] for row in guarded.log]
    assert losses[1] == pytest.approx(4 * losses[0])  # evaluated, then stepped over again from step 0
    assert losses[2] == pytest.approx(losses[0] / 4)
    assert np.abs(guarded.heights - 1).max() < 0.05


def test_backtracking_starts_each_level_at_the_full_step(tiny_design):
    runner = Quadratic(tiny_design, {}, iterations=8, checkpoint_every=100, learning_rate=1.5, schedule="joint",
                       backtrack=True)
    runner.opt = dataclasses.replace(runner.opt, levels=2)
    seen = []
    real = runner.step_delta
    runner.step_delta = lambda state, grad: seen.append((state.step, state.lr_scale)) or real(state, grad)
    _run(runner)
    assert dict(seen)[4] == 1.0 and min(scale for _, scale in seen[:4]) < 1.0


def test_backtracking_with_one_view_per_step_is_refused(tiny_design):
    # The bench's ptracer method once ran so: every step compared another wall's loss and
    # was taken back, and the lens never moved.
    with pytest.raises(ValueError, match="backtrack needs schedule 'joint'"):
        Quadratic(tiny_design, {}, schedule="cyclic", backtrack=True)


def test_a_fault_that_stays_stops_with_a_message(tiny_design):
    always = {k: float("nan") for k in range(3, 100)}
    with pytest.raises(optimize.NumericalFault, match=r"step 2: the loss is nan, even after halving the learning "
                                                      r"rate 10 times from the checkpoint at step 2"):
        _run(Quadratic(tiny_design, always, iterations=6, checkpoint_every=2))


def test_nan_in_the_first_lens_is_refused(tmp_path, tiny_profile):
    heights = np.zeros((32, 9))
    heights[3, 4] = np.nan
    np.savez(tmp_path / "init.npz", heights=heights)
    run = cli("optimize", "--out", tmp_path, "--profile", tiny_profile)
    assert_one_clear_line(run, "init.npz", "1 heights are NaN or Inf", "re-run init")
    assert files_under(tmp_path) == [tmp_path / "init.npz"]


def test_a_first_lens_without_its_slope_limit_is_refused(tmp_path, tiny_profile):
    np.savez(tmp_path / "init.npz", heights=np.zeros((32, 9)))
    run = cli("optimize", "--out", tmp_path, "--profile", tiny_profile)
    assert_one_clear_line(run, "init.npz", "no slope limit", "re-run init")


# -- reproducibility ------------------------------------------------------------------------
def test_splat_gradient_is_bit_reproducible(mi, tiny_design, inner_layer):
    from lampfab import splat

    walls = room.walls(tiny_design)
    targets = [np.random.default_rng(7).random(room.image_shape(w, 16)) for w in walls]
    h = np.random.default_rng(3).normal(scale=0.5, size=(tiny_design.optimize.grid_u, tiny_design.optimize.grid_v))
    results = []
    for _ in range(2):
        opt = splat.SplatOptimizer(surface.Cylinder(45.0, 90.0), *inner_layer, Source(room.light_position(tiny_design)), 1.49,
                                   walls, targets, dataclasses.replace(tiny_design.optimize, splat_photons=100_000),
                                   Limits(20.0, 45.0))
        results.append(opt.gradient(h, [0, 1, 2], seed=11))
    assert results[0][0] == results[1][0] and np.abs(results[0][1]).max() > 0
    assert results[0][1].tobytes() == results[1][1].tobytes()


def _checkpoint_step(out: Path) -> int:
    """The step of ``out``'s optimize checkpoint, 0 if none."""
    if not (out / "checkpoint.npz").exists():
        return 0
    with np.load(out / "checkpoint.npz") as saved:
        return int(saved["step"])


@pytest.mark.slow
@pytest.mark.e2e
def test_interrupted_runs_resume_to_the_same_bytes_as_an_uninterrupted_one(tmp_path, tiny_with):
    """Two builds from scratch with one seed; the second is stopped by Ctrl-C (SIGINT),
    then SIGTERM, then killed with SIGKILL, and each time resumed.  Every artifact
    matches bit for bit."""
    prof = tiny_with("resume.toml", replace=(("iterations = 2", "iterations = 24"),
                                              ("preview_every = 1", "preview_every = 1000")))
    outs = []
    for name in ("straight", "stopped"):
        run = make("init", f"BUILD={tmp_path / name}", "NAME=apple", f"PROFILE={prof}")
        assert run.returncode == 0, run.stderr[-2000:]
        outs.append(tmp_path / name / "apple")
    straight, stopped = outs
    assert (straight / "init.npz").read_bytes() == (stopped / "init.npz").read_bytes()
    optimize_cmd = [sys.executable, "stages/30_optimize.py", "--profile", str(prof), "--out"]
    run = subprocess.run([*optimize_cmd, str(straight)], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]

    step = 0
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        before = step
        proc = subprocess.Popen([*optimize_cmd, str(stopped)], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        while _checkpoint_step(stopped) <= before:  # a checkpoint newer than the last one
            assert proc.poll() is None, proc.communicate()[1][-2000:]
            time.sleep(0.05)
        os.kill(proc.pid, sig)
        stdout, stderr = proc.communicate()
        if sig != signal.SIGKILL:
            assert proc.returncode == 2
            lines = [ln for ln in stderr.splitlines() if ln.startswith("lampfab:")]
            assert len(lines) == 1 and "interrupted at step" in lines[0] and "run the same command again" in lines[0]
        else:
            assert proc.returncode == -signal.SIGKILL
        step = _checkpoint_step(stopped)
        assert before < step < 24
        assert not (stopped / "optimize.json").exists() and not (stopped / "heightmap.npz").exists()
    again = subprocess.run([*optimize_cmd, str(stopped)], cwd=ROOT, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"resuming from {stopped / 'checkpoint.npz'} at step {step}" in again.stdout
    assert (straight / "heightmap.npz").read_bytes() == (stopped / "heightmap.npz").read_bytes()
    assert not (stopped / "checkpoint.npz").exists() and not list(stopped.glob(".*"))

    report = json.loads((stopped / "optimize.json").read_text())
    assert report["figures"]["resumed"] and report["figures"]["steps"] == 24 and report["seed"] == 0
    assert {"init", "target_front", "design_profile", "fabrication_profile", "inner_layer"} <= set(report["inputs"])
    assert report["versions"]["drjit"] and report["settings"]["design"]["optimize"]["seed"] == 0

    # The STEP's header carries a timestamp unless SOURCE_DATE_EPOCH fixes it.
    env = {**os.environ, "SOURCE_DATE_EPOCH": "1700000000"}
    for out in outs:
        for stage in ("40_solid", "50_fabcheck", "60_export"):
            run = subprocess.run([sys.executable, f"stages/{stage}.py", "--profile", str(prof), "--out", str(out)],
                                 cwd=ROOT, capture_output=True, text=True, env=env)
            assert run.returncode == 0, run.stderr[-2000:]
    for name in ("solid.npz", "lens.stl", "lens.step", "lens.glb"):
        assert (straight / name).read_bytes() == (stopped / name).read_bytes(), name


def test_setup_refuses_an_old_python_with_one_line(tmp_path):
    """stages/00_setup.sh stops before installing anything when python3 is older than
    3.11 (lampfab reads profiles with tomllib)."""
    fake = tmp_path / "python3"
    fake.write_text('#!/bin/sh\n[ "$1" = "--version" ] && echo "Python 3.10.12"\nexit 1\n')
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{tmp_path}:{os.environ['PATH']}"}
    run = subprocess.run(["bash", str(ROOT / "stages" / "00_setup.sh")], env=env, capture_output=True, text=True)
    assert run.returncode == 1
    assert run.stderr.strip() == "lampfab setup: needs Python 3.11 or newer as python3 (found: Python 3.10.12)"


def test_a_reader_that_stops_early_gets_no_traceback():
    """`lampfab profiles | head -1`: the listing stops quietly when its reader does (here
    a pipe whose reader is gone before the listing starts, so every write fails)."""
    read, write = os.pipe()
    os.close(read)
    try:
        run = subprocess.run([sys.executable, "-m", "lampfab.cli", "profiles"], cwd=ROOT, stdout=write,
                             stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write)
    assert run.returncode == 141 and run.stderr == ""
