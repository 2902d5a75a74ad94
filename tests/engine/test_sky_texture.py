"""The unseen sky given the plate's own texture (`Params.sky_texture`, sky_texture.py): on by
default (methods.SKY_TEXTURE), none at 0, the prior's log-average kept, the contrast in
proportion to the share, the skyline continued around the camera mirrored at the plate's
edges in a band that fades out above the plate, a sun clipped, the ground and the plate's own
view untouched, every gather back end alike."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, lookup_table
from virtual_reflections.envmap import apply_table
from virtual_reflections.layers import SkyTexture
from virtual_reflections.layouts import texel_directions
from virtual_reflections.methods import SKY_TEXTURE
from virtual_reflections.sky_texture import (
    SKY_TEXTURE_CLIP,
    SKY_TEXTURE_FADE_DEG,
    fold,
    folded,
    solid_angles,
)

W, H = 160, 90
F = 0.5 * W / math.tan(math.radians(30))  # 60 degrees across
INTRINSICS = (F, F, W / 2, H / 2)
UP = (0.0, 1.0, 0.0)  # a level camera: the horizon through the plate's middle
BOX = (60, 30, 100, 60)
LUMA = np.array([0.2126, 0.7152, 0.0722])


def plate_with_skyline(seed=1):
    """Random texture, the upper half bright on the plate's left (+X) and dark on its right."""
    rng = np.random.default_rng(seed)
    plate = (0.1 + 0.4 * rng.random((H, W, 3))).astype(np.float32)
    plate[: H // 2, : W // 2] *= 2.0  # image column 0 is the plate's left
    plate[: H // 2, W // 2 :] *= 0.5
    return plate


def env(plate, k, layout="latlong", size=256, method="camera"):
    ground = {"ground": (0.0, -1.0, 5.0, 0.5)} if method == "ground" else {}
    params = Params(method=method, intrinsics=INTRINSICS, up=UP, sky_texture=k, **ground)
    table = lookup_table(W, H, BOX, params, layout, size)
    return apply_table(table, plate), table


@pytest.mark.parametrize("layout, size", [("latlong", 256), ("cube", 64)])
def test_on_by_default_off_at_0_and_only_the_unseen_sky_changes(layout, size):
    plate = plate_with_skyline()
    flat, table = env(plate, 0.0, layout, size)
    assert not any(isinstance(layer, SkyTexture) for layer in table.layers)
    default = apply_table(lookup_table(W, H, BOX, Params(method="camera", intrinsics=INTRINSICS,
                                                         up=UP), layout, size), plate)  # fmt: skip
    np.testing.assert_array_equal(default, env(plate, SKY_TEXTURE, layout, size)[0])
    assert not np.allclose(default, flat)
    textured, table = env(plate, 0.5, layout, size)
    assert any(isinstance(layer, SkyTexture) for layer in table.layers)
    d = texel_directions(layout, size).reshape(flat.shape)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)  # a cube's are not unit
    below = d[..., 1] < 0.0
    np.testing.assert_array_equal(textured[below], flat[below])
    changed = (textured != flat).any(-1)
    elevation = np.degrees(np.arcsin(np.clip(d[..., 1], -1, 1)))
    band = (elevation > 3) & (elevation < 15)  # the skyline's band, all round
    assert changed[band].mean() > 0.75  # all but the plate's own view (60 of 360 degrees)
    top = math.degrees(math.atan(H / 2 / F))  # the plate's highest elevation (18 degrees)
    assert not changed[elevation > top + SKY_TEXTURE_FADE_DEG + 1].any()  # the sky above: flat
    if layout == "latlong":  # (a cube's output faces are in the map's frame, not these)
        ahead = d[..., 2] > math.cos(math.radians(10))  # inside the plate's view
        np.testing.assert_array_equal(textured[ahead], flat[ahead])


@pytest.mark.parametrize("layout, size", [("latlong", 256), ("cube", 64)])
def test_the_log_average_is_the_priors_and_the_contrast_grows_with_the_share(layout, size):
    plate = plate_with_skyline()
    flat, _ = env(plate, 0.0, layout, size)
    d = texel_directions(layout, size).reshape(flat.shape)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)  # a cube's are not unit
    ids = np.arange(d.shape[0] * d.shape[1])
    weight = solid_angles(layout, size, ids).reshape(flat.shape[:2])
    sky = d[..., 1] > 0.0
    sky &= (d[..., 2] < math.cos(math.radians(40))) if layout == "latlong" else True
    fade = np.clip(1 - (np.degrees(np.arcsin(np.clip(d[..., 1], -1, 1))) - math.degrees(
        math.atan(H / 2 / F))) / SKY_TEXTURE_FADE_DEG, 0, 1)  # fmt: skip
    spread = {}
    for k in (0.25, 0.5, 1.0):
        textured, _ = env(plate, k, layout, size)
        ratio = np.log((textured[sky] @ LUMA) / (flat[sky] @ LUMA))
        w = (weight * fade)[sky] / (weight * fade)[sky].sum()
        assert abs(float(w @ ratio)) < 0.03, k  # the sky's log-average: the prior's
        assert np.abs(ratio).max() <= k * SKY_TEXTURE_CLIP + 1e-4
        spread[k] = ratio.std()
    assert spread[0.25] > 0.02
    assert spread[0.5] == pytest.approx(2 * spread[0.25], rel=0.1)
    assert spread[1.0] == pytest.approx(2 * spread[0.5], rel=0.1)


