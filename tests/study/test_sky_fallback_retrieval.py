"""The safe fall-back's and the retrieval's held-out study (study/scenes3d/sky_fallback.py,
sky_retrieval.py): the fall-back's cue, threshold and share are fitted on the other HDRIs
only, and the retrieval reads a lat-long as Cycles does and never retrieves the scene's own."""

import math

import numpy as np

from study.scenes3d import heldout_sky, sky_fallback, sky_retrieval


def test_the_fallback_leans_only_past_a_threshold_fitted_on_the_other_hdris():
    # shares: W = 0 (the estimate) .. 1 (the plate-mean world, 0 dB)
    lean = np.linspace(1, 0, len(sky_fallback.SHARES))
    good, bad = 2.0 * lean, -3.0 * lean  # a scene the estimate helps, one it hurts
    scores = np.array([good, good, bad, bad, good, bad])[:, None, :]
    cue = np.array([[0.1], [0.2], [0.9], [0.8], [0.15], [0.85]])  # high cue: hurt
    groups = ["a", "a", "b", "c", "d", "e"]
    held, chosen, leaned = sky_fallback.fit_fallback(scores, cue, groups)
    # every fold learns "lean fully where the cue is high" from the others and applies it
    assert list(leaned) == [False, False, True, True, False, True]
    assert list(held) == [2.0, 2.0, 0.0, 0.0, 2.0, 0.0]
    for _, c, side, t, k in chosen:
        assert c == 0 and side == 1 and 0.2 < t < 0.8 and sky_fallback.SHARES[k] == 1.0
    # with only helped scenes to learn from, the held-out hurt scene is not leaned on
    held, _, leaned = sky_fallback.fit_fallback(scores[[0, 1, 4, 2]], cue[[0, 1, 4, 2]],
                                                ["a", "b", "d", "c"])  # fmt: skip
    assert not leaned.any() and held[3] == -3.0


def test_ground_share_is_the_rows_below_the_horizon():
    assert sky_fallback.ground_share(50.0, 0.0) == 0.5  # a level camera
    assert sky_fallback.ground_share(50.0, 40.0) == 1.0  # looking down past half the field
    assert 0.5 < sky_fallback.ground_share(50.0, 5.0) < 0.7


def test_sample_reads_a_lat_long_as_cycles_environment_texture():
    h, w = 8, 16
    image = np.zeros((h, w, 3), np.float32)
    image[..., 0] = np.arange(w)[None, :]  # the column
    image[..., 1] = np.arange(h)[:, None]  # the row, 0 at the top
    up, plus_x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    assert sky_retrieval.sample(image, up)[1] == 0  # straight up: the top row
    # +X is the image's middle column (u = 0.5), on the horizon's row; -X its first
    c = sky_retrieval.sample(image, plus_x)
    assert c[0] == w // 2 and c[1] == h // 2
    assert sky_retrieval.sample(image, -plus_x)[0] == 0
    # a turn of the world about +Z by 90 degrees shows -Y where +X was
    turned = sky_retrieval.sample(image, np.array([0.0, -1.0, 0.0]), math.pi / 2)
    assert turned[0] == c[0]


def test_retrieval_never_returns_the_scenes_own_hdri():
    rng = np.random.default_rng(0)
    own = rng.uniform(0.1, 1.0, (16, 32, 3)).astype(np.float32)
    other = np.full((16, 32, 3), 0.5, np.float32)
    dirs = sky_retrieval.unit(rng.uniform(0.5, 1.0, (6, 8, 3)))  # all above the horizon
    plate = np.clip(sky_retrieval.sample(own, dirs), 0, 1)
    alpha = np.zeros((6, 8))
    hdris = {"own": own, "other": other}
    assert sky_retrieval.retrieve(plate, dirs, alpha, hdris, None)[0] == "own"
    assert sky_retrieval.retrieve(plate, dirs, alpha, hdris, "own")[0] == "other"


def test_a_flat_structure_reproduces_the_flat_estimate():
    d = {
        "today": np.array([0.5, 0.5, 0.5]),
        "plate_mean": np.array([0.3, 0.4, 0.5]),
        "dark": np.zeros((2, 2, 3)),
        "part": np.full((2, 2, 3), 0.25),
        "sky": np.array([[True, False], [True, True]]),
    }
    d["structure"] = np.ones((3, 3)) / heldout_sky.lum(np.ones(3))  # luminance 1 everywhere
    for mode in sky_retrieval.MODES:
        got = sky_retrieval.composite(d, 2.0, "today's level", 0.0, 1.0, mode)
        assert np.allclose(got, 2.0 * 0.25)  # the neutral estimate at twice today's level
