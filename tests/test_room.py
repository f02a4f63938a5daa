import numpy as np

from lampfab import room


def test_walls_face_the_lamp_and_sit_at_the_profile_distance(default_design):
    light = room.light_position(default_design)
    for wall in room.walls(default_design):
        to_lamp = light - wall.centre
        assert wall.normal @ to_lamp > 0
        assert abs(wall.normal @ to_lamp) == default_design.room.wall_distance_mm
        assert np.isclose(wall.width_mm, default_design.room.target_width_mm)
