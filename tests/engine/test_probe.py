"""An on-set HDRI in place of the sky prior (probe.py, envmap.prior_parts): the map splits
exactly at the prior, the probe is read in Blender's equirectangular layout along the right
directions, and where the plate shows the surroundings the map stays the plate's."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, lookup_table
from virtual_reflections.envmap import apply_table, prior_parts
from virtual_reflections.fill import sky_level
from virtual_reflections.layouts import texel_directions
from virtual_reflections.probe import Probe, exposure_ratio, sample, shrink_to, with_probe

W, H = 160, 90
F = 0.5 * W / math.tan(math.radians(30))
INTRINSICS = (F, F, W / 2, H / 2)
# Camera frame -> Blender world for a camera at the origin looking along world +Y, level:
# camera +Z (ahead) = world +Y, camera +Y (up) = world +Z, camera +X (the plate's left) = -X.
LEVEL = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


def up_when_pitched(deg):
    a = math.radians(deg)
    return (0.0, math.cos(a), -math.sin(a))


def pitched(deg):
    """Camera frame -> world for that camera pitched ``deg`` down."""
    a = math.radians(deg)
    tilt = np.array([[1, 0, 0], [0, math.cos(a), math.sin(a)], [0, -math.sin(a), math.cos(a)]])
    return LEVEL @ tilt.T


def test_the_probe_is_read_in_blenders_layout():
    """World +X is the centre column, +Y a quarter of the width to its left, the zenith the
    top row, the nadir the bottom one."""
    h, w = 64, 128
    img = np.zeros((h, w, 3), np.float32)
    img[:, w // 2 - 1 : w // 2 + 1, 0] = 1.0  # +X
    img[:, w // 4 - 1 : w // 4 + 1, 1] = 1.0  # +Y
    img[0, :, 2] = 1.0  # the zenith
    dirs = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [-1.0, 0, 0]])
    got = sample(img, dirs)
    assert got[0, 0] == pytest.approx(1.0) and got[0, 1] == 0
    assert got[1, 1] == pytest.approx(1.0) and got[1, 0] == 0
    assert got[2, 2] == pytest.approx(1.0)
    assert got[3].sum() == 0


def ground_band_params(pitch, texture=0.0):
    """Camera View with the world's horizon and the ground band's neutral prior at 1.6 (the
    prior these tests split; Auto's from the plate is split alike)."""
    return Params(
        method="camera",
        intrinsics=INTRINSICS,
        up=up_when_pitched(pitch),
        sky_gain=1.6,
        sky_from_plate=0.0,
        sky_tint_share=0.0,
        sky_texture=texture,
    )


def test_the_map_splits_exactly_at_the_prior():
    """Without the prior, plus the weight times the prior's level, is the map."""
    rng = np.random.default_rng(5)
    plate = (0.1 + 0.3 * rng.random((H, W, 3))).astype(np.float32)
    params = ground_band_params(30)
    table = lookup_table(W, H, (60, 30, 100, 60), params, "latlong", 256)
    env = apply_table(table, plate)
    without, weight = prior_parts(table, plate)
    level = 1.6 * sky_level(plate)
    # the fill reads a coarser level of the plate's pyramid: take its level from the split
    d = texel_directions("latlong", 256)
    up = d @ np.array(up_when_pitched(30)) > math.cos(math.radians(10))
    assert weight[up].min() > 0.99  # straight up, nothing but the prior
    implied = ((env - without)[up].mean(-1) / weight[up]).mean()
    assert implied == pytest.approx(level, rel=0.05)
    np.testing.assert_allclose(without + weight[..., None] * implied, env, atol=2e-5)
    ahead = d[..., 2] > math.cos(math.radians(3))
    assert weight[ahead].max() < 1e-4  # what the plate shows owes nothing to the prior


def test_the_split_leaves_the_plates_texture_on_the_sky_out():
    """With Sky Texture on, the prior's parts are those of the flat prior: an HDRI put in its
    place (probe.py) brings its own structure, not the plate's on top."""
    rng = np.random.default_rng(6)
    plate = (0.1 + 0.3 * rng.random((H, W, 3))).astype(np.float32)
    flat, textured = ground_band_params(30), ground_band_params(30, texture=1.0)
    parts = [
        prior_parts(lookup_table(W, H, (60, 30, 100, 60), p, "latlong", 256), plate)
        for p in (flat, textured)
    ]
    for a, b in zip(*parts):
        np.testing.assert_array_equal(a, b)
    env = apply_table(lookup_table(W, H, (60, 30, 100, 60), textured, "latlong", 256), plate)
    assert not np.allclose(env, apply_table(lookup_table(W, H, (60, 30, 100, 60), flat,
                                                         "latlong", 256), plate))  # fmt: skip


def test_no_prior_without_a_horizon():
    plate = np.full((H, W, 3), 0.2, np.float32)
    table = lookup_table(
        W, H, (60, 30, 100, 60), Params(method="camera", intrinsics=INTRINSICS), "latlong", 128
    )
    assert prior_parts(table, plate) is None


def test_the_probe_fills_the_unseen_sky_along_the_right_directions():
    """A probe bright in the world's +Z (zenith) and dark below, red toward world -Y (behind
    the camera): the map straight up is the zenith's, behind and above it is red, ahead it is
    still the plate."""
    h, w = 128, 256
    img = np.zeros((h, w, 3), np.float32)
    img[: h // 8] = (4.0, 4.0, 4.0)  # within 22.5 degrees of the zenith
    img[h // 8 : h // 2, 3 * w // 4 - 16 : 3 * w // 4 + 16] = (2.0, 0.0, 0.0)  # toward -Y
    probe = Probe(img, pitched(30))
    plate = np.full((H, W, 3), 0.2, np.float32)
    params = ground_band_params(30)
    table = lookup_table(W, H, (60, 30, 100, 60), params, "latlong", 256)
    without, weight = prior_parts(table, plate)
    env = with_probe(without, weight, probe.latlong(256))
    d = texel_directions("latlong", 256)
    world = d @ pitched(30).T
    zenith = world[..., 2] > math.cos(math.radians(10))
    assert env[zenith].mean(0) == pytest.approx((4.0, 4.0, 4.0), rel=0.02)
    behind = (world[..., 1] < -0.9) & (world[..., 2] > math.sin(math.radians(12)))
    assert behind.any()
    red = env[behind].mean(0)
    assert red[0] > 1.5 and red[1] < 0.1 * red[0]
    ahead = d[..., 2] > math.cos(math.radians(3))
    np.testing.assert_allclose(env[ahead], 0.2, atol=1e-4)


def test_the_exposure_check_compares_the_sky_both_show():
    """A level camera: the plate's upper half is the probe's sky times 2 -> ratio 2. A camera
    looking 40 degrees down sees no sky: no comparison."""
    h, w = 64, 128
    img = np.full((h, w, 3), 0.5, np.float32)
    img[: h // 2] = (1.0, 1.2, 1.5)
    probe = Probe(img, LEVEL)
    plate = np.full((H, W, 3), 0.3, np.float32)
    plate[: H // 2] = 2.0 * np.array((1.0, 1.2, 1.5), np.float32)
    assert exposure_ratio(plate, INTRINSICS, up_when_pitched(0), probe) == pytest.approx(
        2.0, rel=1e-3
    )
    assert exposure_ratio(plate, INTRINSICS, up_when_pitched(40), probe) is None


def test_a_bad_probe_is_refused():
    with pytest.raises(ValueError, match="NaN"):
        Probe(np.full((8, 16, 3), np.nan, np.float32), np.eye(3))
    with pytest.raises(ValueError, match="rotation"):
        Probe(np.zeros((8, 16, 3), np.float32), 2 * np.eye(3))
    with pytest.raises(ValueError, match="shape"):
        Probe(np.zeros((8, 16), np.float32), np.eye(3))


def test_the_whole_unseen_sky_is_the_prior():
    """A level camera sees sky in its top half; behind it, above the horizon, the map is the
    prior alone (not the plate's sky continued), so the probe takes all of it; what the plate
    shows stays the plate's, and below the horizon the prior has no part."""
    rng = np.random.default_rng(2)
    plate = (0.2 + 0.2 * rng.random((H, W, 3))).astype(np.float32)
    params = ground_band_params(0)
    table = lookup_table(W, H, (60, 30, 100, 60), params, "latlong", 256)
    d = texel_directions("latlong", 256)
    behind = (d[..., 2] < -0.9) & (d[..., 1] > math.sin(math.radians(3)))
    ahead = d[..., 2] > math.cos(math.radians(3))
    below = d[..., 1] < -math.sin(math.radians(3))
    without, weight = prior_parts(table, plate)
    assert weight[behind].min() > 0.99
    assert weight[ahead].max() < 1e-4 and weight[below].max() < 1e-4
    env = apply_table(table, plate)
    np.testing.assert_allclose(without[below], env[below], atol=1e-5)


def test_a_probe_wider_than_the_map_is_box_filtered_first():
    """A 512-wide HDRI on a 64-wide map: a one-texel sun is averaged over its 8 x 8 block
    (not missed between the map's samples), and a constant stays constant."""
    img = np.full((256, 512, 3), 0.25, np.float32)
    img[100, 300] = 1000.0
    on_map = Probe(img, np.eye(3)).latlong(64)
    assert on_map.shape == (32, 64, 3)

    def energy(image):  # above the constant, summed over solid angle
        h, w = image.shape[:2]
        lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
        omega = np.cos(lat)[:, None] * (np.pi / h) * (2 * np.pi / w)
        return float(((image[..., 0] - 0.25) * omega).sum())

    assert energy(on_map) == pytest.approx(energy(img), rel=0.5)
    assert np.median(on_map) == pytest.approx(0.25, rel=1e-5)


def test_an_hdri_wider_than_any_map_is_kept_shrunk_with_its_energy():
    """`shrink_to`: no wider than asked, by whole blocks (a width not a multiple keeps the
    blocks that fit), the mean radiance kept, a small sun's energy kept; an image already
    narrow enough unchanged."""
    rng = np.random.default_rng(3)
    hdri = rng.random((1000, 2000, 3)).astype(np.float32)
    hdri[400, 1200] = 5e4  # a sun one pixel wide
    small = shrink_to(hdri, 512)
    assert small.shape == (250, 500, 3)
    np.testing.assert_allclose(small.mean((0, 1)), hdri.mean((0, 1)), rtol=1e-4)
    assert small.max() == pytest.approx(5e4 / 16, rel=1e-3)
    narrow = shrink_to(hdri[:, :400], 512)
    np.testing.assert_array_equal(narrow, hdri[:, :400])
