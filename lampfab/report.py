"""The final report: one self-contained HTML page (images embedded, no external files).

A maker reads it in a minute: the first screen is the lamp in its room, a one-line
verdict and the few facts that matter; then each wall's pictures side by side; then the
figures in groups with human labels and units (the raw keys stay in the ``*.json``
reports); then free sections (checks, finishing, next steps).  Opens offline in any
browser; write it with ``write_report``.  ``report_page`` decides what goes in it.
"""

from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass, field
from pathlib import Path

from .artifacts import write_text
from .errors import LampfabError

_MIME = ((b"\x89PNG\r\n\x1a\n", "image/png"), (b"\xff\xd8\xff", "image/jpeg"), (b"GIF8", "image/gif"))

_CSS = """
:root { color-scheme: dark; }
* { box-sizing: border-box; }
body { margin: 0; background: #0d0f12; color: #d8dce3;
  font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, Helvetica, Arial, sans-serif; }
main { max-width: 1320px; margin: 0 auto; padding: 28px 24px 64px; }
h1 { font-size: 28px; font-weight: 600; margin: 0 0 6px; color: #fff; letter-spacing: .01em; }
h2 { font-size: 20px; font-weight: 600; margin: 40px 0 12px; color: #fff;
  border-bottom: 1px solid #262b33; padding-bottom: 6px; }
h3 { font-size: 17px; font-weight: 600; margin: 0 0 12px; color: #f3d98b; }
.wall h3 { text-transform: capitalize; }
.verdict { font-size: 18px; color: #eef1f5; margin: 0 0 16px; }
.verdict.good { border-left: 4px solid #7bd88f; padding-left: 12px; }
.verdict.warn { border-left: 4px solid #f3d98b; padding-left: 12px; }
.verdict.bad { border-left: 4px solid #ff7b72; padding-left: 12px; }
.hero img { display: block; width: 100%; height: auto; border-radius: 8px; border: 1px solid #2a2f38; }
.hero figcaption { margin-top: 6px; font-size: 13px; color: #8a93a1; }
.facts { display: grid; grid-template-columns: repeat(auto-fit, minmax(230px, 1fr)); gap: 12px; margin: 16px 0 0; }
.fact { background: #15181d; border: 1px solid #232830; border-radius: 10px; padding: 12px 14px; }
.fact b { display: block; color: #8a93a1; font-weight: 500; font-size: 13px; }
.fact span { color: #fff; font-size: 16px; }
.wall { background: #15181d; border: 1px solid #232830; border-radius: 10px; padding: 18px; margin: 0 0 22px; }
.row { display: grid; grid-template-columns: repeat(auto-fit, minmax(240px, 1fr)); gap: 16px; }
figure { margin: 0; }
figure img { display: block; width: 100%; height: auto; background: #000;
  border: 1px solid #2a2f38; border-radius: 6px; image-rendering: auto; }
.missing { display: flex; align-items: center; justify-content: center; aspect-ratio: 4 / 3;
  background: #000; border: 1px dashed #3a404b; border-radius: 6px; color: #6b7380; }
figcaption { margin-top: 8px; font-size: 13px; color: #aab2bf; }
figcaption b { display: block; color: #e6e9ee; font-size: 14px; margin-bottom: 2px; }
.figs { display: flex; flex-wrap: wrap; gap: 2px 14px; }
.figs span { white-space: nowrap; }
.figs em { font-style: normal; color: #f3d98b; font-variant-numeric: tabular-nums; }
table { border-collapse: collapse; width: 100%; font-size: 14px; margin-bottom: 18px; }
th, td { text-align: left; padding: 5px 10px; border-bottom: 1px solid #232830; vertical-align: top; }
th { color: #8a93a1; font-weight: 500; width: 45%; }
td { font-variant-numeric: tabular-nums; color: #e6e9ee; word-break: break-word; }
.groups { display: grid; grid-template-columns: repeat(auto-fit, minmax(380px, 1fr)); gap: 0 28px; }
.groups h3 { margin-top: 10px; }
section.free { background: #15181d; border: 1px solid #232830; border-radius: 10px;
  padding: 4px 18px 14px; margin: 0 0 18px; }
section.free h2 { border: 0; margin-top: 14px; }
code, pre { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; font-size: 13px; }
a { color: #8fc1ff; }
.ok { color: #7bd88f; } .fail { color: #ff7b72; } .warn { color: #f3d98b; }
.note { color: #8a93a1; font-size: 13px; }
footer { margin-top: 40px; color: #5d6470; font-size: 12px; }
"""


@dataclass(frozen=True)
class Picture:
    """One embedded picture: its label, its file (None: a placeholder), figures shown
    under it as (label, text) pairs, and a note."""
    label: str
    path: object
    figures: list = field(default_factory=list)
    note: str = ""


