"""The stages: each reads its inputs from the build folder, calls the library, and
writes its artifact plus a JSON report (inputs with hashes, resolved settings,
versions, the checkout's git describe, wall time, key figures).  ``stages/NN_name.py``
and ``lampfab <stage>`` both call these.

``build.Build`` owns the build folder: every artifact's path, typed reads and writes,
and the lens kind it picks once (``kind``: a lamp, or a panel from ``panel.kind``).
``stages/`` holds one module per stage; ``settings`` the snapshot Make depends on and
the input checks; ``progress`` the log lines and bars; ``summary`` make lamp's last
lines; ``report_page`` report.html.
"""

from .build import STAGES, Build
from .settings import snapshot
from .stages.export import export
from .stages.fabcheck import fabcheck
from .stages.init import init
from .stages.optimize import optimize
from .stages.plan import plan
from .stages.prepare import prepare
from .stages.solid import solid
from .stages.verify import verify
from .summary import summary

__all__ = ["STAGES", "Build", "export", "fabcheck", "init", "optimize", "plan", "prepare", "snapshot", "solid",
           "summary", "verify"]
