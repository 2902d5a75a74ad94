"""The unseen sky estimated from the whole plate (Params.sky_from_plate, the add-on's Auto;
issue 41, docs/scenes3d.md "A safe fall-back and retrieval, held out by HDRI"): its level is
PLATE_SKY_GAIN times the plate mean's luminance, its colour moved halfway toward the plate
mean's, and where the plate shows almost no sky the whole map leans SAFE_LEAN toward the
plate mean (the flat colour it must never be much worse than)."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, lookup_table
from virtual_reflections.envmap import apply_table, prior_parts
from virtual_reflections.fill import (
    PLATE_SKY_GAIN,
    PLATE_SKY_TINT,
    SAFE_GROUND_SHARE,
    SAFE_LEAN,
    sky_in_view,
)
from virtual_reflections.layouts import texel_directions

W, H = 160, 90
F = 0.5 * W / math.tan(math.radians(30))
INTRINSICS = (F, F, W / 2, H / 2)
LUMA = np.array([0.2126, 0.7152, 0.0722])
BOX = (60, 30, 100, 60)


def up_when_pitched(deg):
    a = math.radians(deg)
    return (0.0, math.cos(a), -math.sin(a))


def warm_plate(seed=3):
    rng = np.random.default_rng(seed)
    plate = (0.1 + 0.3 * rng.random((H, W, 3))).astype(np.float32)
    plate[..., 0] *= 1.5  # warm: the sky takes half of its chromaticity
    return plate


def maps(pitch, plate, **kwargs):
    out = {}
    for from_plate in (False, True):
        params = Params(
            method="camera", intrinsics=INTRINSICS, up=up_when_pitched(pitch),
            sky_gain=PLATE_SKY_GAIN, sky_from_plate=from_plate, **kwargs,
        )  # fmt: skip
        table = lookup_table(W, H, BOX, params, "latlong", 256)
        out[from_plate] = (apply_table(table, plate), table)
    return out


def expected_sky(plate):
    mean = plate.reshape(-1, 3).astype(np.float64).mean(0)
    level = PLATE_SKY_GAIN * float(mean @ LUMA)
    return level * ((1 - PLATE_SKY_TINT) + PLATE_SKY_TINT * mean / float(mean @ LUMA)), mean


def test_the_sky_is_the_plate_means_level_tinted_halfway_toward_it():
    """A level camera (half the plate sky): no lean; straight up the map is the plate mean's
    luminance times the gain, halfway toward its colour; ahead the plate is unchanged."""
    plate = warm_plate()
    got = maps(0.0, plate)
    env, table = got[True]
    assert table.fill.lean == 0.0
    d = texel_directions("latlong", 256)
    top = d @ np.array(up_when_pitched(0.0)) > math.cos(math.radians(10))
    sky, _ = expected_sky(plate)
    np.testing.assert_allclose(env[top].mean(0), sky, rtol=0.03)
    ahead = d[..., 2] > math.cos(math.radians(3))
    np.testing.assert_allclose(env[ahead], got[False][0][ahead], atol=1e-6)


def test_a_plate_of_ground_only_leans_the_whole_map_toward_the_plate_mean():
    """A camera 30 degrees down sees no sky (its ground share over SAFE_GROUND_SHARE): every
    texel, the plate's own ahead too, is SAFE_LEAN of the way to the plate mean."""
    plate = warm_plate()
    assert 1.0 - sky_in_view(INTRINSICS, W, H, up_when_pitched(30.0)) > SAFE_GROUND_SHARE
    got = maps(30.0, plate)
    env, table = got[True]
    assert table.fill.lean == SAFE_LEAN and got[False][1].fill.lean == 0.0
    d = texel_directions("latlong", 256)
    ahead = d[..., 2] > math.cos(math.radians(3))
    _, mean = expected_sky(plate)
    np.testing.assert_allclose(
        env[ahead], (1 - SAFE_LEAN) * got[False][0][ahead] + SAFE_LEAN * mean, rtol=0.02
    )
    top = d @ np.array(up_when_pitched(30.0)) > math.cos(math.radians(10))
    sky, _ = expected_sky(plate)
    np.testing.assert_allclose(env[top].mean(0), (1 - SAFE_LEAN) * sky + SAFE_LEAN * mean,
                               rtol=0.03)  # fmt: skip


@pytest.mark.parametrize("pitch", [0.0, 30.0])
def test_the_map_still_splits_exactly_at_the_prior(pitch):
    """envmap.prior_parts (the on-set HDRI's split): without the prior, plus its weight times
    the prior's level, is the map, leaning or not."""
    plate = warm_plate(7)
    env, table = maps(pitch, plate)[True]
    without, weight = prior_parts(table, plate)
    mean = plate.reshape(-1, 3).astype(np.float64).mean(0)
    level = PLATE_SKY_GAIN * float(mean @ LUMA)
    colour = (1 - PLATE_SKY_TINT) + PLATE_SKY_TINT * mean / float(mean @ LUMA)
    rebuilt = without + (1 - table.fill.lean) * weight[..., None] * level * colour
    np.testing.assert_allclose(rebuilt, env, rtol=0.02, atol=2e-3)