def test_the_skyline_continues_mirrored_at_the_plates_edges():
    """Just past the plate's left edge the sky is the left half's (bright), past its right
    edge the right half's (dark): the view folded back at each edge, no seam."""
    plate = plate_with_skyline()
    flat, _ = env(plate, 1.0, "latlong", 512)
    prior, _ = env(plate, 0.0, "latlong", 512)
    d = texel_directions("latlong", 512).reshape(flat.shape)
    azimuth = np.degrees(np.arctan2(d[..., 0], d[..., 2]))  # + toward the plate's left
    low = (d[..., 1] > math.sin(math.radians(3))) & (d[..., 1] < math.sin(math.radians(15)))
    gain = (flat @ LUMA) / (prior @ LUMA)
    left = gain[low & (azimuth > 35) & (azimuth < 45)].mean()
    right = gain[low & (azimuth < -35) & (azimuth > -45)].mean()
    assert left > 1.5 * right


def test_fold_reflects_back_and_forth_without_a_seam():
    lo, hi = -0.5, 0.5
    a = np.linspace(-7.0, 7.0, 20001)
    f = fold(a, lo, hi)
    assert f.min() >= lo - 1e-12 and f.max() <= hi + 1e-12
    np.testing.assert_allclose(fold(np.array([-0.2, 0.3]), lo, hi), [-0.2, 0.3])  # inside: kept
    np.testing.assert_allclose(fold(np.array([0.6, -0.7]), lo, hi), [0.4, -0.3])  # mirrored
    assert np.abs(np.diff(f)).max() <= np.diff(a).max() + 1e-9  # continuous: no jump


def test_folded_directions_keep_their_elevation_and_land_in_the_view():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    up = np.array([0.0, math.cos(0.2), -math.sin(0.2)])  # pitched down a little
    out, fade = folded(d, W, H, INTRINSICS, up)
    np.testing.assert_allclose(out @ up, d @ up, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-5)
    half = math.atan(W / 2 / F) + 0.02
    level = out - (out @ up)[:, None] * up
    forward = np.array([0.0, 0.0, 1.0]) - up[2] * up
    cosine = (level @ forward) / np.linalg.norm(level, axis=1) / np.linalg.norm(forward)
    assert np.arccos(np.clip(cosine, -1, 1)).max() < half  # within the plate's azimuths


def test_a_sun_is_clipped():
    """A blazing patch in the sky of the plate makes no texel of the unseen sky more than
    e^(k clip) times the prior."""
    plate = plate_with_skyline()
    plate[5:10, 60:70] = 5000.0
    flat, _ = env(plate, 1.0)
    prior, _ = env(plate, 0.0)
    gain = (flat @ LUMA) / (prior @ LUMA)
    assert gain.max() <= math.exp(SKY_TEXTURE_CLIP) * 1.001


def test_the_ground_method_keeps_the_texture():
    plate = plate_with_skyline()
    textured, table = env(plate, 0.5, method="ground")
    flat, _ = env(plate, 0.0, method="ground")
    assert any(isinstance(layer, SkyTexture) for layer in table.layers)
    d = texel_directions("latlong", 256).reshape(flat.shape)
    sky = (d[..., 1] > 0.05) & (d[..., 2] < 0.0)
    assert not np.allclose(textured[sky], flat[sky])
    np.testing.assert_array_equal(textured[d[..., 1] < 0.0], flat[d[..., 1] < 0.0])


@pytest.mark.parametrize("k", [-0.1, 1.5, float("nan")])
def test_a_share_outside_0_1_is_refused(k):
    with pytest.raises(ValueError, match="sky_texture"):
        Params(method="camera", sky_texture=k)


def test_a_rough_surface_sees_less_of_the_texture():
    """params.sky_texture_for: the artist's share for a mirror, falling linearly to none at
    AUTO_SKY_ROUGHNESS, as Auto's sky turns to the rough one's."""
    from virtual_reflections.params import AUTO_SKY_ROUGHNESS, sky_texture_for

    assert sky_texture_for(0.75, 0.0) == 0.75
    assert sky_texture_for(0.75, AUTO_SKY_ROUGHNESS / 2) == pytest.approx(0.375, abs=1e-4)
    assert sky_texture_for(0.75, AUTO_SKY_ROUGHNESS) == 0.0
    assert sky_texture_for(0.75, 0.35) == 0.0
    assert sky_texture_for(0.0, 0.0) == 0.0
