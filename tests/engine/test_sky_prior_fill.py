"""The fill's sky where the plate shows none (fill.py): how much of the frame reaches above
the world's horizon (`sky_in_view`), and the prior the fill blends toward there, `sky_gain`
times the plate's level, neutral, the ground rows left as the plate shows them."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, lookup_table
from virtual_reflections.envmap import apply_table
from virtual_reflections.fill import sky_in_view
from virtual_reflections.layouts import texel_directions
from virtual_reflections.params import (
    AUTO_SKY_GAIN,
    AUTO_SKY_ROUGHNESS,
    AUTO_SKY_TINT,
    ROUGH_SKY_RATIOS,
    SKY_GAINS,
    sky_gain_for,
    sky_prior_for,
)

W, H = 160, 90
F = 0.5 * W / math.tan(math.radians(30))  # 60 degrees across, 36 high
INTRINSICS = (F, F, W / 2, H / 2)


def up_when_pitched(deg):
    """The world's up in the engine's camera frame (+Y up, +Z ahead) for a camera pitched
    ``deg`` down (negative: up)."""
    a = math.radians(deg)
    return (0.0, math.cos(a), -math.sin(a))


@pytest.mark.parametrize(
    "pitch, expected",
    [(0.0, 0.5), (-25.0, 1.0), (25.0, 0.0), (10.0, (H / 2 - F * math.tan(math.radians(10))) / H)],
)
def test_the_share_of_rows_that_see_sky(pitch, expected):
    share = sky_in_view(INTRINSICS, W, H, up_when_pitched(pitch))
    assert share == pytest.approx(expected, abs=1.5 / H)


def test_a_rolled_camera_sees_sky_in_a_corner():
    """Looking 20 degrees down (no sky on a level frame) but rolled 30 degrees: the top
    corner on the raised side reaches above the horizon, so some rows see sky."""
    a, r = math.radians(20), math.radians(30)
    level = np.array([0.0, math.cos(a), -math.sin(a)])
    rolled = (level[0] * math.cos(r) - level[1] * math.sin(r),
              level[0] * math.sin(r) + level[1] * math.cos(r), level[2])  # fmt: skip
    assert sky_in_view(INTRINSICS, W, H, level) == 0.0
    assert 0.0 < sky_in_view(INTRINSICS, W, H, rolled) < 0.5


def test_the_unseen_sky_is_the_gain_times_the_plate_and_the_ground_stays():
    """A plate of ground only (a camera 30 degrees down): straight up, the map is a neutral
    grey in proportion to the gain; toward the plate's centre it is the plate."""
    rng = np.random.default_rng(3)
    plate = (0.2 + 0.05 * rng.random((H, W, 3))).astype(np.float32)
    plate[..., 0] *= 1.3  # a warm ground: the prior stays neutral all the same
    up = up_when_pitched(30.0)
    box = (60, 30, 100, 60)
    sky, ahead = {}, {}
    for kind, gain in SKY_GAINS.items():
        params = Params(
            method="camera",
            intrinsics=INTRINSICS,
            up=up,
            sky_gain=gain,
            sky_from_plate=0.0,
            sky_tint_share=0.0,
        )
        env = apply_table(lookup_table(W, H, box, params, "latlong", 256), plate)
        d = texel_directions("latlong", env.shape[1])
        sky[kind] = env[d @ np.array(up) > math.cos(math.radians(15))].mean(0)
        ahead[kind] = env[d[..., 2] > math.cos(math.radians(3))].mean(0)
    for kind, colour in sky.items():
        assert np.ptp(colour) < 0.01 * colour.mean(), (kind, colour)
        ratio = colour.mean() / sky["auto"].mean()
        assert ratio == pytest.approx(SKY_GAINS[kind] / SKY_GAINS["auto"], rel=0.01), kind
        np.testing.assert_allclose(ahead[kind], plate.reshape(-1, 3).mean(0), rtol=0.05)
    assert sky["enclosed"].mean() < sky["auto"].mean() < sky["open"].mean()


