"""The frustum method: exact placement by the camera's field of view, blur outside it."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, environment_map
from virtual_reflections.frustum import plate_positions
from virtual_reflections.panorama import camera_frame_directions


def test_pixel_directions_land_on_their_pixels():
    w, h, hfov = 160, 90, 60.0
    d = camera_frame_directions(w, h, hfov)  # CONVENTIONS.md pinhole directions
    pos, lod = plate_positions(d, w, h, hfov)
    py, px = np.mgrid[0:h, 0:w] + 0.5
    assert np.abs(pos[..., 0] - px).max() < 1e-3 and np.abs(pos[..., 1] - py).max() < 1e-3
    assert lod.max() == 0.0


def test_outside_the_view_is_clamped_to_the_nearest_edge_and_blurred():
    w, h, hfov = 160, 90, 60.0
    left = np.array([[math.sin(1.0), 0.0, math.cos(1.0)]])  # 57 degrees to the left
    up = np.array([[0.0, math.sin(1.2), math.cos(1.2)]])
    behind = np.array([[0.0, 0.0, -1.0]])
    (pl,), (ll,) = plate_positions(left, w, h, hfov)
    (pu,), (lu,) = plate_positions(up, w, h, hfov)
    _, (lb,) = plate_positions(behind, w, h, hfov, max_blur=1.0)
    assert pl[0] == pytest.approx(0.0) and pl[1] == pytest.approx(45.0)  # the left edge
    assert pu[0] == pytest.approx(80.0) and pu[1] == pytest.approx(0.0)  # the top edge
    assert 0 < ll < lb and lu > 0  # more blur further out, capped
    _, (capped,) = plate_positions(behind, w, h, hfov, max_blur=0.125)
    assert capped == pytest.approx(math.log2(0.125 * h))


def test_frustum_map_reproduces_a_plate_of_the_map():
    """A plate rendered from a known lat-long map comes back exactly where the plate sees."""
    from virtual_reflections.layouts import texel_directions

    w, h, hfov = 320, 180, 70.0
    d = camera_frame_directions(w, h, hfov)
    plate = np.stack([0.5 + 0.5 * d[..., 0], 0.5 + 0.5 * d[..., 1], d[..., 2]], -1)
    env = environment_map(
        plate.astype(np.float32), (0, 0, 1, 1), Params(method="frustum", hfov=hfov), "latlong", 256
    )
    dirs = texel_directions("latlong", 256)
    inside = (
        (dirs[..., 2] > 0)
        & (np.abs(dirs[..., 0] / dirs[..., 2]) < 0.6)
        & (np.abs(dirs[..., 1] / dirs[..., 2]) < 0.3)
    )
    expected = np.stack([0.5 + 0.5 * dirs[..., 0], 0.5 + 0.5 * dirs[..., 1], dirs[..., 2]], -1)
    assert np.abs(env[inside] - expected[inside]).max() < 0.01


def test_frustum_needs_the_field_of_view():
    with pytest.raises(ValueError, match="field of view"):
        Params(method="frustum")
    with pytest.raises(ValueError, match="method"):
        Params(method="magic")


def test_shifted_lens_and_non_square_pixels():
    w, h = 200, 100
    fx, fy, cx, cy = 150.0, 120.0, 130.0, 40.0  # principal point off-centre
    py, px = np.mgrid[0:h, 0:w] + 0.5
    d = np.stack([-(px - cx) / fx, -(py - cy) / fy, np.ones_like(px)], -1)
    pos, lod = plate_positions(d, w, h, intrinsics=(fx, fy, cx, cy))
    assert np.abs(pos[..., 0] - px).max() < 1e-3 and np.abs(pos[..., 1] - py).max() < 1e-3
    assert lod.max() == 0.0
