"""A post's fins stop light wherever it crosses them: as it leaves an LED, and after a
reflection inside the lens sends it back across the cavity."""

import dataclasses

import numpy as np
import pytest

from lampfab import fins, trace
from lampfab.room import Wall
from lampfab.source import Source

LIGHT = (0.0, 0.0, 45.0)
# Fins at 45, 135, 225 and 315 degrees, 10.5 mm out, 25 mm above and below the LEDs.
POST = Source(LIGHT, "post", 1.5, facing_deg=(90.0, 180.0, 0.0), offset_mm=3.0, fin_radius_mm=10.5,
              fin_height_mm=50.0)


def _stops(mi, source, o, d, t_max=None):
    o, d = np.asarray(o, np.float32), np.asarray(d, np.float32)
    t = None if t_max is None else mi.Float(np.asarray(t_max, np.float32))
    return fins.stops(mi, source, mi.Point3f(*o.T), mi.Vector3f(*d.T), t).numpy()


def test_a_fin_stops_a_ray_only_where_it_stands(mi):
    towards_left = [-0.6, 0.8, 0.0]  # from the front sector, meets the 45-degree fin 6.5 mm out after 5.7 mm
    o = [[8.0, 0.0, 45.0], [8.0, 0.0, 45.0], [8.0, 0.0, 75.0], [8.0, 0.0, 45.0], [8.0, 0.0, 45.0]]
    d = [towards_left, towards_left, towards_left, [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]
    # Stopped; stopped short of the fin (t_max 5); over the fin's top; past its tip (11.3 mm
    # out); heading away.
    assert _stops(mi, POST, o, d, [100.0, 5.0, 100.0, 100.0, 100.0]).tolist() == [True, False, False, False, False]
    assert _stops(mi, POST, o, d).tolist() == [True, True, False, False, False]
    bare = dataclasses.replace(POST, fin_radius_mm=0.0, fin_height_mm=0.0)
    assert not _stops(mi, bare, o, d).any()
    assert fins.stopper(mi, bare) is None and fins.stopper(mi, None) is None


def test_light_the_cavity_reflects_across_it_ends_on_a_fin(mi, inner_layer):
    """``into_glass`` follows every k-th photon's reflection across the cavity: with fins,
    those that cross from one sector into the opposite one carry nothing, those that stay
    in their sector all their light."""
    v, f = inner_layer
    cavity = trace.MeshScene(v, f[:, ::-1]).scene
    o, d = trace.emit(mi, POST, 200_000, 3)
    every = 4
    _, _, bare = trace.into_glass(mi, cavity, o, d, 1.51, every)
    p, _, w = trace.into_glass(mi, cavity, o, d, 1.51, every, fins.stopper(mi, POST))
    p, w, bare = trace.to_numpy(p), w.numpy(), bare.numpy()
    n = len(trace.to_numpy(o))  # the refracted photons come first, then the reflected ones
    start, end, weight = p[:n][::every], p[n:], w[n:]
    assert np.array_equal(w[:n], bare[:n])  # the light entering the glass directly is untouched
    azimuth = np.degrees(np.arctan2(np.stack([start[:, 1], end[:, 1]]), np.stack([start[:, 0], end[:, 0]])))
    sector = np.round(azimuth / 90.0) % 4  # 0 front, 1 left, 2 back, 3 right
    inside = (np.abs(azimuth - 90.0 * np.round(azimuth / 90.0)) < 35.0).all(0)  # 10 degrees clear of a fin
    level = (np.abs(np.stack([start[:, 2], end[:, 2]]) - LIGHT[2]) < 20.0).all(0)  # the whole chord by a fin
    opposite = inside & level & ((sector[0] - sector[1]) % 4 == 2)
    same = inside & (sector[0] == sector[1])
    assert opposite.sum() > 100 and same.sum() > 100
    assert np.all(weight[opposite] == 0) and np.all(bare[n:][opposite] > 0)
    assert np.array_equal(weight[same], bare[n:][same])


def test_the_tracer_ends_light_reflected_across_the_cavity_on_the_fins(mi, small_lens, monkeypatch):
    """What reaches a wall after a reflection inside the lens: the fins stop part of it
    (the light the far sector reflected back across the cavity); the rest is the same."""
    walls = [Wall("front", np.array([-900.0, 1000.0, 715.0]), np.array([1800.0, 0, 0]), np.array([0, 0, -1350.0]))]
    shapes = [(12, 16)]
    post = dataclasses.replace(POST, position_mm=(0.0, 0.0, 40.0), facing_deg=(90.0, 270.0))
    scene = trace.MeshScene(small_lens.vertices, small_lens.faces)
    images, info = trace.render_walls(scene, post, 1.51, walls, shapes, 1_000_000, seed=2)
    monkeypatch.setattr(trace.fins, "stopper", lambda mi, source: None)
    open_images, open_info = trace.render_walls(scene, post, 1.51, walls, shapes, 1_000_000, seed=2)
    direct, open_direct = images[0] - info["ghosts"][0], open_images[0] - open_info["ghosts"][0]
    assert direct.sum() == pytest.approx(open_direct.sum(), rel=0.02)  # the LED's own light: the same
    assert info["ghosts"][0].sum() < 0.8 * open_info["ghosts"][0].sum()
