"""Where the benchmark scripts record a run: a section appended to today's file in
bench/log/ (created with its heading), which bench/RESULTS.md's summary links to."""

import datetime
from pathlib import Path

LOG = Path(__file__).resolve().parent / "log"


def append(text: str) -> Path:
    """Append ``text`` (a section starting with its ``## `` heading) to today's log file."""
    path = LOG / f"{datetime.date.today().isoformat()}.md"
    if not path.exists():
        path.write_text(f"# {datetime.date.today().isoformat()}\n")
    with open(path, "a") as fh:
        fh.write("\n" + text.strip("\n") + "\n")
    return path


def record(text: str) -> None:
    """``append`` ``text`` and say where it went."""
    print("recorded in", append(text))
