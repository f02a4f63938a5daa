"""Fabrication checks: can this lens be printed or milled as designed?

``run_checks`` measures a lamp against a fabrication profile and ``paint_checks`` draws
``checks.png`` (``lamp``); a panel's checks are ``panel.checks``.  Every check answers a
``CheckResult`` (``result``) pointing at its worst place (``places``).  The measurements:
the outer surface's per-cell fields (``fields``, with ``distance`` for the wall
thickness), the solid's mesh (``mesh``), the whole part's size and validity (``part``),
a mill's access (``cnc``); ``paint`` composes the picture.
"""

from .lamp import paint_checks, run_checks
from .result import NAMES, CheckResult, failed

__all__ = ["NAMES", "CheckResult", "failed", "paint_checks", "run_checks"]
