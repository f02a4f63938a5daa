"""The maker's view: text and panorama targets, the report in a real browser, the
summary, the optimization GIF, lens.glb for Blender and a GLB inner layer."""

from __future__ import annotations

import base64
import io
import json
import re
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

from lampfab import inner, profile, room, targets
from lampfab.errors import LampfabError
from lampfab.pipeline.build import Build

from tests.helpers import ROOT, TINY_LED, cli, make


# -- text ---------------------------------------------------------------------------
def _lit_box(img, level=0.5):
    rows, cols = np.nonzero(img > level)
    return rows.min(), rows.max(), cols.min(), cols.max()


def test_text_fills_the_wall_inside_its_margin():
    img = targets.text_image("Happy birthday", 96, 128)
    assert img.shape == (96, 128) and img.min() >= 0 and img.max() == pytest.approx(1.0)
    r0, r1, c0, c1 = _lit_box(img)
    margin = targets.TEXT_MARGIN
    assert c0 >= margin * 128 - 1 and c1 <= (1 - margin) * 128
    assert r0 >= margin * 96 - 1 and r1 <= (1 - margin) * 96
    # Two words on a 4:3 wall: two lines make larger letters than one, so the text is
    # as wide as the margin allows and tall.
    assert (c1 - c0) > 0.75 * 128 and (r1 - r0) > 0.4 * 96 and 0.05 < (img > 0.5).mean() < 0.5


def test_text_keeps_given_lines_and_refuses_nothing_or_too_much():
    one = targets.text_image("ab cd", 60, 200)
    two = targets.text_image("ab\ncd", 60, 200)
    assert _lit_box(two)[1] - _lit_box(two)[0] > _lit_box(one)[1] - _lit_box(one)[0]
    for bad in ("", "   \n ", "x" * 500):
        with pytest.raises(LampfabError, match="TEXT"):
            targets.text_image(bad, 60, 80)
    with pytest.raises(LampfabError, match="cannot draw: 你 好"):
        targets.text_image("Hello 你好", 60, 80)
    assert targets.text_image("Joyeux anniversaire Léa 😀", 60, 80).max() > 0.5    # DejaVu has both


@pytest.mark.parametrize("phrase", ["Sleep well my darling", "Make today a good day", "Keep calm and carry on",
                                    "Dream big little star", "Hi"])
def test_text_takes_the_line_breaks_that_make_large_letters_and_a_narrow_picture(phrase):
    """Of every way of breaking the words into lines (by brute force over the cuts), the
    layout's letters are the largest, or within ``LAYOUT_EM_TOLERANCE`` of them on the
    narrowest picture when that is an eighth of the width narrower; breaking lines by
    their count of characters set "Sleep well my darling" one word a line with letters a
    sixth smaller.  "Dream big little star" goes on four lines, not on three with its
    middle line edge to edge; "Keep calm and carry on" stays on three, four lines would
    be narrower by less than an eighth."""
    import itertools

    rows, cols = 48, 64
    em, layout = targets.text_layout(phrase, rows, cols)
    assert layout.split() == phrase.split()
    words = phrase.split()
    every = []
    for k in range(len(words)):
        for cuts in itertools.combinations(range(1, len(words)), k):
            bounds = (0, *cuts, len(words))
            lines = "\n".join(" ".join(words[a:b]) for a, b in zip(bounds, bounds[1:]))
            every.append((targets.text_layout(lines, rows, cols)[0], _ink_width(targets.text_image(lines, rows, cols))))
    largest_em, largest_width = max(every, key=lambda c: (c[0], -c[1]))
    narrowest = min(w for e, w in every if e >= (1 - targets.LAYOUT_EM_TOLERANCE) * largest_em)
    width = _ink_width(targets.text_image(phrase, rows, cols))
    gain = largest_width - narrowest  # in whole pixels: a pixel either way at the threshold
    if gain >= targets.LAYOUT_NARROWER_SHARE * cols + 1:
        assert width <= narrowest + 1 and em >= (1 - targets.LAYOUT_EM_TOLERANCE) * largest_em
    elif gain <= targets.LAYOUT_NARROWER_SHARE * cols - 1:
        assert em == pytest.approx(largest_em)
    if phrase == "Sleep well my darling":
        assert layout == "Sleep\nwell my\ndarling" and em > 1.15 * targets.text_layout("Sleep\nwell\nmy\ndarling",
                                                                                          rows, cols)[0]
    if phrase == "Dream big little star":
        assert layout == "Dream\nbig\nlittle\nstar"
        assert width < 0.8 * _ink_width(targets.text_image("Dream\nbig little\nstar", rows, cols))
    if phrase == "Keep calm and carry on":
        assert layout == "Keep\ncalm and\ncarry on"


