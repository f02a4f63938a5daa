import numpy as np

from lampfab import room, transport


def test_walls_face_the_lamp_and_sit_at_the_profile_distance(default_design):
    light = room.light_position(default_design)
    for wall in room.walls(default_design):
        to_lamp = light - wall.centre
        assert wall.normal @ to_lamp > 0
        assert abs(wall.normal @ to_lamp) == default_design.room.wall_distance_mm
        assert np.isclose(wall.width_mm, default_design.room.target_width_mm)


def test_sector_orientation_matches_the_viewer(default_design):
    walls = {w.name: w for w in room.walls(default_design)}
    # Seen from inside the room, light leaving further counter-clockwise lands further
    # left on the front wall; higher light lands higher on every vertical wall.
    assert transport.orientation(walls["front"]) == (False, False)
    assert transport.orientation(walls["left"]) == (False, False)
    assert transport.orientation(walls["right"]) == (False, False)
