"""The map pre-filtered for a rough material (virtual_reflections/prefilter.py)."""

import numpy as np
import pytest

from virtual_reflections.ggx_lobe import ggx_annuli
from virtual_reflections.prefilter import SHARP, lobe_sigmas, prefilter_latlong

H, W = 128, 256


def directions():
    """(H, W, 3) unit directions of the lat-long texel centres (docs/conventions.md)."""
    lon = -2 * np.pi * ((np.arange(W) + 0.5) / W - 0.5)
    lat = -np.pi * ((np.arange(H) + 0.5) / H - 0.5)
    lon, lat = np.meshgrid(lon, lat)
    return np.stack((np.sin(lon) * np.cos(lat), np.sin(lat), np.cos(lon) * np.cos(lat)), -1)


def solid_angles():
    lat = -np.pi * ((np.arange(H) + 0.5) / H - 0.5)
    return np.repeat((np.cos(lat) * (np.pi / H) * (2 * np.pi / W))[:, None], W, 1)


def spot(row, col):
    env = np.zeros((H, W, 3), np.float32)
    env[row, col] = 1.0 / solid_angles()[row, col]  # unit energy
    return env


def test_a_constant_surrounding_stays_constant():
    env = np.full((H, W, 3), (0.2, 0.5, 1.5), np.float32)
    np.testing.assert_allclose(prefilter_latlong(env, 0.4), env, rtol=1e-4)


def test_a_mirror_is_left_alone():
    env = np.random.default_rng(1).random((H, W, 3), dtype=np.float32)
    out = prefilter_latlong(env, SHARP)
    np.testing.assert_array_equal(out, env)
    assert out is not env


@pytest.mark.parametrize("row", [H // 2, H // 4 + 2])
def test_a_point_spreads_by_the_lobe_and_keeps_its_energy(row):
    """A point of light (on the horizon, at 40 degrees) becomes a blob around its direction:
    the energy stays (within 8 % over the sphere: the separable filter is not exactly
    rotation-invariant; near the poles it is a weighted mean that keeps constants, not
    energy), the blob is centred on the point (within 1.5 degrees: the separable filter's
    widest Gaussians lean a little toward the equator at 40 degrees of latitude), and its
    angular spread (the rms angle of the core, within 3 sigma) grows with roughness as the
    lobe says."""
    d = directions()
    omega = solid_angles()
    spreads = []
    for roughness in (0.25, 0.4):
        out = prefilter_latlong(spot(row, 40), roughness)[..., 0]
        energy = (out * omega).sum()
        assert abs(energy - 1.0) < 0.08, energy
        angle = np.arccos(np.clip(d @ d[row, 40], -1, 1))
        core = lobe_sigmas(roughness)[0][1]
        inside = angle < 3 * core
        mean_dir = (out[..., None] * omega[..., None] * d).sum((0, 1))
        off = np.degrees(np.arccos(mean_dir @ d[row, 40] / np.linalg.norm(mean_dir)))
        assert off < 1.5  # the lobe's tail reaches 37 degrees (sigma) at roughness 0.4
        w = (out * omega)[inside]
        spreads.append(np.sqrt((w * angle[inside] ** 2).sum() / w.sum()))
    assert spreads[1] > 1.8 * spreads[0]  # alpha = r^2: 0.16 / 0.0625 = 2.6x wider
    assert spreads[0] > 0.5 * lobe_sigmas(0.25)[0][1]


@pytest.mark.parametrize("roughness", [0.25, 0.35])
def test_a_bright_light_reaches_as_far_as_the_ggx_tail(roughness):
    """A sun's energy 20 to 75 degrees off its direction is what GGX puts there (within a
    quarter): away from its highlight a rough surface under a sun shows mostly the lobe's
    tail (the two Gaussians fitted before put 1 % of what GGX does 45-75 degrees off at
    roughness 0.25)."""
    d = directions()
    out = prefilter_latlong(spot(H // 2, 40), roughness)[..., 0] * solid_angles()
    angle = np.arccos(np.clip(d @ d[H // 2, 40], -1, 1))
    for lo, hi in ((20, 45), (45, 75)):
        ring = (angle >= np.radians(lo)) & (angle < np.radians(hi))
        truth = ggx_annuli(roughness, np.radians([lo, hi]))[0]
        assert out[ring].sum() == pytest.approx(truth, rel=0.25), (lo, hi)


def test_no_seam_at_the_back_and_across_the_pole():
    """Light just left of the back seam spreads to its right (wrapping), and light near the
    north pole reaches the far side of the pole."""
    out = prefilter_latlong(spot(H // 2, 0), 0.3)[..., 0]
    assert out[H // 2, W - 1] > 0.5 * out[H // 2, 1]
    polar = prefilter_latlong(spot(1, 10), 0.3)[..., 0]
    assert polar[1, 10 + W // 2] > 0.05 * polar[1, 10]


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="twice as wide"):
        prefilter_latlong(np.zeros((10, 10, 3)), 0.3)
    with pytest.raises(ValueError, match="roughness"):
        prefilter_latlong(np.zeros((8, 16, 3)), float("nan"))
    with pytest.raises(ValueError, match="roughness"):
        prefilter_latlong(np.zeros((8, 16, 3)), 1.5)
