"""Stage 6, fabcheck: can the solid be made with the fabrication profile? (checks.json,
checks.png; checks.failed.json when a check fails)"""

from __future__ import annotations

from ... import artifacts
from ...errors import CheckFailed
from ..build import Build
from ..progress import log


def fabcheck(build: Build, allow_fail: bool) -> dict:
    """Every fabrication check of the solid (``kind.check``); raises CheckFailed on a
    failed check unless ``allow_fail``."""
    from ...checks import failed
    from ...checks.result import short

    report = build.begin("fabcheck", {"solid": build.solid_file})
    results = build.kind.check(build, *build.solid_mesh())
    bad = failed(results)
    report.figure(checks=[r.to_json() for r in results], passed=not bad, allowed_to_fail=allow_fail)
    for r in results:
        if r.applies:
            log(f"check: {r.name}: {'pass' if r.passed else 'FAIL'} ({short(r.value)} {r.unit}, "
                f"limit {short(r.limit)})")
    if bad and not allow_fail:
        # A checks.json of an earlier run with other settings must not pass for this one.
        artifacts.remove(build.report_file("fabcheck"))
        report.write(build.failed_checks_file)
        worst = bad[0]
        place = worst.worst or {}
        where = f" at u {place['u_deg']:.1f}°, z {place['z_mm']:.1f} mm" if "u_deg" in place else ""
        raise CheckFailed(f"check {worst.name} failed: {short(worst.value)} {worst.unit} against "
                          f"limit {short(worst.limit)}{where} ({len(bad)} failed; see "
                          f"{build.failed_checks_file} and checks.png; ALLOW_FAIL=1 to go on)", bad)
    artifacts.remove(build.failed_checks_file)
    report.write(build.report_file("fabcheck"))
    return report.data
