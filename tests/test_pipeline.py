"""End to end, as a user runs it: `make lamp` with a tiny profile, then the files."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
TINY = ROOT / "tests" / "data" / "tiny.toml"


def make(*args, cwd=ROOT):
    return subprocess.run(["make", "--no-print-directory", *args], cwd=cwd, capture_output=True, text=True)


@pytest.fixture(scope="module")
def lamp(tmp_path_factory):
    build = tmp_path_factory.mktemp("build")
    run = make("lamp", f"BUILD={build}", "NAME=apple", f"PROFILE={TINY}", "ALLOW_FAIL=1")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return build / "apple", run, build


@pytest.mark.slow
def test_make_lamp_writes_every_artifact(lamp):
    out, run, _ = lamp
    for name in ["targets/front.png", "prepare.json", "plan.json", "init.json", "heightmap.npz", "loss.csv",
                 "optimize.json", "solid.npz", "checks.png", "lens.stl", "lens.step", "design.json",
                 "export.json", "verify.json", "report.html", "verify/front_led.png"]:
        assert (out / name).is_file(), name
    assert "total" in run.stdout  # the per-stage summary
    log = (out / "loss.csv").read_text().splitlines()
    steps = json.loads((out / "optimize.json").read_text())["figures"]["steps"]
    assert log[0] == "step,level,view,loss,seconds" and len(log) == 1 + steps
    assert [int(row.split(",")[0]) for row in log[1:]] == list(range(steps))
    for report in ["prepare", "plan", "init", "optimize", "solid", "export", "verify"]:
        data = json.loads((out / f"{report}.json").read_text())
        assert data["versions"]["mitsuba"] and data["wall_time_s"] >= 0 and data["settings"]["design"]


@pytest.mark.slow
def test_design_json_contract_and_files(lamp):
    from lampfab import solid, step, stl

    out, _, _ = lamp
    design = json.loads((out / "design.json").read_text())
    assert design["units"] == "mm" and len(design["light"]["position"]) == 3
    assert {w["name"] for w in design["walls"]} == {"front", "left", "right"}
    for wall in design["walls"]:
        assert (out / wall["target"]).is_file()
        assert np.linalg.norm(wall["right"]) > 100 and np.linalg.norm(wall["down"]) > 100
    v, f = stl.read_stl(out / design["lens"]["stl"])
    edges = solid.edge_check(f)
    assert edges["watertight"] and edges["winding_consistent"] and edges["components"] == 1
    assert v[:, 2].min() == pytest.approx(0.0, abs=1e-3)  # standing on its base
    back = step.read_step(out / design["lens"]["step"])
    assert back["n_solids"] == 1 and back["valid"] and back["closed"]
    assert back["volume_mm3"] == pytest.approx(solid.mesh_volume(v, f), rel=5e-3)


@pytest.mark.slow
def test_verify_reports_figures_and_report_embeds_images(lamp):
    out, _, _ = lamp
    figures = json.loads((out / "verify.json").read_text())["figures"]
    for name in ["front", "left", "right"]:
        wall = figures["walls"][name]
        assert -1 <= wall["pearson"] <= 1 and 0 < wall["share"] < 1
        # Two glass-air interfaces reflect ~4 % each; every photon is either direct or a ghost.
        assert 0.01 < wall["ghost_share"] < 0.3
        images = np.load(out / "verify" / f"{name}.npz")
        assert np.all(images["ghosts"] <= images["point"])
        assert -1 <= wall["direct_ssim"] <= 1 and wall["ssim"] < wall["ssim_ceiling"] <= 1
    html = (out / "report.html").read_text()
    assert len(re.findall(r'<img[^>]+src="data:image/png;base64,', html)) >= 9


@pytest.mark.slow
def test_exported_files_match_the_optimizer_and_come_with_finishing_advice(lamp):
    out, _, _ = lamp
    export = json.loads((out / "export.json").read_text())["figures"]
    assert export["admesh"]["repairs"] == 0 and export["admesh"]["parts"] == 1       # a slicer takes it as is
    figures = json.loads((out / "verify.json").read_text())["figures"]
    agree = [figures["walls"][w]["optimizer_pearson"] for w in ("front", "left", "right")]
    # The tiny profile's optimizer splats only 20k photons onto 16 px walls, so its own render
    # is noisy; the default profile reaches OPTIMIZER_MATCH_R (README). A wrong export (e.g. a
    # mirrored or rotated lens) would fall far below this.
    assert min(agree) == figures["optimizer_match_min"] and min(agree) > 0.85
    assert figures["optimizer_match_limit"] == 0.98
    study = figures["tolerance"]
    assert study["amplitudes_mm"][0] == 0.0 and study["max_drop"][0] == 0.0
    assert study["profile_error_mm"] == 0.05                                           # sla_resin's
    assert any("lights the front wall" in p for p in figures["guidance"])
    html = (out / "report.html").read_text()
    assert "Finishing and tolerances" in html and "peak surface error" in html


@pytest.mark.slow
def test_rerun_is_a_no_op_and_profile_change_redoes_work(lamp, tmp_path):
    out, _, build = lamp
    again = make("lamp", f"BUILD={build}", "NAME=apple", f"PROFILE={TINY}", "ALLOW_FAIL=1")
    assert again.returncode == 0 and "stages/" not in again.stdout
    changed = tmp_path / "tiny2.toml"
    changed.write_text(TINY.read_text().replace("photons = 50000", "photons = 60000"))
    plan = make("plan", f"BUILD={build}", "NAME=apple", f"PROFILE={changed}")
    assert plan.returncode == 0 and "stages/20_plan.py" in plan.stdout


@pytest.mark.slow
def test_a_failed_check_stops_with_one_line(lamp, tmp_path):
    out, _, build = lamp
    # A printer that wants 40 mm walls: no lens of this size has them everywhere.
    strict = tmp_path / "thick_walls.toml"
    sla = (ROOT / "profiles" / "fab" / "sla_resin.toml").read_text()
    strict.write_text(re.sub(r"(?m)^min_wall_mm = .*$", "min_wall_mm = 40.0", sla))
    run = make("check", f"BUILD={build}", "NAME=apple", f"PROFILE={TINY}", f"FAB={strict}")
    assert run.returncode != 0
    lines = [ln for ln in run.stderr.splitlines() if ln.startswith("lampfab:")]
    assert len(lines) == 1 and "failed" in lines[0] and "Traceback" not in run.stderr
    assert not (out / "checks.json").exists() and (out / "checks.failed.json").exists()


def test_bad_image_is_one_line_and_leaves_no_files(tmp_path):
    bad = tmp_path / "not an image é.png"
    bad.write_text("hello")
    run = subprocess.run([sys.executable, "-m", "lampfab.cli", "prepare", "--out", str(tmp_path / "b"),
                          "--profile", str(TINY), "--target", str(bad)], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1 and str(bad) in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "b" / "prepare.json").exists()


def test_help_is_instant_and_lists_the_stages():
    run = subprocess.run([sys.executable, "-X", "importtime", "-m", "lampfab.cli", "--help"], cwd=ROOT,
                         capture_output=True, text=True)
    assert run.returncode == 0
    for stage in ["prepare", "plan", "init", "optimize", "solid", "check", "export", "verify", "lamp"]:
        assert stage in run.stdout
    assert "mitsuba" not in run.stderr and "OCP" not in run.stderr  # heavy imports stay lazy


@pytest.mark.slow
def test_floor_and_per_wall_targets(tmp_path):
    """A fourth surface, the floor behind the lamp, and a different image per wall."""
    profile = tmp_path / "floor.toml"
    profile.write_text(TINY.read_text().replace('walls = ["front", "left", "right"]',
                                                'walls = ["front", "left", "right", "floor"]'))
    run = make("verify", f"BUILD={tmp_path / 'b'}", "NAME=four", f"PROFILE={profile}", "ALLOW_FAIL=1",
               f"TARGET_FLOOR={ROOT / 'examples' / 'star.png'}")
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    out = tmp_path / "b" / "four"
    design = json.loads((out / "design.json").read_text())
    floor = next(w for w in design["walls"] if w["name"] == "floor")
    assert floor["origin"][2] < 0 and abs(floor["down"][2]) < 1e-9  # on the floor, below the lamp
    figures = json.loads((out / "verify.json").read_text())["figures"]["walls"]
    assert set(figures) == {"front", "left", "right", "floor"}
    prepared = json.loads((out / "prepare.json").read_text())["figures"]
    assert prepared["floor_source"].endswith("star.png") and prepared["front_source"].endswith("apple.png")
