"""CheckResult: what checks.json holds for each check, exactly as before it was a type."""

import json

import numpy as np

from lampfab.checks import CheckResult, failed
from lampfab.checks.places import cylinder_place, panel_place
from lampfab.checks.result import not_applicable, short


def test_the_json_keeps_its_keys_order_and_plain_types():
    r = CheckResult("drain", np.int64(2), 0, "voids", np.bool_(False), worst=cylinder_place([0.0, -2.0, 3.5]),
                    note="two voids")
    assert json.dumps(r.to_json()) == (
        '{"name": "drain", "value": 2.0, "limit": 0.0, "unit": "voids", "passed": false, "applies": true, '
        '"worst": {"u_deg": 270.0, "z_mm": 3.5, "xyz_mm": [0.0, -2.0, 3.5]}, "note": "two voids"}')
    assert CheckResult.from_json(json.loads(json.dumps(r.to_json()))) == r
    assert r.failed and failed([r, not_applicable("overhang", "deg", "milled")]) == [r]


def test_a_check_that_does_not_apply_passes_with_nothing_measured():
    r = not_applicable("tool_axis", "deg", "on the rotary axis")
    assert (r.value, r.limit, r.passed, r.applies, r.worst, r.failed) == (None, None, True, False, None, False)


def test_places_and_figures_as_the_log_shows_them():
    assert panel_place(np.array([1.23456, 10.0, 5.5])) == {"x_mm": 1.2346, "z_mm": 5.5, "xyz_mm": [1.2346, 10.0, 5.5]}
    assert cylinder_place([0.0, 1.0, 0.0])["u_deg"] == 90.0
    assert (short(0.123456), short(None), short(2.0)) == ("0.123", "None", "2")
