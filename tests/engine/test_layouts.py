"""Layout conventions: docs/conventions.md lat-long, OpenEXR ImfEnvmap cube faces."""

import numpy as np
import pytest

from virtual_reflections.layouts import map_shape, texel_directions


def test_latlong_centre_is_the_view_direction_and_left_half_is_plus_x():
    d = texel_directions("latlong", 64)
    h, w = map_shape("latlong", 64)
    assert d[h // 2, w // 2] == pytest.approx([0.0, 0.0, 1.0], abs=0.1)  # forward
    assert (d[:, : w // 2, 0] > 0).all() and (d[:, w // 2 :, 0] < 0).all()
    assert (d[: h // 2, :, 1] > 0).all()  # top rows look up
    # Pixel centre formula of docs/conventions.md.
    x, y = 5, 7
    lat, lon = -np.pi * ((y + 0.5) / h - 0.5), -2 * np.pi * ((x + 0.5) / w - 0.5)
    expected = [np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)]
    assert d[y, x] == pytest.approx(expected)


# ImfEnvmap's CubeMap::direction/pixelPosition, written out per face: (face, col, row) of
# a 3x3 face's corner and centre texels and the direction they hold.
@pytest.mark.parametrize(
    "face, col, row, direction",
    [
        (0, 1, 1, (1, 0, 0)),
        (1, 1, 1, (-1, 0, 0)),
        (2, 1, 1, (0, 1, 0)),
        (3, 1, 1, (0, -1, 0)),
        (4, 1, 1, (0, 0, 1)),
        (5, 1, 1, (0, 0, -1)),
        # +Z is the back face seen upright and unmirrored: top-left is up and to the left.
        (4, 0, 0, (1, 1, 1)),
        (4, 2, 2, (-1, -1, 1)),
        # +X: columns run from front (-Z) to back (+Z), rows from up to down.
        (0, 0, 0, (1, 1, -1)),
        (0, 2, 2, (1, -1, 1)),
        (1, 0, 0, (-1, 1, 1)),
        (2, 0, 0, (-1, 1, 1)),
        (3, 0, 0, (-1, -1, -1)),
        (5, 0, 0, (-1, 1, -1)),
    ],
)
def test_cube_faces_follow_imfenvmap(face, col, row, direction):
    d = texel_directions("cube", 3)
    assert d[face * 3 + row, col] == pytest.approx(direction)


def test_shapes_and_bad_sizes():
    assert map_shape("latlong", 1024) == (512, 1024)
    assert map_shape("cube", 512) == (3072, 512)
    for layout, size in (("latlong", 7), ("cube", 1), ("sphere", 64)):
        with pytest.raises(ValueError):
            map_shape(layout, size)
