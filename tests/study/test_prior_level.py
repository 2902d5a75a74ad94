"""`prior_level.band_levels` reads the plate's ground band as the engine's fill does: below the
world's horizon of a camera pitched down, not the sky above it (no bpy)."""

import math

import numpy as np
import pytest

from study.scenes3d import prior_level
from virtual_reflections.params import SKY_GAINS


def test_the_band_is_the_ground_below_the_horizon_of_a_camera_looking_down():
    width, height, hfov, pitch = 320, 180, 60.0, 10.0
    f = (width / 2) / math.tan(math.radians(hfov / 2))
    horizon = int(height / 2 - f * math.tan(math.radians(pitch)))  # the row at elevation 0
    plate = np.full((height, width, 3), 0.2, np.float32)
    plate[: horizon - 4] = 5.0  # a bright sky above the horizon
    plate[-40:, ::2] = 0.05  # a textured foreground, inside the band 5-40 degrees down
    levels = prior_level.band_levels(plate, hfov, pitch)
    assert 0.05 < levels["log_average"] < levels["mean"] < 0.2  # the sky is not in it
    # Looking up 30 degrees, no pixel lies in the band: the whole plate's level (the sky in it)
    # over Auto's gain (`fill.prior_level`)
    up = prior_level.band_levels(plate, hfov, -30.0)
    whole = float((plate.reshape(-1, 3) @ [0.2126, 0.7152, 0.0722]).mean()) / SKY_GAINS["auto"]
    assert up["mean"] == pytest.approx(whole, rel=1e-3)


def test_the_statistic_table_needs_the_auto_gain():
    assert "Auto gain only" in prior_level.statistic_table({"sky_gain": 1.0, "scenes": []})
    assert "Auto gain only" in prior_level.statistic_table({"surroundings": "open", "scenes": []})


def test_the_scales_hold_one():
    assert prior_level.SCALES[50] == pytest.approx(1.0)


def test_each_scene_s_own_best_gain_is_where_its_curve_peaks():
    curve = -((np.log(prior_level.SCALES) - math.log(2.0)) ** 2)  # peaks at twice Auto's gain
    data = {"scenes": [{"scene": {"name": "s1"}, "split": {"prior_scales": list(curve)}}]}
    assert prior_level.scene_gains(data)["s1"] == pytest.approx(2 * SKY_GAINS["auto"], rel=0.05)
    assert prior_level.scene_gains_line(data).startswith("Each scene's own best gain: s1 3.")
    assert "Auto gain only" in prior_level.scene_gains_line({"sky_gain": 1.0, "scenes": []})
