"""lampfab.image: every accepted input decodes to the right luminance; every bad input
is refused with a one-line LampfabError naming the file."""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from lampfab.errors import LampfabError
from lampfab.image import MAX_PIXELS, REC709, _luminance, letterbox, load_target, srgb_to_linear


def _lin(v8):
    return srgb_to_linear(np.asarray(v8, dtype=np.float64) / 255.0)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def _save(im: Image.Image, path, **kw):
    im.save(path, **kw)
    return path


# ---------------------------------------------------------------- accepted inputs


def test_srgb_curve_endpoints_and_midpoint():
    assert srgb_to_linear(0.0) == 0.0
    assert srgb_to_linear(1.0) == pytest.approx(1.0)
    assert srgb_to_linear(0.5) == pytest.approx(0.21404, abs=1e-5)


def test_grey_png(tmp_path, rng):
    data = rng.integers(0, 256, (12, 17), dtype=np.uint8)
    path = _save(Image.fromarray(data), tmp_path / "grey.png")
    lum = load_target(path)
    assert lum.shape == (12, 17) and lum.dtype == np.float64
    np.testing.assert_allclose(lum, _lin(data), atol=1e-12)
    assert lum.min() >= 0.0 and lum.max() <= 1.0


def test_rgb_png_uses_rec709_in_linear_light(tmp_path, rng):
    data = rng.integers(0, 256, (9, 11, 3), dtype=np.uint8)
    data[0, 0] = (255, 0, 0)
    data[0, 1] = (0, 255, 0)
    data[0, 2] = (0, 0, 255)
    data[0, 3] = (0, 0, 0)
    path = _save(Image.fromarray(data), tmp_path / "rgb.png")
    lum = load_target(path)
    np.testing.assert_allclose(lum, _lin(data) @ REC709, atol=1e-12)
    np.testing.assert_allclose(lum[0, :3], [0.2126, 0.7152, 0.0722], atol=1e-12)


def test_rgba_composited_over_black(tmp_path):
    data = np.zeros((4, 6, 4), dtype=np.uint8)
    data[..., :3] = 255
    data[..., 3] = np.array([0, 64, 128, 192, 255, 255], dtype=np.uint8)
    data[1, :, :3] = (200, 100, 50)
    path = _save(Image.fromarray(data), tmp_path / "rgba.png")
    lum = load_target(path)
    alpha = data[..., 3] / 255.0
    np.testing.assert_allclose(lum, (_lin(data[..., :3]) @ REC709) * alpha, atol=1e-12)
    assert lum[0, 0] == 0.0  # fully transparent: no light, whatever the colour


def test_la_png(tmp_path):
    grey = np.full((3, 4), 255, dtype=np.uint8)
    grey[0, 0] = 10
    alpha = np.array([[255, 128, 0, 255]] * 3, dtype=np.uint8)
    im = Image.merge("LA", (Image.fromarray(grey), Image.fromarray(alpha)))
    lum = load_target(_save(im, tmp_path / "la.png"))
    np.testing.assert_allclose(lum, _lin(grey) * alpha / 255.0, atol=1e-12)


def test_palette_png_with_transparent_entry(tmp_path):
    idx = np.array([[0, 1, 2, 3], [3, 2, 1, 0]], dtype=np.uint8)
    palette = [0, 0, 0, 255, 255, 255, 255, 0, 0, 30, 60, 90]
    im = Image.frombytes("P", (4, 2), idx.tobytes())
    im.putpalette(palette)
    path = _save(im, tmp_path / "pal.png", transparency=1)  # white entry is transparent
    with Image.open(path) as check:
        assert check.mode == "P" and check.info.get("transparency") == 1
    lum = load_target(path)
    colours = np.array(palette, dtype=np.uint8).reshape(-1, 3)
    expect = _lin(colours[idx]) @ REC709
    expect[idx == 1] = 0.0
    np.testing.assert_allclose(lum, expect, atol=1e-12)


def test_palette_png_without_transparency(tmp_path):
    rgb = np.zeros((5, 5, 3), dtype=np.uint8)
    rgb[1:4, 1:4] = (255, 255, 255)
    im = Image.fromarray(rgb).convert("P", palette=Image.Palette.ADAPTIVE, colors=4)
    lum = load_target(_save(im, tmp_path / "pal2.png"))
    expect = np.zeros((5, 5))
    expect[1:4, 1:4] = 1.0
    np.testing.assert_allclose(lum, expect, atol=1e-12)


def test_grey_png_with_transparent_level(tmp_path):
    data = np.array([[10, 200, 255]], dtype=np.uint8)
    lum = load_target(_save(Image.fromarray(data), tmp_path / "trns.png", transparency=200))
    np.testing.assert_allclose(lum, [[_lin(10), 0.0, 1.0]], atol=1e-12)


