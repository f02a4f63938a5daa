"""The final report: one self-contained HTML page (images embedded, no external files).

For each wall: target, verified render (point light) and LED-size blur render side by
side with their figures; then every key figure from the pipeline; then free sections
(checks, next steps).  Opens offline in any browser; write it with ``write_report``.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
from pathlib import Path

from .artifacts import write_text
from .errors import LampfabError

_MIME = ((b"\x89PNG\r\n\x1a\n", "image/png"), (b"\xff\xd8\xff", "image/jpeg"), (b"GIF8", "image/gif"))

# Wall dict keys with a fixed place on the page; any other scalar key is listed too.
_IMAGE_KEYS = ("target_png", "render_png", "blur_png")
_KNOWN = {"name", *_IMAGE_KEYS, "pearson", "ssim", "share", "ghost_share", "direct_ssim",
          "blur_pearson", "blur_ssim", "blur_share"}

_CSS = """
:root { color-scheme: dark; }
* { box-sizing: border-box; }
body { margin: 0; background: #0d0f12; color: #d8dce3;
  font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, Helvetica, Arial, sans-serif; }
main { max-width: 1280px; margin: 0 auto; padding: 32px 24px 64px; }
h1 { font-size: 28px; font-weight: 600; margin: 0 0 4px; color: #fff; letter-spacing: .01em; }
h2 { font-size: 20px; font-weight: 600; margin: 40px 0 12px; color: #fff;
  border-bottom: 1px solid #262b33; padding-bottom: 6px; }
h3 { font-size: 17px; font-weight: 600; margin: 0 0 12px; color: #f3d98b; text-transform: capitalize; }
.sub { color: #8a93a1; margin: 0 0 24px; }
.wall { background: #15181d; border: 1px solid #232830; border-radius: 10px;
  padding: 18px; margin: 0 0 22px; }
.row { display: grid; grid-template-columns: repeat(auto-fit, minmax(260px, 1fr)); gap: 16px; }
figure { margin: 0; }
figure img { display: block; width: 100%; height: auto; background: #000;
  border: 1px solid #2a2f38; border-radius: 6px; }
.missing { display: flex; align-items: center; justify-content: center; aspect-ratio: 4 / 3;
  background: #000; border: 1px dashed #3a404b; border-radius: 6px; color: #6b7380; }
figcaption { margin-top: 8px; font-size: 13px; color: #aab2bf; }
figcaption b { display: block; color: #e6e9ee; font-size: 14px; margin-bottom: 2px; }
.figs { display: flex; flex-wrap: wrap; gap: 4px 14px; }
.figs span { white-space: nowrap; }
.figs em { font-style: normal; color: #f3d98b; font-variant-numeric: tabular-nums; }
.extra { margin-top: 12px; font-size: 13px; color: #8a93a1; }
table { border-collapse: collapse; width: 100%; font-size: 14px; margin-bottom: 18px; }
th, td { text-align: left; padding: 5px 10px; border-bottom: 1px solid #232830; vertical-align: top; }
th { color: #8a93a1; font-weight: 500; width: 40%; }
td { font-variant-numeric: tabular-nums; color: #e6e9ee; word-break: break-word; }
tr.group th { color: #f3d98b; font-weight: 600; padding-top: 16px; text-transform: capitalize; }
section.free { background: #15181d; border: 1px solid #232830; border-radius: 10px;
  padding: 4px 18px 14px; margin: 0 0 18px; }
section.free h2 { border: 0; margin-top: 14px; }
code, pre { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; font-size: 13px; }
pre { background: #0a0c0f; padding: 10px; border-radius: 6px; overflow-x: auto; }
a { color: #8fc1ff; }
.ok { color: #7bd88f; } .fail { color: #ff7b72; } .warn { color: #f3d98b; }
footer { margin-top: 40px; color: #5d6470; font-size: 12px; }
"""


def write_report(path: str | os.PathLike, title: str, walls: list[dict], figures: dict,
                 sections: list[tuple[str, str]] = (), first: list[tuple[str, str]] = ()) -> None:
    """Write the HTML report to ``path`` atomically.

    ``walls``: one dict per wall with "name", "target_png", "render_png", "blur_png"
    (paths; None or absent shows a placeholder) and figures "pearson", "ssim", "share"
    (of the point-light render) and optionally "blur_pearson", "blur_ssim",
    "blur_share"; any other scalar key is listed under the wall.
    ``figures``: {group: {name: value}} (e.g. one group per stage), shown as a table.
    ``sections``: (title, html) pairs; the title is escaped, the HTML is inserted as
    is (it comes from lampfab itself, never from the user; ``figure_html`` makes its
    pictures).  ``first``: sections of the same kind shown above the walls.
    An image path that does not exist raises ``LampfabError``.
    """
    from . import __version__

    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head><body><main>",
        f"<h1>{_e(title)}</h1>",
        '<p class="sub">Target, simulated projection with a point light, and the same '
        "with the LED's real size (blur). Pearson r and SSIM compare each render with "
        "its target after normalizing brightness; share is the fraction of the LED's "
        "light that lands on the wall's image.</p>",
    ]
    parts.extend(_section(t, snippet) for t, snippet in first)
    if walls:
        parts.append("<h2>Walls</h2>")
    for wall in walls:
        parts.append(_wall_html(wall))
    if figures:
        parts.append("<h2>Key figures</h2>")
        parts.append(_figures_html(figures))
    parts.extend(_section(t, snippet) for t, snippet in sections)
    parts.append(f"<footer>Made by lampfab {_e(__version__)}.</footer>")
    parts.append("</main></body></html>\n")

    write_text(path, "\n".join(parts))


def _section(title: str, snippet: str) -> str:
    return f'<section class="free"><h2>{_e(title)}</h2>{snippet}</section>'


def figure_html(label: str, path, caption: str = "") -> str:
    """One embedded picture (PNG, JPEG or GIF) with its label and an escaped caption."""
    return _figure(label, path, [], f'<span class="note">{_e(caption)}</span>' if caption else "")


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


def _fmt(value) -> str:
    """A figure as text: floats to 4 significant digits, containers as compact JSON."""
    if isinstance(value, bool) or value is None:
        return {True: "yes", False: "no", None: "—"}[value]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:  # numpy scalar
        value = value.item()
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value) or math.isinf(value):
            return str(value)
        if value != 0 and (abs(value) >= 1e6 or abs(value) < 1e-3):
            return f"{value:.3e}"
        return f"{value:.4g}"
    if isinstance(value, (dict, list, tuple)) or hasattr(value, "tolist"):
        if hasattr(value, "tolist"):
            value = value.tolist()
        return json.dumps(value, default=str, separators=(", ", ": "))
    return str(value)


def _num(value, digits: int = 3) -> str:
    if value is None:
        return "—"
    try:
        return f"{float(value):.{digits}f}"
    except (TypeError, ValueError):
        return _e(value)


def _pct(value) -> str:
    if value is None:
        return "—"
    try:
        return f"{100 * float(value):.1f} %"
    except (TypeError, ValueError):
        return _e(value)


def _figure(label: str, path, caption_figs: list[tuple[str, str]], note: str = "") -> str:
    if path:
        img = f'<img src="{_data_uri(path)}" alt="{_e(label)}">'
    else:
        img = '<div class="missing">not available</div>'
    figs = "".join(f"<span>{_e(k)} <em>{v}</em></span>" for k, v in caption_figs)
    figs_html = f'<div class="figs">{figs}</div>' if figs else ""
    return f"<figure>{img}<figcaption><b>{_e(label)}</b>{figs_html}{note}</figcaption></figure>"


def _wall_html(wall: dict) -> str:
    name = wall.get("name", "wall")
    render_figs = [("Pearson r", _num(wall.get("pearson"))), ("SSIM", _num(wall.get("ssim"))),
                   ("share of light", _pct(wall.get("share")))]
    render_figs += [(label, fmt(wall[key])) for label, key, fmt in
                    (("reflected (ghosts)", "ghost_share", _pct), ("SSIM without ghosts", "direct_ssim", _num))
                    if key in wall]
    blur_figs = [(label, fmt(wall[key])) for label, key, fmt in
                 (("Pearson r", "blur_pearson", _num), ("SSIM", "blur_ssim", _num),
                  ("share of light", "blur_share", _pct)) if key in wall]
    row = [
        _figure("Target", wall.get("target_png"), []),
        _figure("Render (point light)", wall.get("render_png"), render_figs),
        _figure("Render (LED size)", wall.get("blur_png"), blur_figs),
    ]
    extra = [(k, v) for k, v in wall.items() if k not in _KNOWN]
    extra_html = ""
    if extra:
        items = " · ".join(f"{_e(k)}: <em>{_e(_fmt(v))}</em>" for k, v in extra)
        extra_html = f'<div class="extra figs">{items}</div>'
    return (f'<section class="wall"><h3>{_e(name)}</h3><div class="row">{"".join(row)}</div>'
            f"{extra_html}</section>")


def _figures_html(figures: dict) -> str:
    rows = []
    for group, values in figures.items():
        if isinstance(values, dict):
            rows.append(f'<tr class="group"><th colspan="2">{_e(group)}</th></tr>')
            rows.extend(f"<tr><th>{_e(k)}</th><td>{_e(_fmt(v))}</td></tr>" for k, v in values.items())
        else:
            rows.append(f"<tr><th>{_e(group)}</th><td>{_e(_fmt(values))}</td></tr>")
    return f"<table>{''.join(rows)}</table>"
