"""What a fabrication check answers, and the checks in the order checks.json lists them.

Each check gives one ``CheckResult``; checks.json stores it as ``to_json()``:

    {"name": str, "value": float | None, "limit": float | None, "unit": str,
     "passed": bool, "applies": bool, "worst": {...} | None, "note": str}

``value`` is the measured figure in ``unit`` (None where there is nothing to measure, e.g.
a check that does not apply, or no concave region at all); ``passed`` is True for a check
that does not apply.  ``worst`` is the place that decided the value (``places``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

NAMES = ("min_wall", "max_slope", "tool_radius", "tool_axis", "overhang", "cavity_overhang",
         "build_volume", "mesh_valid", "drain", "cavity_access")


@dataclass(frozen=True)
class CheckResult:
    """One check's verdict (see the module docstring for the fields)."""
    name: str
    value: float | None
    limit: float | None
    unit: str
    passed: bool
    applies: bool = True
    worst: dict | None = None
    note: str = ""

    def __post_init__(self):
        # numpy scalars and counts become the plain numbers and booleans checks.json holds.
        for key in ("value", "limit"):
            number = getattr(self, key)
            object.__setattr__(self, key, None if number is None else float(number))
        object.__setattr__(self, "passed", bool(self.passed))
        object.__setattr__(self, "applies", bool(self.applies))

    @property
    def failed(self) -> bool:
        """Whether the check applies and did not pass."""
        return self.applies and not self.passed

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @staticmethod
    def from_json(data: dict) -> "CheckResult":
        return CheckResult(**data)


def not_applicable(name: str, unit: str, note: str) -> CheckResult:
    """A check with nothing to measure on this lens, passed, ``note`` saying why."""
    return CheckResult(name, None, None, unit, True, applies=False, note=note)


def failed(results: list[CheckResult]) -> list[CheckResult]:
    """The checks that apply and did not pass."""
    return [r for r in results if r.failed]


def short(number: float | None) -> str:
    """A check's value or limit as the log and report.html show it: three significant
    digits ("None" where there is none)."""
    return f"{number:.3g}" if isinstance(number, float) else str(number)
