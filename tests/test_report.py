"""lampfab.report: one self-contained HTML page with every image embedded."""

from __future__ import annotations

import base64
import io
import os
import re

import numpy as np
import pytest
from PIL import Image

from lampfab.artifacts import write_png
from lampfab.errors import LampfabError
from lampfab.report import Picture, span, write_report


@pytest.fixture
def pictures(tmp_path):
    rng = np.random.default_rng(5)
    paths = {}
    for name in ("room", "front target", "front led", "floor target"):
        paths[name] = tmp_path / f"{name}.png"
        write_png(paths[name], rng.random((24, 32)))
    return paths


def _page(pictures, **kw):
    walls = [("front", [Picture("Target", pictures["front target"]),
                        Picture("With the LED", pictures["front led"], [("r", "0.912"), ("SSIM", "0.846")])]),
             ("floor", [Picture("Target", pictures["floor target"]), Picture("With the LED", None)])]
    return {"verdict": "Projects your picture well", "hero": Picture("The lamp in its room", pictures["room"],
                                                                     note="a room"),
            "facts": [("Sharpness", "details under ~80 mm")], "walls": walls,
            "groups": {"Light": [("Light on each picture", "18.5 %")], "Empty": []}, **kw}


def _data_uris(text):
    return re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)


def test_report_self_contained_in_the_order_a_maker_reads(tmp_path, pictures):
    out = tmp_path / "out dir ü" / "report.html"
    page = _page(pictures)
    sections = [("Checks", "<ul><li class='ok'>wall thickness ≥ 2 mm</li></ul>"),
                ("Next steps", "<p>Send <code>lamp.step</code> to the shop.</p>")]
    write_report(out, "Lamp for <apple> & co", page.pop("verdict"), sections=sections, **page)

    text = out.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    uris = _data_uris(text)
    assert len(uris) == 4 == text.count("<img ")  # one per image, all embedded; the missing one a placeholder
    assert "not available" in text
    for uri in uris:
        with Image.open(io.BytesIO(base64.b64decode(uri))) as im:
            assert im.format == "PNG" and im.size == (32, 24)
    # Nothing fetched from outside: no links to files, stylesheets or scripts.
    assert "<script" not in text and "<link" not in text
    assert not re.search(r'(src|href)="(?!data:)', text)
    assert "url(" not in text
    # The first screen: verdict, the room, the facts; then the walls, the figures, the sections.
    order = [text.index(s) for s in ("Projects your picture well", "The lamp in its room", "details under ~80 mm",
                                     "0.912", "Light on each picture", "Checks", "Next steps")]
    assert order == sorted(order)
    assert "Empty" not in text  # a group without figures is left out
    # Title escaped, sections' HTML inserted as is.
    assert "Lamp for &lt;apple&gt; &amp; co" in text and "<apple>" not in text
    assert "<li class='ok'>wall thickness ≥ 2 mm</li>" in text and "<code>lamp.step</code>" in text
    # Written atomically: no temporary files left beside it, and readable as any new
    # file of this user is (not the temporary file's private 0600).
    assert [p.name for p in out.parent.iterdir()] == ["report.html"]
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


def test_missing_image_file_is_a_user_error(tmp_path, pictures):
    page = _page(pictures)
    page["hero"] = Picture("room", tmp_path / "never rendered.png")
    out = tmp_path / "r.html"
    with pytest.raises(LampfabError, match="never rendered.png"):
        write_report(out, "t", page.pop("verdict"), **page)
    assert not out.exists()
    assert list(tmp_path.glob(".r.html*")) == []


def test_every_text_is_escaped(tmp_path, pictures):
    page = _page(pictures, verdict="a < b")
    page["walls"][0] = ("<b>front</b>", [Picture("x<y", None, [("1 & 2", "<3")])])
    page["groups"] = {"<stage>": [("x<y", "1 & 2")]}
    out = tmp_path / "r.html"
    write_report(out, "t", page.pop("verdict"), **page)
    text = out.read_text(encoding="utf-8")
    for s in ("a &lt; b", "&lt;b&gt;front&lt;/b&gt;", "x&lt;y", "1 &amp; 2", "&lt;3", "&lt;stage&gt;"):
        assert s in text, s


def test_a_figure_over_walls_reads_as_one_value_or_a_range():
    assert span([0.6123, 0.6119]) == "0.612"
    assert span([0.61, None, 0.67]) == "0.610 to 0.670"
    assert span([None]) == "—"
