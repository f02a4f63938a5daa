"""The LED as the optics see it: its beam, where its photons start, how designs name it."""

import numpy as np
import pytest

from lampfab import raymap, room, trace
from lampfab.source import Source


def _uniform_directions(n, seed=0):
    d = np.random.default_rng(seed).standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_a_flat_leds_intensity_is_its_cosine_from_up_and_nothing_below():
    d = _uniform_directions(400_000)
    flat = Source((0, 0, 45), "disc", 1.5).intensity(d)
    assert flat.mean() == pytest.approx(1.0, abs=0.01)  # the same light in all as a ball
    assert np.all(flat[d[:, 2] < 0] == 0) and np.allclose(flat[d[:, 2] > 0], 4 * d[d[:, 2] > 0, 2])
    assert np.all(Source((0, 0, 45), "sphere", 1.5).intensity(d) == 1)


def test_a_flat_led_shines_up_from_its_face(mi):
    o, d = trace.emit(mi, Source((0.0, 0.0, 45.0), "disc", 1.5), 40_000, 3)
    o, d = trace.to_numpy(o), trace.to_numpy(d)
    assert np.allclose(o[:, 2], 45.0)
    r = np.hypot(o[:, 0], o[:, 1])
    assert r.max() <= 1.5 + 1e-5 and np.mean(r < 1.5 / np.sqrt(2)) == pytest.approx(0.5, abs=0.02)  # even over the disc
    assert (d[:, 2] > 0).all()
    assert np.mean(d[:, 2]) == pytest.approx(2 / 3, abs=0.01)  # Lambertian: mean cosine 2/3
    point_o, point_d = trace.emit(mi, Source((0.0, 0.0, 45.0), "disc", 1.5).point(), 40_000, 3)
    assert np.allclose(trace.to_numpy(point_o), [0.0, 0.0, 45.0])
    assert np.mean(trace.to_numpy(point_d)[:, 2]) == pytest.approx(2 / 3, abs=0.01)  # the point keeps the beam


def test_a_posts_leds_each_shine_level_towards_their_wall(mi):
    """One flat LED per wall, ``offset_mm`` out from the axis, facing its sector's centre."""
    post = Source((0.0, 0.0, 45.0), "post", 1.5, facing_deg=(0.0, 90.0, 180.0), offset_mm=3.0)
    d = _uniform_directions(400_000)
    beam = post.intensity(d)
    assert beam.mean() == pytest.approx(1.0, abs=0.01)
    toward = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [np.sqrt(0.5), np.sqrt(0.5), 0.0]])
    assert np.allclose(post.intensity(toward), [4 / 3, 0.0, 0.0, 4 / 3 * np.sqrt(2)])
    o, d = (trace.to_numpy(a) for a in trace.emit(mi, post, 60_000, 5))
    face = np.argmax((o - [0.0, 0.0, 45.0]) @ post.normals.T, axis=1)  # the LED it left
    normal = post.normals[face]
    assert np.bincount(face, minlength=3) / len(face) == pytest.approx([1 / 3] * 3, abs=0.02)
    assert np.allclose(np.einsum("ij,ij->i", o - [0.0, 0.0, 45.0], normal), 3.0, atol=1e-4)  # on its face
    assert np.linalg.norm(o - [0.0, 0.0, 45.0] - 3.0 * normal, axis=1).max() <= 1.5 + 1e-4
    assert np.mean(np.einsum("ij,ij->i", d, normal)) == pytest.approx(2 / 3, abs=0.01)  # Lambertian
    assert (np.einsum("ij,ij->i", d, normal) > 0).all()
    o = trace.to_numpy(trace.emit(mi, post.point(), 1000, 5)[0])  # each LED's centre
    assert np.allclose(np.unique(np.round(o, 4), axis=0), [[-3.0, 0.0, 45.0], [0.0, 3.0, 45.0], [3.0, 0.0, 45.0]])