def _ink_width(image) -> int:
    _, _, first, last = _lit_box(image)
    return int(last - first + 1)


def test_a_line_break_typed_into_make_s_text_breaks_the_line(tmp_path, tiny_profile):
    """Make cannot hand a real line break from TEXT= to its recipes: "\\n" typed there is one."""
    run = make("prepare", f"BUILD={tmp_path}", "NAME=lines", r"TEXT=Good\nnight", f"PROFILE={tiny_profile}")
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    prepared = json.loads((tmp_path / "lines" / "prepare.json").read_text())["figures"]
    assert prepared["front_source"] == "text: Good\nnight"
    summary = cli("summary", "--out", tmp_path / "lines", "--profile", tiny_profile).stdout
    assert "text: Good / night on front" in summary.splitlines()[0], summary
    assert cli("prepare", "--help").stdout.count("\\n") >= 1
    assert r"a typed \n breaks a line" in make("help").stdout


def _verified(tmp_path, design: str, ssim_over_ceiling: list[float]) -> Build:
    """A build folder holding only a verify report whose walls reach those shares of
    their LED ceiling."""
    walls = {name: {"led_pearson": 0.98, "led_ssim": 0.9 * share, "led_ssim_ceiling": 0.9}
             for name, share in zip(("front", "left", "right"), ssim_over_ceiling)}
    (tmp_path / "verify.json").write_text(json.dumps({"wall_time_s": 60.0,
                                                       "figures": {"walls": walls, "real_light": "LED"}}))
    return Build.open(tmp_path, design, "sla_resin")


def test_the_summary_names_the_longer_refinement_only_where_it_can_help(tmp_path, capsys):
    from lampfab.pipeline.summary import summary

    fine = profile.load_design("fine").optimize.iterations
    summary(_verified(tmp_path, "default", [0.95, 0.86, 0.92]))
    hint = capsys.readouterr().out.strip().splitlines()[-1]
    assert "PROFILE=fine" in hint and f"{fine} steps instead of 56" in hint and "0.860 to 0.950" in hint
    # A floor, 128 px walls or a profile already as long would not gain from it.
    for design, shares in (("default", [0.95, 0.91, 0.90]), ("fine", [0.95, 0.86, 0.92]),
                           ("floor", [0.95, 0.86, 0.92]), ("hires", [0.95, 0.86, 0.92])):
        summary(_verified(tmp_path, design, shares))
        assert "PROFILE=fine" not in capsys.readouterr().out, design
    longer = tmp_path / "longer.toml"
    longer.write_text(f'base = "default"\n[optimize]\niterations = {fine + 76}\n')
    summary(_verified(tmp_path, str(longer), [0.95, 0.86, 0.92]))
    assert "PROFILE=fine" not in capsys.readouterr().out


def test_text_lines_hold_each_line_and_only_its_neighbours_margin():
    """Each band of ``text_lines`` holds all of its line's ink: a wall's lines, read one
    by one, show every word whole."""
    rows, cols = 48, 64
    img = targets.text_image("Dream big little star", rows, cols)
    bands = targets.text_lines("Dream big little star", rows, cols)
    assert len(bands) == targets.text_layout("Dream big little star", rows, cols)[1].count("\n") + 1 == 4
    assert bands[0][0] == 0 and bands[-1][1] == rows
    lit = np.flatnonzero(img.any(axis=1))
    covered = set().union(*(range(a, b) for a, b, _ in bands))
    assert set(lit) <= covered
    # Adjacent bands meet (or share the row their inks' gap is cut in), never overlap more.
    assert all(0 <= a[1] - b[0] <= 1 for a, b in zip(bands, bands[1:]))
    assert all(b - a >= 0.6 * rows / len(bands) for a, b, _ in bands)


