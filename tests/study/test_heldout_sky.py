"""The held-out fit of the unseen sky (study/scenes3d/heldout_sky.py): leave-one-HDRI-out picks
each group's constants on the other groups only, and the estimates' composites are exact where
they should be."""

import numpy as np
import pytest

from study.scenes3d import heldout_sky


def test_loho_fits_each_group_on_the_others_only():
    scores = np.array(
        [
            [3.0, 0.0],  # a
            [3.0, 0.0],  # a
            [0.0, 2.0],  # b
            [0.0, 5.0],  # c
        ]
    )
    groups = ["a", "a", "b", "c"]
    held, chosen = heldout_sky.loho(scores, groups, [0, 1])
    # a is fitted on b and c (column means 0, 3.5), b on a, a, c (2, 1.67), c on a, a, b (2, 0.67)
    assert list(chosen) == [1, 1, 0, 0]
    assert list(held) == [0.0, 0.0, 0.0, 0.0]  # each scored on its own scenes only
    # restricted to one column there is nothing to fit
    held, chosen = heldout_sky.loho(scores, groups, [1])
    assert list(chosen) == [1, 1, 1, 1] and list(held) == [0.0, 0.0, 2.0, 5.0]


def test_the_safe_fit_avoids_a_column_with_a_deep_loss():
    # c held out, fitted on a and b: column 0's mean (5 - 3) / 2 = 1.0 beats column 1's 0.8,
    # but b loses 3 dB there: less twice the mean shortfall below -1 dB, 1.0 - 2 = -1.0
    scores = np.array([[5.0, 0.8], [-3.0, 0.8], [0.0, 0.0]])
    groups = ["a", "b", "c"]
    _, plain = heldout_sky.loho(scores, groups, [0, 1])
    _, safe = heldout_sky.loho(scores, groups, [0, 1], safe=True)
    assert plain[2] == 0 and safe[2] == 1


def scene():
    rng = np.random.default_rng(3)
    dark = rng.random((6, 8, 3)) * 0.2
    today = np.array([0.3, 0.32, 0.35])
    part = np.zeros((6, 8, 3))
    part[:3] = today  # the prior's pixels: the upper rows
    return {
        "dark": dark,
        "part": part,
        "full": dark + part,
        "mean": np.full((6, 8, 3), 0.25),
        "today": today,
        "top": np.array([0.5, 0.6, 0.9]),
        "plate_mean": np.array([0.2, 0.2, 0.1]),
        "sky": part.sum(-1) > 0.02,
        "camera": rng.random((6, 8, 3)),  # the camera view's mirror: the plate's structure
    }


def test_the_defaults_own_estimate_reproduces_its_render_and_a_colour_lands_exactly():
    d = scene()
    today = heldout_sky.composite(d, 1.0, "today's level", "plate mean", 0.0, 0.0)
    assert np.allclose(today, d["full"])
    # the plate mean's level and chromaticity in full: the prior's pixels are that colour times g
    got = heldout_sky.composite(d, 2.0, "plate mean's level", "plate mean", 1.0, 0.0)
    assert np.allclose(got[:3], 2.0 * d["plate_mean"] + d["dark"][:3])
    assert np.allclose(got[3:], d["dark"][3:])
    # a full fall-back is the plate-mean world's mirror
    assert np.allclose(heldout_sky.composite(d, 1.0, "today's level", "top rows", 0.5, 1.0), 0.25)
    # the disagreement's fall-back: beta |ln(today's level / the plate mean's)|, at most 1
    lum = heldout_sky.lum
    w = min(1.0, 0.25 * abs(np.log(lum(d["today"]) / lum(d["plate_mean"]))))
    got = heldout_sky.composite(d, 1.0, "today's level", "plate mean", 0.0, "b0.25")
    assert np.allclose(got, (1 - w) * d["full"] + w * d["mean"]) and 0 < w < 1


def test_every_family_holds_the_defaults_own_estimate_or_a_plate_cue():
    first = heldout_sky.FAMILIES["today's level × g, neutral (the default's form)"]
    assert (1.0, "today's level", "plate mean", 0.0, 0.0, 0.0) in [
        (pytest.approx(g), *rest) for g, *rest in first
    ]
    assert len({len(p) for f in heldout_sky.FAMILIES.values() for p in f}) == 1