def test_a_posts_fins_keep_each_leds_light_to_its_sector(mi):
    """Fins at the sectors' edges stop what would cross into a neighbour's sector; the
    light they stop still counts as emitted (sent where nothing is)."""
    fins = Source((0.0, 0.0, 45.0), "post", 1.5, facing_deg=(90.0, 180.0, 0.0), offset_mm=3.0,
                  fin_radius_mm=11.0, fin_height_mm=50.0)
    o, d = (trace.to_numpy(a) for a in trace.emit(mi, fins, 60_000, 7))
    stopped = o[:, 2] < -1e6
    assert np.all(d[stopped] == [0.0, 0.0, -1.0])
    beam = fins.intensity(_uniform_directions(400_000)).mean()  # what the transport expects
    assert stopped.mean() == pytest.approx(1.0 - beam, abs=0.03) and 0.1 < stopped.mean() < 0.2
    p, v = o[~stopped] - [0.0, 0.0, 45.0], d[~stopped]
    face = np.argmax(p @ fins.normals.T, axis=1)
    a, b, c = (v[:, :2] ** 2).sum(1), 2 * (p[:, :2] * v[:, :2]).sum(1), (p[:, :2] ** 2).sum(1) - 11.0 ** 2
    hit = p + ((-b + np.sqrt(b * b - 4 * a * c)) / (2 * a))[:, None] * v  # where each meets the fins' radius
    off = (np.degrees(np.arctan2(hit[:, 1], hit[:, 0])) - np.asarray(fins.facing_deg)[face] + 180.0) % 360.0 - 180.0
    under = np.abs(hit[:, 2]) <= 25.0
    assert np.all(np.abs(off[under]) <= 45.0 + 1e-3)  # none crossed a fin
    assert np.any(np.abs(off[~under]) > 45.0)  # over and under the fins, light still crosses
    without = Source((0.0, 0.0, 45.0), "post", 1.5, facing_deg=(90.0, 180.0, 0.0), offset_mm=3.0)
    assert (trace.to_numpy(trace.emit(mi, without, 60_000, 7)[0])[:, 2] > 0).all()


def test_the_transport_weighs_each_photon_by_the_beam(default_design, inner_layer):
    light = room.light_position(default_design)
    ball = raymap.stratified_photons(*inner_layer, Source(light), 1.5, 64, 32, seed=2)
    flat = raymap.stratified_photons(*inner_layer, Source(light, "disc"), 1.5, 64, 32, seed=2)
    assert np.array_equal(ball.emitted, flat.emitted)
    assert np.allclose(flat.weight, ball.weight * 4 * np.maximum(ball.emitted[:, 2], 0))
    assert flat.weight[ball.emitted[:, 2] < 0].sum() == 0
    assert flat.weight.sum() == pytest.approx(ball.weight.sum(), rel=0.05)


def test_designs_name_their_light():
    disc = Source.from_json({"position": [0, 0, 15], "shape": "disc", "radius": 1.5, "length": 0.0})
    assert (disc.shape, disc.facing_up, disc.describe()) == ("disc", True, "flat LED 1.5 mm facing up")
    # Written before designs named the shape: a length is a filament, else a ball.
    assert Source.from_json({"position": [0, 0, 45], "radius": 0.8, "length": 26.0}).shape == "cylinder"
    assert Source.from_json({"position": [0, 0, 45], "radius": 1.5}).describe() == "LED 1.5 mm"
    post = {"position": [0, 0, 45], "shape": "post", "radius": 1.5, "facing_deg": [0, 90, 180], "offset_mm": 3.0}
    assert Source.from_json(post) == Source((0, 0, 45), "post", 1.5, 0.0, (0.0, 90.0, 180.0), 3.0)
    assert Source.from_json(post).describe() == "3 flat LEDs 1.5 mm facing out"
    with pytest.raises(ValueError, match="shape 'cube'"):
        Source((0, 0, 0), "cube")
    with pytest.raises(ValueError, match="only a post"):
        Source((0, 0, 0), "post")
    with pytest.raises(ValueError, match="only a post has fins"):
        Source((0, 0, 0), "disc", fin_radius_mm=5.0, fin_height_mm=5.0)