def test_a_tinted_sky_keeps_its_luminance_and_the_ground():
    """`Params.sky_tint` (the artist's Surroundings Custom): straight up, the map takes the
    tint's chromaticity at the neutral prior's luminance; the plate's ground is unchanged; a
    black or negative tint is refused."""
    rng = np.random.default_rng(4)
    plate = (0.2 + 0.05 * rng.random((H, W, 3))).astype(np.float32)
    up = up_when_pitched(30.0)
    box = (60, 30, 100, 60)
    luma = np.array([0.2126, 0.7152, 0.0722])
    tint = (0.4, 0.6, 1.0)  # a blue sky
    maps = {}
    for colour in ((1.0, 1.0, 1.0), tint):
        params = Params(
            method="camera",
            intrinsics=INTRINSICS,
            up=up,
            sky_tint=colour,
            sky_from_plate=0.0,
            sky_tint_share=0.0,
        )
        maps[colour] = apply_table(lookup_table(W, H, box, params, "latlong", 256), plate)
    d = texel_directions("latlong", 256)
    top = d @ np.array(up) > math.cos(math.radians(15))
    ahead = d[..., 2] > math.cos(math.radians(3))
    neutral, blue = maps[(1.0, 1.0, 1.0)][top].mean(0), maps[tint][top].mean(0)
    assert float(blue @ luma) == pytest.approx(float(neutral @ luma), rel=0.01)
    np.testing.assert_allclose(blue / blue[2], np.array(tint) / tint[2], rtol=0.02)
    np.testing.assert_allclose(maps[tint][ahead], maps[(1.0, 1.0, 1.0)][ahead], atol=1e-6)
    for bad in ((0.0, 0.0, 0.0), (1.0, -0.1, 1.0), (1.0, 1.0)):
        with pytest.raises(ValueError, match="sky_tint must be a colour"):
            Params(method="camera", intrinsics=INTRINSICS, up=up, sky_tint=bad)


def test_the_gain_for_a_rough_surface():
    """`sky_gain_for`: the mirror's gain at roughness 0 (and for a kind it does not know, or no
    roughness), the gain times the study's ratio at each knot, between knots between their
    gains, held beyond the last; growing with roughness."""
    assert sky_gain_for("auto") == pytest.approx(SKY_GAINS["auto"])
    assert sky_gain_for("world", 0.0) == pytest.approx(SKY_GAINS["auto"])
    assert sky_gain_for("open", float("nan")) == pytest.approx(SKY_GAINS["open"])
    for kind, knots in ROUGH_SKY_RATIOS.items():
        for roughness, ratio in knots:
            assert sky_gain_for(kind, roughness) == pytest.approx(SKY_GAINS[kind] * ratio)
        (a, ra), (b, rb) = knots[0], knots[1]
        middle = sky_gain_for(kind, 0.5 * (a + b)) / SKY_GAINS[kind]
        assert min(ra, rb) <= middle <= max(ra, rb)
        assert sky_gain_for(kind, 5.0) == pytest.approx(sky_gain_for(kind, 1.0))
        gains = [sky_gain_for(kind, r) for r in np.linspace(0, 1, 21)]
        assert all(b >= a for a, b in zip(gains, gains[1:])), kind


def test_a_plate_without_ground_is_the_sky_itself():
    """A camera looking 25 degrees up sees no ground: the unseen sky straight up is the plate's
    own level (a flat plate: its colour's luminance), not the gain times it; a camera looking
    30 degrees down takes the gain times its ground's level (above). So do the ground band's
    prior and Auto's from the plate's colour."""
    plate = np.full((H, W, 3), 0.3, np.float32)
    box = (60, 30, 100, 60)
    priors = (
        (SKY_GAINS["auto"], {"sky_gain": SKY_GAINS["auto"], "sky_from_plate": 0.0}),
        (AUTO_SKY_GAIN, {}),  # Auto: Params' defaults
    )
    for gain, fields in priors:
        for pitch, expected in ((-25.0, 0.3), (30.0, 0.3 * gain)):
            up = up_when_pitched(pitch)
            params = Params(method="camera", intrinsics=INTRINSICS, up=up, **fields)
            env = apply_table(lookup_table(W, H, box, params, "latlong", 256), plate)
            d = texel_directions("latlong", env.shape[1])
            straight_up = d @ np.array(up) > math.cos(math.radians(15))  # far above the frame
            assert env[straight_up].mean() == pytest.approx(expected, rel=0.02), (pitch, gain)


def _straight_up(plate, **fields):
    up = up_when_pitched(30.0)
    params = Params(method="camera", intrinsics=INTRINSICS, up=up, **fields)
    env = apply_table(lookup_table(W, H, (60, 30, 100, 60), params, "latlong", 256), plate)
    d = texel_directions("latlong", env.shape[1])
    return env[d @ np.array(up) > math.cos(math.radians(15))].mean(0)


