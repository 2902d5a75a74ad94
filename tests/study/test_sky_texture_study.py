"""The study of the unseen sky's texture (study/scenes3d/sky_texture.py): the held-out pick
respects the floor and never sees its own group, the texture keeps the estimate's
log-average, and the plate's skyline is lent from the right side of the plate."""

import math

import numpy as np

from study.scenes3d import heldout_sky, sky_texture


def test_the_held_out_pick_keeps_the_floor_and_never_sees_its_group():
    # column 1 has the best mean but a scene of group "b" falls below the floor: only when
    # "b" is held out (so unseen) may column 1 be chosen, for "b"'s own scenes.
    psnr = np.array([[0.5, 2.0], [0.5, 2.0], [0.4, -3.0], [0.6, 2.0]])
    groups = np.array(["a", "a", "b", "c"])
    chosen = sky_texture.held_out_picks(psnr, psnr, groups)
    assert chosen.tolist() == [0, 0, 1, 0]
    # an objective of its own (FLIP, lower better: negated) under the same floor
    flip = np.array([[0.5, 0.4], [0.5, 0.4], [0.5, 0.4], [0.5, 0.4]])
    assert sky_texture.held_out_picks(psnr, -flip, groups).tolist() == [0, 0, 1, 0]


def test_textured_keeps_the_estimates_log_average_and_off_is_the_flat_sky():
    rng = np.random.default_rng(5)
    part = np.zeros((6, 8, 3))
    part[:3] = 0.3
    d = {
        "dark": rng.random((6, 8, 3)) * 0.1,
        "part": part,
        "today": np.full(3, 0.3),
        "plate_mean": np.array([0.3, 0.25, 0.2]),
        "sky": part.sum(-1) > 0.02,
    }
    d["texture"] = np.log(0.5 + 0.5 * rng.random(int(d["sky"].sum())))  # within the clip
    flat = sky_texture.textured(d, 1.4, 0.75, 0.0)
    np.testing.assert_allclose(flat, heldout_sky.plate_sky(d, 1.4, 0.75))
    got = sky_texture.textured(d, 1.4, 0.75, 1.0)
    sky = d["sky"]
    ratio = np.log((got - d["dark"])[sky] / (flat - d["dark"])[sky])
    np.testing.assert_allclose(ratio.mean(), 0.0, atol=1e-9)  # the log-average: the estimate's
    assert ratio.std() > 0.1
    np.testing.assert_allclose(got[~sky], flat[~sky])


def test_the_plates_skyline_is_lent_from_its_nearer_edge():
    """A plate bright on its left (+Y azimuth here), dark on its right: directions just past
    its left edge take the bright side, past its right edge the dark side."""
    az = np.radians(np.linspace(-30, 30, 61))
    el = np.radians(np.linspace(-10, 20, 31))
    a, e = np.meshgrid(az, el)
    dirs = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1)
    plate = np.where(a[..., None] > 0, 0.8, 0.05) * np.ones(3)
    past = math.radians(40)
    wanted = np.array(
        [[math.cos(past), math.sin(past), 0.1], [math.cos(past), -math.sin(past), 0.1]]
    )
    wanted /= np.linalg.norm(wanted, axis=1, keepdims=True)
    t = sky_texture.plate_texture(plate, dirs, wanted)
    assert t[0] > t[1] + 2.0