def write_report(path: str | os.PathLike, title: str, verdict: str, *, tone: str = "good",
                 hero: Picture | None = None, facts: list[tuple[str, str]] = (),
                 walls: list[tuple[str, list[Picture]]] = (), groups: dict[str, list[tuple[str, str]]] | None = None,
                 sections: list[tuple[str, str]] = ()) -> None:
    """Write the HTML report to ``path`` atomically.

    ``verdict``: the one line under the title (text, escaped), coloured by ``tone``
    ("good", "warn", "bad"); ``hero``: the big picture; ``facts``: (label, text) tiles
    under it; ``walls``: per wall its name and pictures side by side; ``groups``:
    {group: [(label, text)]}, the figures as tables; ``sections``: (title, HTML) pairs
    whose HTML comes from lampfab itself, never from the user, and is inserted as is
    (``figure_html`` makes their pictures).  Every text shown is escaped here.  An image
    path that does not exist raises ``LampfabError``.
    """
    from . import __version__

    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             '<meta name="viewport" content="width=device-width, initial-scale=1">',
             f"<title>{_e(title)}</title>", f"<style>{_CSS}</style>", "</head><body><main>",
             f"<h1>{_e(title)}</h1>", f'<p class="verdict {_e(tone)}">{_e(verdict)}</p>']
    if hero is not None:
        parts.append(f'<figure class="hero">{_img(hero)}<figcaption>{_e(hero.note)}</figcaption></figure>')
    if facts:
        parts.append('<div class="facts">' + "".join(
            f'<div class="fact"><b>{_e(k)}</b><span>{_e(v)}</span></div>' for k, v in facts) + "</div>")
    if walls:
        parts.append("<h2>What each wall shows</h2>")
    for name, pictures in walls:
        row = "".join(figure(p) for p in pictures)
        parts.append(f'<section class="wall"><h3>{_e(name)}</h3><div class="row">{row}</div></section>')
    if groups:
        parts.append("<h2>Key figures</h2><div class=\"groups\">" + "".join(
            f"<div><h3>{_e(group)}</h3><table>"
            + "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in rows) + "</table></div>"
            for group, rows in groups.items() if rows) + "</div>")
    parts.extend(f'<section class="free"><h2>{_e(t)}</h2>{snippet}</section>' for t, snippet in sections)
    parts.append(f"<footer>Made by lampfab {_e(__version__)}. Every figure's raw value is in the stage "
                 f"reports (*.json) beside this page.</footer>")
    parts.append("</main></body></html>\n")
    write_text(path, "\n".join(parts))


def figure(picture: Picture) -> str:
    """One picture with its label, its figures and its note (all escaped)."""
    figs = "".join(f"<span>{_e(k)} <em>{_e(v)}</em></span>" for k, v in picture.figures)
    figs_html = f'<div class="figs">{figs}</div>' if figs else ""
    note = f'<span class="note">{_e(picture.note)}</span>' if picture.note else ""
    return f"<figure>{_img(picture)}<figcaption><b>{_e(picture.label)}</b>{figs_html}{note}</figcaption></figure>"


def figure_html(label: str, path, caption: str = "") -> str:
    """One embedded picture (PNG, JPEG or GIF) with its label and an escaped caption."""
    return figure(Picture(label, path, note=caption))


def _img(picture: Picture) -> str:
    if not picture.path:
        return '<div class="missing">not available</div>'
    return f'<img src="{_data_uri(picture.path)}" alt="{_e(picture.label)}">'


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _data_uri(path) -> str:
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise LampfabError(f"{p}: image for the report not found (run the stage that makes it first)") from None
    except OSError as exc:
        raise LampfabError(f"{p}: cannot read image for the report ({exc.strerror or exc})") from None
    for magic, mime in _MIME:
        if data.startswith(magic):
            return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"
    raise LampfabError(f"{p}: not a PNG, JPEG or GIF image; the report embeds only these")


def number(value, digits: int = 3) -> str:
    """A figure to ``digits`` decimals, or a dash when it is missing."""
    if value is None:
        return "—"
    return f"{float(value):.{digits}f}"


def percent(value, digits: int = 1) -> str:
    if value is None:
        return "—"
    return f"{100 * float(value):.{digits}f} %"


def span(values, fmt=number) -> str:
    """Several walls' figure as one text: "0.61" when alike, else "0.61-0.67"."""
    present = [v for v in values if v is not None]
    if not present:
        return "—"
    lo, hi = fmt(min(present)), fmt(max(present))
    return lo if lo == hi else f"{lo} to {hi}"