def test_the_source_method_refuses_a_flat_led(tmp_path):
    """``ptracer`` lights the lens with Mitsuba's point light, which shines every way."""
    import dataclasses

    from lampfab import pipeline
    from lampfab.errors import LampfabError

    flat = tmp_path / "flat.toml"
    flat.write_text("shape = 'disc'\nradius_mm = 1.5\n")
    build = pipeline.Build.open(tmp_path / "b", "default", "sla_resin", str(flat))
    opt = dataclasses.replace(build.design.optimize, method="ptracer", design_light="point")
    with pytest.raises(LampfabError, match='method "ptracer" .* LED=flat shines from flat faces'):
        build.optimizer(opt, None, [])


def test_an_led_that_pokes_out_of_the_cavity_is_refused(tmp_path):
    """A 26 mm filament 15 mm up the lens would reach through the cavity's floor (10 mm)."""
    from lampfab import pipeline, profile
    from lampfab.errors import LampfabError

    low = tmp_path / "low.toml"
    low.write_text((profile.PROFILE_DIR / "default.toml").read_text().replace(
        "light_height_mm = 45.0", "light_height_mm = 15.0"))
    with pytest.raises(LampfabError, match=r"glowing 26 mm filament \(0.8 mm radius\) reaches \[0.0, 0.0, 2.0\] mm, "
                                           r"outside the cavity; move \[lens\] light_height_mm"):
        pipeline.Build.open(tmp_path, str(low), "sla_resin", "filament26").inner()
    pipeline.Build.open(tmp_path, "default", "sla_resin", "filament26").inner()  # at mid-height it fits
    pipeline.Build.open(tmp_path, str(low), "sla_resin", "star3535").inner()
    pipeline.Build.open(tmp_path, "default", "sla_resin", "post3535").inner()
    tall = tmp_path / "tall.toml"
    tall.write_text("shape = 'post'\nradius_mm = 1.5\noffset_mm = 3.0\nfin_radius_mm = 10.5\nfin_height_mm = 80.0\n"
                    "board_diameter_mm = 22.0\nrod_width_mm = 4.0\n")
    with pytest.raises(LampfabError, match=r"fins \(10.5 mm out, 80 mm tall\) reach \[.*, 5.0\] mm, outside"):
        pipeline.Build.open(tmp_path, "default", "sla_resin", str(tall)).inner()
    wide = tmp_path / "wide.toml"
    wide.write_text("shape = 'post'\nradius_mm = 1.5\noffset_mm = 15.0\n")
    with pytest.raises(LampfabError, match=r"glowing face \(1.5 mm radius\) reaches \[0.0, 16.5, 45.0\] mm"):
        pipeline.Build.open(tmp_path, "default", "sla_resin", str(wide)).inner()


def test_the_transports_photons_leave_a_post_from_the_face_that_sends_them(default_design, inner_layer):
    """The transport designs for the point light verify and the refinement trace: each
    photon from its face's centre, not from the axis."""
    post = Source(room.light_position(default_design), "post", 1.5, facing_deg=(0.0, 90.0, 180.0), offset_mm=3.0,
                  fin_radius_mm=11.0, fin_height_mm=50.0)
    d = _uniform_directions(20_000)
    start = post.origins(d)
    lit = post.intensity(d) > 0
    face = np.argmax(d @ post.normals.T, axis=1)
    assert np.allclose(start[lit], post.position + 3.0 * post.normals[face[lit]])
    assert np.allclose(start[~lit], post.position)  # behind every face or past the fins: weightless
    ph = raymap.stratified_photons(*inner_layer, post, 1.5, 64, 32, seed=2)
    sent = ph.weight > 0
    cos = np.maximum(ph.emitted[sent] @ post.normals.T, 0.0)
    centre = post.position + 3.0 * post.normals[np.argmax(cos, axis=1)]
    # Where each enters the glass lies on its ray from its face's centre, not from the axis.
    along = ph.origin[sent] - centre
    assert np.abs(np.cross(along, ph.emitted[sent])).max() < 1e-3
    off_axis = np.abs(np.cross(ph.origin[sent] - post.position, ph.emitted[sent])).max(axis=1)
    assert off_axis.max() > 2.0