def test_16bit_png_keeps_precision(tmp_path):
    data = np.linspace(0, 65535, 5 * 64).round().astype(np.uint16).reshape(5, 64)
    path = _save(Image.fromarray(data), tmp_path / "deep.png")
    with Image.open(path) as check:
        assert check.mode.startswith("I;16")
    lum = load_target(path)
    np.testing.assert_allclose(lum, srgb_to_linear(data / 65535.0), atol=1e-12)
    assert len(np.unique(lum)) == data.size  # more than 256 levels survive


def test_mode_i_and_f_images():
    i = Image.fromarray(np.array([[0, 32768, 65535, 70000, -5]], dtype=np.int32))
    assert i.mode == "I"
    np.testing.assert_allclose(_luminance(i), srgb_to_linear(np.array([[0, 32768, 65535, 65535, 0]]) / 65535.0))
    f = Image.fromarray(np.array([[0.0, 0.5, 1.0, 1.5, np.nan]], dtype=np.float32))
    assert f.mode == "F"
    np.testing.assert_allclose(_luminance(f), [[0.0, srgb_to_linear(0.5), 1.0, 1.0, 0.0]], atol=1e-7)


def test_bilevel_png(tmp_path):
    im = Image.new("1", (6, 3), 0)
    im.putpixel((2, 1), 1)
    lum = load_target(_save(im, tmp_path / "bw.png"))
    expect = np.zeros((3, 6))
    expect[1, 2] = 1.0
    np.testing.assert_array_equal(lum, expect)


def test_jpeg_grey_and_cmyk(tmp_path):
    data = np.zeros((32, 48), dtype=np.uint8)
    data[8:24, 8:40] = 255
    lum = load_target(_save(Image.fromarray(data), tmp_path / "photo.jpg", quality=95))
    assert lum.shape == (32, 48)
    assert np.abs(lum - _lin(data)).mean() < 0.02
    cmyk = Image.new("CMYK", (16, 16), (0, 0, 0, 255))  # black ink
    cmyk.paste((0, 0, 0, 0), (0, 0, 8, 16))  # no ink: white
    lum = load_target(_save(cmyk, tmp_path / "print.jpeg", quality=95))
    assert lum[:, :6].mean() > 0.9 and lum[:, 10:].mean() < 0.05


def test_exif_orientation_honoured(tmp_path):
    # Stored 40 wide x 20 high, bright block at the stored top-left; Orientation 6
    # means "rotate 90 degrees clockwise to view": shown 20 wide x 40 high, block top-right.
    data = np.zeros((20, 40), dtype=np.uint8)
    data[:10, :10] = 255
    im = Image.fromarray(data)
    exif = Image.Exif()
    exif[0x0112] = 6
    path = _save(im, tmp_path / "phone.jpg", exif=exif.tobytes(), quality=95)
    lum = load_target(path)
    assert lum.shape == (40, 20)
    expect = np.rot90(_lin(data), k=-1)
    assert np.abs(lum - expect).mean() < 0.02
    assert lum[:10, 10:].mean() > 0.8 and lum[:10, :10].mean() < 0.05


def test_unicode_and_spaces_in_path(tmp_path):
    folder = tmp_path / "my pictures é ☀"
    folder.mkdir()
    data = np.zeros((8, 8), dtype=np.uint8)
    data[2:6, 2:6] = 255
    path = _save(Image.fromarray(data), folder / "äpfel und birnen 🍎.png")
    lum = load_target(path)
    assert lum.sum() == pytest.approx(16.0)
    lum2 = load_target(str(path))
    np.testing.assert_array_equal(lum, lum2)


def test_bundled_examples_load():
    from pathlib import Path

    examples = Path(__file__).resolve().parents[1] / "examples"
    for name, shape in (("apple", (512, 512)), ("star", (512, 512)), ("portrait", (384, 512))):
        lum = load_target(examples / f"{name}.png")
        assert lum.shape == shape
        assert lum.max() - lum.min() > 0.5


# ---------------------------------------------------------------- refused inputs


def _refused(path, *words):
    with pytest.raises(LampfabError) as info:
        load_target(path)
    msg = str(info.value)
    assert str(path) in msg, msg
    assert "\n" not in msg, msg
    for w in words:
        assert w.lower() in msg.lower(), msg
    return msg


def test_missing_file(tmp_path):
    _refused(tmp_path / "nothing here.png", "not found", "PNG or JPEG")


def test_folder_instead_of_file(tmp_path):
    _refused(tmp_path, "folder")


def test_empty_file(tmp_path):
    path = tmp_path / "empty.png"
    path.write_bytes(b"")
    _refused(path, "empty", "PNG or JPEG")


