"""The GGX lobe the rough maps are pre-filtered with (virtual_reflections/ggx_lobe.py)."""

import numpy as np
import pytest

from virtual_reflections.ggx_lobe import dominant_shift, ggx_annuli, lobe

ANGLES = np.radians([10.0, 20.0, 30.0, 45.0, 60.0, 75.0])


def beyond(weights_sigmas, angles):
    """The share of a sum of Gaussians over the sphere beyond each angle (radians)."""
    return sum(w * np.exp(-(angles**2) / (2 * s * s)) for w, s in weights_sigmas)


def ggx_beyond(roughness, angles):
    edges = np.concatenate(([0.0], angles, [np.pi / 2]))
    shares = ggx_annuli(roughness, edges)
    return 1.0 - np.cumsum(shares)[: len(angles)]


@pytest.mark.parametrize("roughness", [0.15, 0.25, 0.35, 0.5])
def test_the_fit_holds_the_tail_of_ggx(roughness):
    """The share of the lobe beyond 10 to 75 degrees is GGX's within a quarter of it (or
    0.0075) at every angle where GGX holds more than 0.2 %; the two Gaussians fitted before
    (60 % at 1.2 alpha, 40 % at 3.2 alpha, fitted on the cumulative share alone) held under
    half of it beyond 60 degrees at roughness 0.35."""
    truth = ggx_beyond(roughness, ANGLES)
    fitted = beyond(lobe(roughness), ANGLES)
    shown = truth > 0.002
    assert np.all(np.abs(fitted - truth)[shown] <= np.maximum(0.25 * truth, 0.0075)[shown]), (
        np.round(truth, 4),
        np.round(fitted, 4),
    )
    if roughness == 0.35:
        alpha = roughness**2
        before = beyond([(0.6, 1.2 * alpha), (0.4, 3.2 * alpha)], ANGLES)
        assert before[4] < 0.5 * truth[4]


def test_the_gaussians_are_a_share_each_and_widen_by_twos():
    for roughness in (0.05, 0.35, 1.0):
        fitted = lobe(roughness)
        weights = np.array([w for w, _ in fitted])
        sigmas = np.array([s for _, s in fitted])
        assert np.all(weights >= 0) and weights.sum() == pytest.approx(1.0)
        ratios = sigmas[1:] / sigmas[:-1]
        assert np.allclose(np.log2(ratios), np.round(np.log2(ratios)))
        assert sigmas.max() <= 1.0 + 1e-9


def test_ggx_annuli_share_the_whole_lobe_and_narrow_with_roughness():
    edges = np.linspace(0, np.pi / 2, 91)
    for roughness in (0.1, 0.5):
        assert ggx_annuli(roughness, edges).sum() == pytest.approx(1.0)
    near = np.radians([0.0, 5.0, 90.0])
    assert ggx_annuli(0.2, near)[0] > ggx_annuli(0.5, near)[0]


def mean_direction(roughness, theta, samples=400_000):
    """The radiance-weighted mean reflected direction of GGX for a view ``theta`` off the
    normal (x toward the viewer), by plain Monte Carlo: uniform microfacet normals over the
    hemisphere weighted by D (an estimator independent of the module's quadrature)."""
    rng = np.random.default_rng(7)
    a2 = roughness**4
    z = rng.random(samples)
    phi = 2 * np.pi * rng.random(samples)
    r_xy = np.sqrt(1 - z * z)
    h = np.stack((r_xy * np.cos(phi), r_xy * np.sin(phi), z), -1)
    d = a2 / (np.pi * (z * z * (a2 - 1) + 1) ** 2)
    v = np.array((np.sin(theta), 0.0, np.cos(theta)))
    vh = h @ v
    r = 2 * vh[:, None] * h - v

    def g1(c):
        c = np.clip(c, 1e-9, 1)
        return 2 / (1 + np.sqrt(1 + a2 * (1 - c * c) / (c * c)))

    ok = (vh > 0) & (r[:, 2] > 0)
    w = np.where(ok, d * g1(v[2]) * g1(r[:, 2]) * vh / v[2], 0.0)
    m = (w[:, None] * r).sum(0)
    return m / np.linalg.norm(m)


@pytest.mark.parametrize("roughness, theta_deg", [(0.35, 75.0), (0.5, 60.0), (0.5, 80.0)])
def test_the_lobe_centre_matches_the_mean_reflected_direction(roughness, theta_deg):
    """normalize(R + t (N - R)) with t from the fit is within 2 degrees of the mean
    direction Monte Carlo finds, which lies 13 to 31 degrees from the mirror direction here."""
    theta = np.radians(theta_deg)
    a, b, c = dominant_shift(roughness)
    x = 1 - np.cos(theta)
    t = np.clip(x * (a + x * (b + x * c)), 0, 1)
    mirror = np.array((-np.sin(theta), 0.0, np.cos(theta)))
    centre = mirror + t * (np.array((0.0, 0.0, 1.0)) - mirror)
    centre /= np.linalg.norm(centre)
    truth = mean_direction(roughness, theta)
    assert np.degrees(np.arccos(np.clip(centre @ truth, -1, 1))) < 2.0
    assert np.degrees(np.arccos(np.clip(mirror @ truth, -1, 1))) > 8.0


def test_the_shift_grows_toward_grazing_and_with_roughness():
    def shift(roughness, theta_deg):
        a, b, c = dominant_shift(roughness)
        x = 1 - np.cos(np.radians(theta_deg))
        return x * (a + x * (b + x * c))

    assert abs(shift(0.35, 0.0)) < 1e-9
    assert shift(0.35, 30) < shift(0.35, 60) < shift(0.35, 80)
    assert shift(0.15, 70) < shift(0.35, 70) < shift(0.5, 70)
    assert abs(shift(0.05, 70)) < 0.01  # a near-mirror is read along the mirror direction
