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
from lampfab.report import write_report


def _images(folder, name, rng):
    paths = {}
    for kind in ("target", "render", "blur"):
        p = folder / f"{name} {kind}.png"
        write_png(p, rng.random((24, 32)))
        paths[f"{kind}_png"] = p
    return paths


@pytest.fixture
def walls(tmp_path):
    rng = np.random.default_rng(5)
    return [
        {"name": "front", **_images(tmp_path, "front", rng), "pearson": 0.9123, "ssim": 0.8456,
         "share": 0.6234, "blur_pearson": 0.8011, "blur_ssim": 0.7022, "blur_share": 0.6101,
         "target_px": [192, 256]},
        {"name": "floor", **_images(tmp_path, "floor", rng), "pearson": 0.7777, "ssim": 0.6666,
         "share": 0.2},
    ]


def _data_uris(text):
    return re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)


def test_report_self_contained(tmp_path, walls):
    out = tmp_path / "out dir ü" / "report.html"
    figures = {"optimize": {"iterations": 400, "loss": 1.234e-5, "converged": True},
               "export": {"volume_mm3": 123456.789, "bbox_mm": [120.0, 120.0, 80.5]}}
    sections = [("Checks", "<ul><li class='ok'>wall thickness ≥ 2 mm</li></ul>"),
                ("Next steps", "<p>Send <code>lamp.step</code> to the shop.</p>")]
    write_report(out, "Lamp for <apple> & co", walls, figures, sections)

    text = out.read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    uris = _data_uris(text)
    assert len(uris) == 6 == text.count("<img ")  # one per image, all embedded
    for uri in uris:
        with Image.open(io.BytesIO(base64.b64decode(uri))) as im:
            assert im.format == "PNG" and im.size == (32, 24)
    # Nothing fetched from outside: no links to files, stylesheets or scripts.
    assert "<script" not in text and "<link" not in text
    assert not re.search(r'(src|href)="(?!data:)', text)
    assert "url(" not in text
    # Figures under the images and in the table.
    for s in ("0.912", "0.846", "62.3 %", "0.801", "0.702", "61.0 %", "0.778", "0.667", "20.0 %"):
        assert s in text, s
    assert "target_px" in text and "[192, 256]" in text
    for s in ("optimize", "iterations", "400", "1.234e-05", "yes", "volume_mm3", "1.235e+05",
              "[120.0, 120.0, 80.5]"):
        assert s in text, s
    # Title escaped, sections' HTML inserted as is.
    assert "Lamp for &lt;apple&gt; &amp; co" in text and "<apple>" not in text
    assert "<li class='ok'>wall thickness ≥ 2 mm</li>" in text
    assert "<code>lamp.step</code>" in text
    assert text.index("Checks") < text.index("Next steps")
    # Written atomically: no temporary files left beside it, and readable as any new
    # file of this user is (not the temporary file's private 0600).
    assert [p.name for p in out.parent.iterdir()] == ["report.html"]
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask


def test_missing_blur_shows_placeholder(tmp_path, walls):
    walls[1]["blur_png"] = None
    out = tmp_path / "r.html"
    write_report(out, "t", walls, {})
    text = out.read_text(encoding="utf-8")
    assert len(_data_uris(text)) == 5
    assert "not available" in text


def test_missing_image_file_is_a_user_error(tmp_path, walls):
    walls[0]["render_png"] = tmp_path / "never rendered.png"
    out = tmp_path / "r.html"
    with pytest.raises(LampfabError, match="never rendered.png"):
        write_report(out, "t", walls, {})
    assert not out.exists()
    assert list(tmp_path.glob(".r.html*")) == []


def test_names_and_figure_keys_are_escaped(tmp_path, walls):
    walls[0]["name"] = "<b>front</b>"
    walls[0]["note"] = "a < b"
    out = tmp_path / "r.html"
    write_report(out, "t", walls, {"<stage>": {"x<y": "1 & 2"}})
    text = out.read_text(encoding="utf-8")
    assert "&lt;b&gt;front&lt;/b&gt;" in text and "a &lt; b" in text
    assert "&lt;stage&gt;" in text and "x&lt;y" in text and "1 &amp; 2" in text