# -- panorama -----------------------------------------------------------------------
def test_panorama_columns_land_on_the_walls_they_face():
    """A bright column at the panorama's centre, quarter and three quarters lands in
    the middle of the front, left and right walls; the middle row at the image centre."""
    design = profile.load_design("default")
    light = room.light_position(design)
    h, w = 200, 800
    for col, name in ((w // 2, "front"), (w // 4, "left"), (3 * w // 4, "right")):
        pano = np.zeros((h, w))
        pano[:, col - 3: col + 3] = 1.0
        pano[h // 2 - 2: h // 2 + 2, :] = 0.5
        wall = next(x for x in room.walls(design) if x.name == name)
        img = targets.panorama_slice(pano, wall, light, design.room.wall_distance_mm,
                                     design.room.target_center_z_mm, 48, 64)
        column = img.sum(axis=0)
        assert abs(np.argmax(column) - 31.5) <= 1 and column.max() > 2 * np.median(column), name
        assert abs(np.argmax(img[:, 5]) - 23.5) <= 1 and img[:, 5].max() > 0.2, name
    with pytest.raises(LampfabError, match="360"):
        targets.check_panorama(np.zeros((100, 150)), "photo.png")


# -- end to end ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def text_lamp(tmp_path_factory, tiny_profile):
    build = tmp_path_factory.mktemp("text")
    run = make("lamp", f"BUILD={build}", 'TEXT=Hi there', f"PROFILE={tiny_profile}", f"LED={TINY_LED}")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    return build / "text", run


@pytest.mark.slow
@pytest.mark.e2e
def test_text_lamp_end_to_end(text_lamp):
    out, run = text_lamp
    prepared = json.loads((out / "prepare.json").read_text())["figures"]
    assert prepared["front_source"] == "text: Hi there"
    with Image.open(out / "targets" / "front_preview.png") as im:
        lit = (np.asarray(im) > 128).mean()
    assert 0.05 < lit < 0.5  # letters, not a blank or a full wall
    settings = json.loads((out / "settings.json").read_text())
    assert settings["text"] == "Hi there"
    # One summary line per stage with its time, then the total.
    lines = run.stdout.strip().splitlines()[-9:]
    for line, stage in zip(lines, ["prepare", "plan", "init", "optimize", "solid", "fabcheck", "export", "verify"]):
        assert re.match(rf"{stage}\s+\d+\.\d s  \S", line), line
    assert lines[-1].startswith("total") and "report.html" in lines[-1]
    # The slope limit init chose is on its line and in the report's fabrication table.
    slope = json.loads((out / "init.json").read_text())["figures"]["slope_limit_deg"]
    assert slope in (60.0, 68.0) and f"(slopes up to {slope:g}°)" in lines[2], lines[2]
    assert re.search(rf"Slopes of the outer surface</th><td>up to {slope:g}°", (out / "report.html").read_text())
    # The tiny profile's lens projects the letters at r 0.80-0.82.
    assert min(_wall_pearsons(out)) > 0.7
    # verify read every wall's words back (whether a tiny lamp's read is test_ocr's
    # business) and says so on the verify line.
    walls = json.loads((out / "verify.json").read_text())["figures"]["walls"]
    for name, f in walls.items():
        assert f["words"] == 2 and all(0 <= f[k] <= 2 for k in ("led_words_read", "point_words_read",
                                                                 "target_words_read")), name
    assert re.search(r"front r \S+ SSIM \S+ \d/2 words read", lines[-2]), lines[-2]
    assert re.search(r"OCR reads \d of its 6 words on the walls \(\d in the sharp targets\)",
                     (out / "report.html").read_text())
    # The report says what light the lens was designed for.
    page = (out / "report.html").read_text()
    assert "traces it as flat emitters on a post on the lamp's axis, one facing each wall" in page
    assert "level, black fins between them keeping each to its wall's part of the lens" in page
    # plan read them too: sharp, and blurred by its coarse design's LED kernels.
    plan = json.loads((out / "plan.json").read_text())["figures"]["sharpness"]["walls"]
    assert all(f["words"] == 2 and 0 <= f["perfect_words_read"] <= 2 and 0 <= f["target_words_read"] <= 2
               for f in plan.values())


@pytest.mark.slow
@pytest.mark.e2e
def test_optimization_gif_and_lens_glb(text_lamp, tiny_design):
    import trimesh

    from lampfab import paint
    from lampfab.export import stl

    out, _ = text_lamp
    with Image.open(out / "optimization.gif") as gif:
        frames = gif.n_frames
    iterations = tiny_design.optimize.iterations
    assert frames == iterations + 1  # step 0 and each step (tiny previews every step)
    scene = trimesh.load(out / "lens.glb")
    v, f = stl.read_stl(out / "lens.stl")
    design = json.loads((out / "design.json").read_text())
    assert design["lens"]["glb"] == "lens.glb"
    assert design["lens"]["black_paint"] == tiny_design.lens.black_paint == "top_base_and_back"
    assert design["lens"]["painted_u_deg"] == pytest.approx([225.0, 315.0], abs=20)  # the back, where no wall is
    painted = paint.painted_from_json(v, f, design["lens"])
    # The glass and the paint: one primitive each, together the whole closed lens.
    parts = {g.visual.material.name: g for g in scene.geometry.values()}
    glass, black = parts["lampfab glass"], parts["lampfab matt black paint"]
    assert len(glass.faces) == (~painted).sum() and len(black.faces) == painted.sum()
    # Each primitive holds its own copy of the shared positions: welded, one closed solid.
    whole = trimesh.Trimesh(np.vstack([glass.vertices, black.vertices]),
                            np.vstack([glass.faces, black.faces + len(glass.vertices)]))
    assert whole.is_watertight and len(whole.faces) == len(f)
    # Metres, Y up: the STL's height in z becomes y / 1000.
    assert glass.bounds[1][1] == pytest.approx(v[:, 2].max() / 1000, rel=1e-5)
    assert glass.bounds[0][1] == pytest.approx(0.0, abs=1e-6)
    assert glass.visual.material.metallicFactor == 0 and glass.visual.material.roughnessFactor == 0
    assert black.visual.material.baseColorFactor[:3].max() < 10  # 0-255: black


def _chromium():
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Chromium is missing: stages/00_setup.sh installs it (apt-get install chromium)"
    return exe


_PROBE = """<script>
const errors = [];
window.addEventListener("error", e => errors.push(String(e.message || (e.target && e.target.alt) || e)), true);
const logged = console.error;
console.error = (...args) => { errors.push(args.join(" ")); logged(...args); };
window.addEventListener("load", () => {
  const imgs = Array.from(document.images);
  const out = document.createElement("pre");
  out.id = "probe";
  out.textContent = JSON.stringify({errors: errors,
    images: imgs.map(i => [i.alt, i.complete, i.naturalWidth, i.naturalHeight])});
  document.body.appendChild(out);
});
</script>"""


@pytest.mark.slow
@pytest.mark.e2e
@pytest.mark.browser
def test_report_loads_every_image_in_a_real_browser(text_lamp, tmp_path):
    """Chromium opens report.html offline; every <img> decodes to its real size and
    nothing reports an error."""
    out, _ = text_lamp
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "<script" not in html  # the report itself runs nothing; the probe is added to a copy
    page = tmp_path / "probe.html"
    page.write_text(html.replace("<head>", "<head>" + _PROBE), encoding="utf-8")
    run = subprocess.run([_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                          f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000",
                          "--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120)
    found = re.search(r'<pre id="probe">(.*?)</pre>', run.stdout, re.S)
    assert found, run.stdout[-2000:] + run.stderr[-2000:]
    probe = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert probe["errors"] == []
    seen = probe["images"]
    embedded = re.findall(r'<img src="data:image/(?:png|gif|jpeg);base64,([A-Za-z0-9+/=]+)" alt="([^"]*)"', html)
    assert len(seen) == len(embedded) == html.count("<img ")
    walls = json.loads((out / "verify.json").read_text())["figures"]["walls"]
    # Per wall: target, LED, point light, Mitsuba; room, close-up, shape, heightmap, GIF, checks.
    assert len(seen) == 4 * len(walls) + 6
    for (alt, complete, width, height), (data, alt_html) in zip(seen, embedded):
        with Image.open(io.BytesIO(base64.b64decode(data))) as im:
            assert complete and (width, height) == im.size, (alt, width, height, im.size)
    for label in ("The lamp in its room", "The lens, close up", "Its shape", "The outer layer, unrolled",
                  "The walls during optimization", "Checks on the unrolled lens"):
        assert label in [s[0] for s in seen]


@pytest.mark.slow
@pytest.mark.e2e
def test_panorama_lamp_end_to_end(tmp_path, tiny_profile):
    run = make("lamp", f"BUILD={tmp_path}", f"PANORAMA={ROOT / 'examples' / 'panorama.png'}",
               f"PROFILE={tiny_profile}", f"LED={TINY_LED}")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    out = tmp_path / "panorama"
    prepared = json.loads((out / "prepare.json").read_text())
    assert prepared["inputs"]["panorama"]["path"].endswith("panorama.png")
    fronts = {}
    for name in ("front", "left", "right"):
        with Image.open(out / "targets" / f"{name}_preview.png") as im:
            fronts[name] = np.asarray(im, np.float64)
    # Each wall shows its own slice: the moon is only above the front wall.
    assert not np.allclose(fronts["front"], fronts["left"]) and not np.allclose(fronts["left"], fronts["right"])
    assert fronts["front"][:40].max() > 200 and fronts["left"][:40].max() < 50
    assert (out / "report.html").is_file() and (out / "lens.stl").is_file()
    # The tiny profile's lens projects its slices at r 0.77-0.80.
    assert min(_wall_pearsons(out)) > 0.65


def _wall_pearsons(out) -> list[float]:
    walls = json.loads((out / "verify.json").read_text())["figures"]["walls"]
    return [wall["pearson"] for wall in walls.values()]


def test_text_and_panorama_together_is_one_line(tmp_path, tiny_profile):
    run = cli("prepare", "--out", tmp_path / "b", "--profile", tiny_profile, "--text", "Hi", "--panorama",
              ROOT / "examples" / "panorama.png")
    assert run.returncode == 2 and run.stderr.count("\n") == 1 and "choose one" in run.stderr


def test_a_profile_sizes_the_bundled_hollow(tmp_path):
    """``[lens] hollow_radius_mm`` in a copied profile is the hollow the build designs around."""
    mine = tmp_path / "wide hollow.toml"
    mine.write_text((ROOT / "profiles" / "default.toml").read_text().replace(
        "[lens]\n", "[lens]\nhollow_radius_mm = 18.0\n", 1))
    build = Build.open(tmp_path / "b", str(mine), "sla_resin")
    v, f = build.inner()
    assert np.hypot(v[:, 0], v[:, 1]).max() == pytest.approx(18.0)
    v16, _ = Build.open(tmp_path / "b", "default", "sla_resin").inner()
    assert np.hypot(v16[:, 0], v16[:, 1]).max() == pytest.approx(16.0)


# -- Blender round trip ----------------------------------------------------------------
def test_glb_inner_layer_reads_as_the_same_mesh(tmp_path):
    """An inner layer exported as GLB (metres, Y up, as Blender writes it) loads in mm, Z up,
    each vertex where it was: the layer is made lopsided, so a mirrored or turned reading
    would not match, and the GLB is written by trimesh, not by lampfab's own writer."""
    import trimesh

    design = profile.load_design("default")
    lens = design.lens
    args = (room.light_position(design), lens.outer_radius_mm, lens.max_offset_mm, lens.height_mm)
    v, f = inner.load_inner(None, 1.0, *args)
    v = v.copy()
    v[:, 0] *= np.where(v[:, 0] > 0, 1.3, 1.0)   # wider towards +x
    v[:, 1] += 0.05 * (v[:, 2] - v[:, 2].min())  # leaning towards +y as it rises
    blender = v[:, [0, 2, 1]] * np.array([1.0, 1.0, -1.0]) / 1000.0  # glTF: x, z, -y in metres
    glb = tmp_path / "inner.glb"
    trimesh.Trimesh(blender, f, process=False).export(glb)
    v_glb, f_glb = inner.load_inner(glb, 1.0, *args)
    assert len(f_glb) == len(f)

    def rows(a):
        return a[np.lexsort(np.round(a, 3).T)]

    np.testing.assert_allclose(rows(v_glb), rows(v), atol=1e-4)
    mirrored = v * np.array([-1.0, 1.0, 1.0])
    assert np.abs(rows(mirrored) - rows(v)).max() > 1.0  # the check above would see a mirror
