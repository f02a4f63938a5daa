"""What a stage shows while it runs: log lines, written above the progress bars on the
terminal rather than through them, and the bars (tqdm, imported when a bar starts)."""

from __future__ import annotations

import sys


def log(msg: str) -> None:
    """One line on stdout, above any progress bar."""
    from tqdm import tqdm

    tqdm.write(msg, file=sys.stdout)
    sys.stdout.flush()


def steps_bar(total: int, desc: str, **options):
    """A bar of ``total`` steps named ``desc``, as wide as the terminal; ``options`` as
    tqdm's (initial, disable)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="step", dynamic_ncols=True, **options)


class PartsBar:
    """A bar through named parts, for a stage whose parts take long with nothing to print
    between them: ``begin(part)`` marks the parts before it done and names it."""

    def __init__(self, desc: str, parts: list[str]):
        from tqdm import tqdm

        self.parts = parts
        self.bar = tqdm(total=len(parts), desc=desc, unit="part", dynamic_ncols=True,
                        bar_format="{desc}: {n}/{total} parts{postfix} [{elapsed}]")

    def begin(self, part: str) -> None:
        self.bar.update(self.parts.index(part) - self.bar.n)
        self.bar.set_postfix_str(part)

    def close(self) -> None:
        """Every part done."""
        self.bar.update(len(self.parts) - self.bar.n)
        self.bar.close()
