"""The ground method's contact shadow (ground.py): the plate has no object, so the ground it
shows is lit as if the object were not there; the map darkens each ground texel by the share
of an even sky that a sphere standing for the object hides from that ground point."""

import numpy as np
import pytest

from virtual_reflections import Params, environment_map
from virtual_reflections.ground import ground_pixels, ground_weight, sky_left
from virtual_reflections.layouts import texel_directions

W, H, SIZE = 320, 180, 128
GREY = 0.5


def test_the_sky_left_is_the_form_factor_of_a_sphere():
    resting = (0.0, 0.0, 5.0, 0.5)  # radius = height: standing on the ground
    assert sky_left(1.0, resting) == pytest.approx(0.0)  # right under it: no sky
    assert sky_left(0.0, resting) == pytest.approx(1.0)  # far off: all of it
    assert sky_left(np.sin(np.radians(45)), resting) == pytest.approx(1 - 0.5**1.5, abs=1e-6)
    floating = (0.0, 0.0, 5.0, 1.0, 0.5)  # half as large as high: a quarter of the share
    assert sky_left(1.0, floating) == pytest.approx(0.75)
    assert sky_left(-0.3, resting) == pytest.approx(1.0)  # up: no ground
    # the artist's Contact Shadow: the hidden share times its strength
    assert sky_left(1.0, (*resting, 0.5, 0.4)) == pytest.approx(0.6)
    assert sky_left(1.0, (*floating, 0.0)) == pytest.approx(1.0)  # off: the plate as it is


def test_the_shadows_strength_is_checked():
    for strength in (-0.1, 1.5):
        with pytest.raises(ValueError, match="shadow's strength"):
            Params(method="ground", hfov=70.0, ground=(0, 0, 5, 0.5, 0.5, strength), up=(0, 1, 0))


@pytest.mark.parametrize(
    "ground",
    [(0.0, -1.1, 5.0, 0.5), (0.3, -0.8, 6.0, 0.8, 0.4), (0.0, -1.1, 5.0, 0.5, 0.5, 0.5)],
)
def test_a_plain_ground_is_darkened_around_the_object(ground):
    """A plate of one grey: each map texel whose ground point is well inside the plate reads
    grey x the sky left at its angle below the horizon; straight down is dark, the horizon
    not."""
    plate = np.full((H, W, 3), GREY, np.float32)
    up = (0.0, 1.0, 0.0)
    params = Params(method="ground", hfov=70.0, ground=ground, up=up)
    env = environment_map(plate, (140, 60, 180, 120), params, "latlong", SIZE).reshape(-1, 3)
    d = texel_directions("latlong", SIZE).reshape(-1, 3)
    intrinsics = (0.5 * W / np.tan(np.radians(35.0)),) * 2 + (W / 2, H / 2)
    px, py, valid = ground_pixels(d, ground, up, intrinsics)
    inside = valid & (ground_weight(px, py, valid, W, H, margin=1e-6) >= 1.0)
    inside &= (px > 8) & (px < W - 8) & (py > 8) & (py < H - 8)
    assert inside.sum() > 50
    expected = GREY * sky_left(-d[inside, 1], ground)
    np.testing.assert_allclose(env[inside].mean(1), expected, atol=0.01)
    assert expected.min() < 0.8 * GREY  # some texels are really in the shadow