def test_truncated_png(tmp_path, rng):
    buf = io.BytesIO()
    Image.fromarray(rng.integers(0, 256, (64, 64), dtype=np.uint8)).save(buf, format="PNG")
    path = tmp_path / "cut.png"
    path.write_bytes(buf.getvalue()[: len(buf.getvalue()) // 2])
    _refused(path, "truncated or corrupt", "PNG or JPEG")


def test_truncated_jpeg(tmp_path, rng):
    buf = io.BytesIO()
    Image.fromarray(rng.integers(0, 256, (64, 64, 3), dtype=np.uint8)).save(buf, format="JPEG")
    path = tmp_path / "cut.jpg"
    path.write_bytes(buf.getvalue()[: len(buf.getvalue()) // 2])
    _refused(path, "truncated or corrupt")


def test_text_file_named_png(tmp_path):
    path = tmp_path / "notes.png"
    path.write_text("this is not a picture\n")
    _refused(path, "not an image", "PNG or JPEG")


def test_unsupported_format(tmp_path):
    data = np.zeros((8, 8), dtype=np.uint8)
    data[:4] = 255
    path = _save(Image.fromarray(data), tmp_path / "anim.gif")
    _refused(path, "GIF", "convert it to PNG")
    path = _save(Image.fromarray(data), tmp_path / "disguised.png", format="BMP")
    _refused(path, "BMP")


def _bilevel_png_bytes(width: int, height: int) -> bytes:
    """A valid all-black 1-bit PNG, built without allocating its pixels."""
    def chunk(kind, payload):
        return (struct.pack(">I", len(payload)) + kind + payload
                + struct.pack(">I", zlib.crc32(kind + payload) & 0xFFFFFFFF))
    row = b"\x00" + bytes((width + 7) // 8)
    comp = zlib.compressobj(9)
    idat = b"".join(comp.compress(row) for _ in range(height)) + comp.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat)
            + chunk(b"IEND", b""))


@pytest.mark.parametrize("side", [7200, 12000])  # 52 MP (Pillow warns), 144 MP (Pillow refuses)
def test_too_large(tmp_path, side):
    assert side * side > MAX_PIXELS
    path = tmp_path / f"huge {side}.png"
    path.write_bytes(_bilevel_png_bytes(side, side))
    msg = _refused(path, "too large", "megapixels")
    assert str(MAX_PIXELS // 1_000_000) in msg


def test_large_but_allowed_size_is_not_refused_for_size(tmp_path):
    # 2000 x 1500 = 3 MP all black: refused only because it is constant.
    path = tmp_path / "big black.png"
    path.write_bytes(_bilevel_png_bytes(2000, 1500))
    _refused(path, "uniform", "nothing to project")


def test_constant_image(tmp_path):
    path = _save(Image.new("RGB", (20, 10), (120, 120, 120)), tmp_path / "grey card.png")
    _refused(path, "uniform", "nothing to project")


def test_fully_transparent_image_is_constant(tmp_path):
    data = np.zeros((6, 6, 4), dtype=np.uint8)
    data[..., :3] = np.arange(6, dtype=np.uint8)[:, None, None] * 40
    path = _save(Image.fromarray(data), tmp_path / "ghost.png")
    _refused(path, "uniform")


# ---------------------------------------------------------------- letterbox


def test_letterbox_wide_image_into_square():
    img = np.ones((50, 100))
    out = letterbox(img, 100, 100)
    assert out.shape == (100, 100)
    np.testing.assert_allclose(out[25:75], 1.0)
    assert (out[:25] == 0).all() and (out[75:] == 0).all()


def test_letterbox_tall_image_downscaled_keeps_aspect(rng):
    img = np.zeros((400, 200))
    img[:, :] = 0.5
    out = letterbox(img, 60, 120)
    cols = np.nonzero(out.any(axis=0))[0]
    rows = np.nonzero(out.any(axis=1))[0]
    assert len(rows) == 60 and len(cols) == 30  # 2:1 kept
    assert cols[0] == 45 and cols[-1] == 74  # centred
    np.testing.assert_allclose(out[:, 45:75], 0.5, atol=1e-6)
    assert (out[:, :45] == 0).all() and (out[:, 75:] == 0).all()


def test_letterbox_area_average_and_range(rng):
    img = rng.random((64, 96))
    out = letterbox(img, 32, 48)  # exact factor 2: each pixel is a 2x2 block average
    expect = img.reshape(32, 2, 48, 2).mean(axis=(1, 3))
    np.testing.assert_allclose(out, expect, atol=1e-6)
    for shape in ((17, 23), (200, 90), (5, 300)):
        out = letterbox(img, *shape)
        assert out.shape == shape
        assert out.min() >= 0.0 and out.max() <= 1.0


def test_letterbox_upscale_stays_in_range(rng):
    img = (rng.random((7, 5)) > 0.5).astype(float)
    out = letterbox(img, 70, 70)
    assert out.min() >= 0.0 and out.max() <= 1.0
    assert (out[:, :10] == 0).all() and (out[:, 60:] == 0).all()
    assert out.dtype == np.float64


def test_letterbox_same_size_is_identity(rng):
    img = rng.random((10, 20))
    np.testing.assert_array_equal(letterbox(img, 10, 20), img)


def test_letterbox_rejects_bad_input():
    with pytest.raises(ValueError):
        letterbox(np.ones((3, 3, 3)), 4, 4)
    with pytest.raises(ValueError):
        letterbox(np.ones((3, 3)), 0, 4)