def test_the_camera_views_structure_is_levelled_to_the_estimate():
    d = scene()
    sky = d["sky"]
    got = heldout_sky.composite(d, 1.0, "today's level", "plate mean", 0.0, 0.0, 1.0)
    seen = d["camera"][sky]
    level = heldout_sky.lum(d["today"]) / (seen @ heldout_sky.LUMA).mean()
    assert np.allclose(got[sky], level * seen)  # the structure, at today's mean luminance
    assert np.allclose((got[sky] @ heldout_sky.LUMA).mean(), heldout_sky.lum(d["today"]))
    assert np.allclose(got[~sky], d["full"][~sky])  # below the sky: untouched
    half = heldout_sky.composite(d, 1.0, "today's level", "plate mean", 0.0, 0.0, 0.5)
    assert np.allclose(half, 0.5 * (got + d["full"]))


def test_todays_prior_is_the_level_the_engine_sets():
    """heldout_sky.prior_as_set (the prior each estimate is scaled from, for renders made
    while Auto took the ground band) is that map's own sky straight up, from the study's band
    levels of the same plate (a camera 30 degrees down: no sky in view)."""
    import math

    from study.scenes3d import prior_level
    from virtual_reflections import Params, lookup_table
    from virtual_reflections.envmap import apply_table
    from virtual_reflections.layouts import texel_directions
    from virtual_reflections.methods import SKY_GAINS

    w, h, hfov, pitch = 160, 90, 60.0, 30.0
    f = 0.5 * w / math.tan(math.radians(hfov / 2))
    a = math.radians(pitch)
    up = (0.0, math.cos(a), -math.sin(a))
    rng = np.random.default_rng(2)
    plate = (0.05 + 0.4 * rng.random((h, w, 3)) ** 3).astype(np.float32)  # a skewed ground
    params = Params(
        method="camera",
        intrinsics=(f, f, w / 2, h / 2),
        up=up,
        sky_gain=SKY_GAINS["auto"],
        sky_from_plate=0.0,
        sky_tint_share=0.0,
    )
    env = apply_table(lookup_table(w, h, (60, 30, 100, 60), params, "latlong", 256), plate)
    d = texel_directions("latlong", 256)
    sky = env[d @ np.array(up) > math.cos(math.radians(10))].mean(0)
    band = prior_level.band_levels(plate, hfov, pitch)
    assert float(sky.mean()) == pytest.approx(heldout_sky.prior_as_set(band), rel=0.02)
    assert band["log_average"] < heldout_sky.prior_as_set(band) / 1.6 < band["mean"]


def test_the_floor_fit_takes_the_best_mean_whose_worst_scene_stays_above_the_floor():
    """`pick_under_floor`: column 0 has the best mean but a scene 3 dB under; column 1 keeps
    every scene above -1 dB; column 2 is safe but poorer. With nothing above the floor, the
    best worst scene. `loho_floor` picks on the other HDRIs' scenes and scores the held-out's."""
    from study.scenes3d import heldout_sky

    scores = np.array([[4.0, 1.5, 0.5], [3.0, 1.0, 0.2], [-3.0, -0.5, 0.1]])
    assert heldout_sky.pick_under_floor(scores) == 1
    assert heldout_sky.pick_under_floor(scores - 5.0) == 2  # none above: the best worst
    groups = np.array(["a", "b", "c"])
    held, chosen = heldout_sky.loho_floor(scores, groups)
    # without c's -3 dB scene, column 0 is safe on a and b: c is scored with it
    assert list(chosen) == [1, 1, 0]
    np.testing.assert_allclose(held, [1.5, 1.0, -3.0])


def test_plate_sky_takes_its_hue_from_grey_whatever_the_rendered_prior():
    """`plate_sky` sets the prior's pixels to gain x the plate mean's luminance, its hue `tint`
    of the way from grey (the engine's `fill.sky_prior`), whether the render's own prior was
    neutral (the earlier Auto) or already the plate's colour: a render made with the recipe
    comes back unchanged."""
    from study.scenes3d import heldout_sky

    plate_mean = np.array([0.3, 0.2, 0.1])
    level = float(plate_mean @ heldout_sky.LUMA)
    weight = np.array([[0.0], [0.5], [1.0]])
    expected = 1.4 * level * (0.25 + 0.75 * plate_mean / level)
    for today in (np.full(3, 0.2), expected):
        d = {"plate_mean": plate_mean, "today": today, "dark": np.zeros((3, 3)),
             "part": weight * today}  # fmt: skip
        np.testing.assert_allclose(heldout_sky.plate_sky(d, 1.4, 0.75), weight * expected)
