"""examples/results.py rewrites the tables between its markers from the builds' reports."""

import json

import pytest

from tests.helpers import load_script


@pytest.fixture
def results(tmp_path, monkeypatch):
    """examples/results.py, its builds under tmp_path/builds."""
    module = load_script("examples/results.py")
    monkeypatch.setattr(module, "BUILDS", tmp_path / "builds")
    return module


def _fake_build(folder, led_r):
    folder.mkdir(parents=True)
    wall = {"led_pearson": led_r, "led_ssim": 0.61, "pearson": 0.96, "ssim": 0.45, "led_share": 0.186,
            "led_blur_mm": {"horizontal": 59.4, "vertical": 81.2}, "led_reference_ssim": 0.945,
            "led_ssim_ceiling": 0.68, "led_ssim_photon_noise": 0.021, "ghost_share": 0.079,
            "mitsuba_pearson": 0.9952}
    reports = {"verify": {"walls": {"front": wall, "left": {**wall, "led_ssim": 0.64}}},
               "checks": {"checks": [{"name": "min_wall", "applies": True, "passed": True}]},
               "plan": {}, "export": {}, "prepare": {}, "init": {}, "optimize": {}, "solid": {}}
    for name, figures in reports.items():
        (folder / f"{name}.json").write_text(json.dumps({"figures": figures, "wall_time_s": 10.0}))
    (folder / "make_seconds.txt").write_text("270.0\n")


def test_the_tables_are_rewritten_between_their_markers_and_nowhere_else(results, tmp_path):
    _fake_build(tmp_path / "builds" / "apple", 0.9912)
    page = tmp_path / "page.md"
    page.write_text("before\n<!-- results:summary -->\nold row\n<!-- /results:summary -->\nafter\n"
                    "<!-- results:times -->\n<!-- /results:times -->\n"
                    "<!-- results:reflections -->\n<!-- /results:reflections -->\n")
    results.write_tables([page])
    text = page.read_text()
    assert text.startswith("before\n<!-- results:summary -->\n| image |")
    assert text.endswith("<!-- /results:reflections -->\n")
    assert "old row" not in text and "after" in text
    row = next(line for line in text.splitlines() if line.startswith("| apple |"))
    assert "| 0.991 / 0.61-0.64 | 0.960 / 0.45 | 59 x 81 mm | pass | 4.5 min |" in row
    assert "| apple | 10.0 | 10.0 |" in text and "| 80 | 4.5 min |" in text  # 8 stages of 10 s
    # SSIM over its ceiling: 0.61 / 0.68 and 0.64 / 0.68.
    assert "| apple | 0.61-0.64 | 0.68 | 0.90-0.94 | 0.94 | 0.021 | 7.9 % |" in text
    results.write_tables([page])  # a second run finds its own output between the markers
    assert page.read_text() == text


def _table_rows(results, tmp_path, table: str, start: str) -> list[str]:
    """The rows starting with ``start`` of ``table`` written on an empty page."""
    page = tmp_path / "page.md"
    page.write_text(f"<!-- results:{table} -->\n<!-- /results:{table} -->\n")
    results.write_tables([page])
    return [line for line in page.read_text().splitlines() if line.startswith(start)]


def test_the_led_design_table_sets_each_point_light_design_beside_its_led_design(results, tmp_path):
    _fake_build(tmp_path / "builds" / "apple", 0.9912)
    _fake_build(tmp_path / "builds" / "apple_point_design", 0.9701)
    rows = _table_rows(results, tmp_path, "led_design", "| apple")
    # Only the pairs whose both builds exist: text and camera have none here.
    assert rows == ["| apple | 0.970 / 0.61-0.64 | 0.991 / 0.61-0.64 | — | — | 0.960 / 0.45 | 0.960 / 0.45 "
                    "|"]


def test_the_slots_table_sets_each_slotted_lens_beside_the_default_one(results, tmp_path):
    _fake_build(tmp_path / "builds" / "star", 0.9851)
    _fake_build(tmp_path / "builds" / "star_slotted", 0.9862)
    walls = tmp_path / "builds" / "star_slotted" / "verify.json"
    slotted = json.loads(walls.read_text())
    for wall, ssim in zip(slotted["figures"]["walls"].values(), (0.90, 0.899)):
        wall.update(led_ssim=ssim, ghost_share=0.005, led_share=0.19)
    walls.write_text(json.dumps(slotted))
    assert _table_rows(results, tmp_path, "slots", "| star") == ["| star | 0.610 / 0.640 | 0.900 / 0.899 | — | 0.945 / 0.945 | "
                                                                 "0.985 → 0.986 | 7.9 → 0.5 % | 37% → 38% | — → — | 4.5 min |"]
    # verify traced the slots left empty too (builds since it does): their SSIM beside.
    for wall, ssim in zip(slotted["figures"]["walls"].values(), (0.71, 0.725)):
        wall.update(led_ssim_slots_empty=ssim)
    walls.write_text(json.dumps(slotted))
    assert "| 0.900 / 0.899 | 0.710 / 0.725 | 0.945 / 0.945 |" in _table_rows(results, tmp_path, "slots", "| star")[0]


def test_a_case_without_a_build_here_keeps_the_row_the_page_has(results, tmp_path):
    """Rerunning a few cases rewrites their rows and leaves the others' as they were."""
    _fake_build(tmp_path / "builds" / "star", 0.9912)
    page = tmp_path / "page.md"
    page.write_text("<!-- results:reflections -->\n| case | head |\n|---|---|\n| apple | kept as it was |\n"
                    "| star | an old star |\n| gone | no such case |\n<!-- /results:reflections -->\n")
    results.write_tables([page])
    rows = [line for line in page.read_text().splitlines() if line.startswith("| ") and "---" not in line]
    assert rows[1:] == ["| apple | kept as it was |", "| star | 0.61-0.64 | 0.68 | 0.90-0.94 | 0.94 | 0.021 | 7.9 % |"]