def test_auto_takes_the_plate_mean_colour_brightened_and_half_way_to_its_hue():
    """Auto (Params' defaults, sky_from_plate 1): straight up, the unseen sky is AUTO_SKY_GAIN
    times the plate's mean luminance, its hue AUTO_SKY_TINT of the way from grey to the
    plate's; a sky_tint_share of 0 is grey, 1 the plate's own hue."""
    rng = np.random.default_rng(5)
    plate = (0.1 + 0.05 * rng.random((H, W, 3))).astype(np.float32)
    plate[: H // 3] = (0.3, 0.45, 0.8)  # a blue band at the top, a dark ground below
    luma = np.array([0.2126, 0.7152, 0.0722])
    mean = plate.reshape(-1, 3).mean(0, dtype=np.float64)
    level, hue = float(mean @ luma), mean / float(mean @ luma)
    for share in (AUTO_SKY_TINT, 0.0, 1.0):
        sky = _straight_up(plate, sky_tint_share=share)
        expected = AUTO_SKY_GAIN * level * ((1 - share) + share * hue)
        np.testing.assert_allclose(sky, expected, rtol=0.02, err_msg=str(share))
    assert _straight_up(plate)[2] > _straight_up(plate)[0]  # blue, as the plate


def test_a_sun_in_an_hdr_plate_counts_as_white_in_autos_sky():
    """A 4 x 4 sun at 5000 in a scene-linear plate: each pixel is clipped at 1 before the
    mean, so Auto's sky barely moves (the unclipped mean would be 28 times brighter)."""
    plate = np.full((H, W, 3), 0.2, np.float32)
    calm = _straight_up(plate)
    plate[10:14, 20:24] = 5000.0
    assert plate.mean() > 20 * 0.2
    np.testing.assert_allclose(_straight_up(plate), calm, rtol=0.01)


def test_the_sky_prior_for_each_surroundings():
    """`sky_prior_for`: Auto the plate's colour at AUTO_SKY_GAIN for a mirror and, from
    AUTO_SKY_ROUGHNESS on, the ground band's sky as before (brighter by Auto's ratio), blended
    geometrically between; Open, Enclosed and Custom the ground's, neutral, at sky_gain_for's."""
    assert sky_prior_for("auto") == {
        "sky_gain": AUTO_SKY_GAIN, "sky_from_plate": 1.0, "sky_tint_share": AUTO_SKY_TINT
    }  # fmt: skip
    assert sky_prior_for("world") == sky_prior_for("auto")  # no HDRI in the world: Auto's
    for rough in (AUTO_SKY_ROUGHNESS, 0.35, 1.0):
        assert sky_prior_for("auto", rough) == {
            "sky_gain": sky_gain_for("auto", rough), "sky_from_plate": 0.0,
            "sky_tint_share": 0.0,
        }  # fmt: skip
    half = sky_prior_for("auto", AUTO_SKY_ROUGHNESS / 2)
    assert half["sky_from_plate"] == pytest.approx(0.5)
    assert half["sky_tint_share"] == pytest.approx(AUTO_SKY_TINT / 2)
    between = (AUTO_SKY_GAIN * sky_gain_for("auto", AUTO_SKY_ROUGHNESS / 2)) ** 0.5
    assert half["sky_gain"] == pytest.approx(between)
    for kind, custom in (("open", None), ("enclosed", None), ("custom", 2.5)):
        prior = sky_prior_for(kind, 0.2, custom)
        assert prior == {
            "sky_gain": sky_gain_for(kind, 0.2, custom), "sky_from_plate": 0.0,
            "sky_tint_share": 0.0,
        }  # fmt: skip
        Params(**prior)  # valid
    with pytest.raises(ValueError, match="sky_from_plate must be 0..1"):
        Params(sky_from_plate=1.5)
    with pytest.raises(ValueError, match="sky_tint_share must be 0..1"):
        Params(sky_tint_share=1.5)


def test_a_rough_surfaces_sky_moves_smoothly_from_the_plates_to_the_grounds():
    """Straight up, the level at sky_from_plate f is the plate's mean level to the f times
    the ground band's to the 1 - f (a flat ground with a bright band at its top, which the
    two levels weigh differently)."""
    plate = np.full((H, W, 3), 0.2, np.float32)
    plate[:10] = 0.9  # a bright band at the top: the two levels differ
    levels = {
        f: float(_straight_up(plate, sky_gain=1.0, sky_tint_share=0.0, sky_from_plate=f).mean())
        for f in (0.0, 0.5, 1.0)
    }
    assert abs(math.log(levels[1.0] / levels[0.0])) > 0.03
    assert levels[0.5] == pytest.approx((levels[0.0] * levels[1.0]) ** 0.5, rel=0.01)
