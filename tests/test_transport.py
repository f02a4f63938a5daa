"""The transport design's sector placement and slope projection."""

import numpy as np

from lampfab import room, surface, transport


def _walls(design):
    return room.walls(design)


def _left_heavy(shape):
    """A target whose light sits in the left third of the image."""
    target = np.full(shape, 0.02)
    target[:, : shape[1] // 3] = 1.0
    return target


def test_centred_images_keep_the_nominal_sectors(default_design):
    walls = _walls(default_design)
    light = room.light_position(default_design)
    targets = [np.ones(room.image_shape(w, 32)) for w in walls]
    spans = transport.sectors(walls, targets, light, dump_share=0.2)
    for wall in walls:
        assert np.allclose(spans[wall.name], wall.sector_deg(), atol=1e-6)


def test_off_centre_images_turn_every_sector_the_same_way(default_design):
    walls = _walls(default_design)
    light = room.light_position(default_design)
    targets = [_left_heavy(room.image_shape(w, 32)) for w in walls]
    spans = transport.sectors(walls, targets, light, dump_share=0.2)
    # Seen from the lamp, the left of every wall's image lies at larger u (see
    # test_room's orientation test): each sector turns that way, by the same angle.
    front_shift = np.mean(spans["front"]) - 90.0
    assert front_shift > 5.0
    assert np.isclose(np.mean(spans["left"]) - 180.0, front_shift, atol=0.5)
    # Neighbours meet without a gap or an overlap ...
    assert np.isclose(spans["right"][1], spans["front"][0])
    assert np.isclose(spans["front"][1], spans["left"][0])
    # ... and a side facing no wall still covers the centred sector, so the unbent
    # light beyond it cannot reach the image.
    assert spans["right"][0] <= -45.0 + 1e-9
    assert spans["left"][1] >= 225.0 - 1e-9


def test_sector_nodes_wrap_round_zero():
    nodes = transport.sector_nodes((-45.0, 45.0), 16)
    u = nodes * 360 / 16
    assert list(nodes) == [14, 15, 0, 1]  # 315°, 337.5°, 0°, 22.5°
    assert np.all((u >= 315) | (u < 45))


def test_slope_projection_meets_the_limit_and_keeps_gentle_parts(cyl, rng):
    nu, nv = 64, 17
    heights = np.zeros((nu, nv))
    # A steep bump in one place, gentle ripples elsewhere.
    u = np.arange(nu)[:, None]
    z = np.arange(nv)[None, :]
    heights += 0.3 * np.sin(2 * np.pi * 3 * u / nu) * np.cos(np.pi * z / (nv - 1))
    heights[10:14, 6:10] += 8.0
    fine = surface.fine_shape(nu, nv, 4)
    before = surface.slopes_deg(cyl, heights, *fine)[0].max()
    assert before > 45.0
    limited, tilt = transport.limit_slopes(cyl, heights, 45.0)
    after = surface.slopes_deg(cyl, limited, *fine)[0].max()
    assert after <= 45.0 - transport.SLOPE_MARGIN_DEG + 1e-9
    assert np.isclose(tilt, after)
    # Far from the bump the ripples survive almost unchanged.
    far = np.abs(limited - heights)[40:60]
    assert far.max() < 0.1 * np.abs(heights[40:60]).max() + 0.05
