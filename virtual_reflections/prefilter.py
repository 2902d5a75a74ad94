"""A lat-long map pre-filtered for a rough material: what a glossy surface reflects.

A mirror reflects one direction; a rough (GGX) surface the radiance around it, weighted by
its lobe. For the looks that read the map along the mirror direction (Replace, Modulate, Mix)
the map is convolved with that lobe once, so the lookup returns the blurred surroundings
(the "split sum" pre-filtering of real-time rendering, with the view along the normal).

The lobe: GGX with alpha = roughness^2 (Blender's Principled BSDF), its reflected directions
at normal incidence, times the cosine. Over the angle from the mirror direction it is fitted
(maximum difference of the cumulative distributions under 0.025 for roughness 0.15 to 0.5) by
two Gaussians over the sphere: 60 % of standard deviation 1.2 alpha and 40 % of 3.2 alpha
(`LOBE`; alpha, not a scene, sets them).

Each Gaussian is applied separably on the lat-long grid: along each row (longitude, wrapping)
with a width of sigma / cos(latitude) texels, by FFT, and along each column (latitude) over
the poles (a column continues on the far side of the pole, half a turn round), there as a
mean weighted by each texel's solid angle, so a constant stays constant and a light keeps
its energy (within 8 % up to 45 degrees of latitude; nearer the poles, where one lat-long row
is a small circle, it is a weighted mean that keeps constants but loses up to a fifth of a
point light's energy). Lat-long
layout and frames as in docs/conventions.md: (H, W, C), H = W / 2, top row first.
"""

from __future__ import annotations

import numpy as np

LOBE = ((0.6, 1.2), (0.4, 3.2))  # (weight, sigma / alpha) of the Gaussians fitting GGX
SHARP = 0.02  # roughness at or under which the map is left as it is (a mirror)


def lobe_sigmas(roughness: float) -> list[tuple[float, float]]:
    """[(weight, sigma in radians)] of the lobe of a GGX surface of ``roughness``."""
    alpha = float(roughness) ** 2
    return [(w, k * alpha) for w, k in LOBE]


def prefilter_latlong(env: np.ndarray, roughness: float) -> np.ndarray:
    """``env`` ((H, W, C) lat-long, H = W / 2) convolved with the GGX lobe of ``roughness``
    (0..1, Blender's): float32 of the same shape. Left unchanged (a copy) at or under SHARP."""
    env = np.asarray(env, np.float32)
    h, w = env.shape[:2]
    if w != 2 * h:
        raise ValueError(f"a lat-long map is twice as wide as high, got {w}x{h}")
    if not np.isfinite(roughness) or not 0.0 <= roughness <= 1.0:
        raise ValueError(f"roughness must be within 0..1, got {roughness}")
    if roughness <= SHARP:
        return env.copy()
    out = np.zeros_like(env)
    for weight, sigma in lobe_sigmas(roughness):
        out += weight * _gaussian(env, sigma)
    return out


def _gaussian(env, sigma):
    """A Gaussian of ``sigma`` radians over the sphere, separably: rows then columns."""
    h, w = env.shape[:2]
    step = np.pi / h  # radians per texel
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    # Along each row: sigma / cos(lat) texels of longitude; at the poles a row is one point.
    along = sigma / (step * np.maximum(np.cos(lat), 0.5 / h))
    freq = np.fft.rfftfreq(w)  # cycles per texel
    transfer = np.exp(-2.0 * (np.pi * freq[None, :] * along[:, None]) ** 2)
    rows = np.fft.irfft(np.fft.rfft(env, axis=1) * transfer[..., None], n=w, axis=1)
    # Along each column: over the poles onto the column half a turn round, each texel
    # weighted by its solid angle (cos lat): the mean over the lobe, not over texels.
    down = sigma / step
    pad = int(min(h, np.ceil(4.0 * down) + 1))
    weight = np.cos(lat)[:, None, None]
    blurred = [
        _columns(rows * weight, w, pad, down),
        _columns(np.broadcast_to(weight, (h, 1, 1)), 1, pad, down),
    ]
    return (blurred[0] / np.maximum(blurred[1], 1e-12)).astype(np.float32)


def _columns(values, w, pad, down):
    """A Gaussian of ``down`` texels along each column of (H, W', C) ``values``, continued
    over each pole onto the column half a turn round (W' = 1: the same column)."""
    h = values.shape[0]
    over = np.roll(values, w // 2, axis=1)
    padded = np.concatenate((over[pad - 1 :: -1], values, over[: h - pad - 1 : -1]), axis=0)
    n = padded.shape[0]
    transfer = np.exp(-2.0 * (np.pi * np.fft.rfftfreq(n) * down) ** 2)
    cols = np.fft.irfft(np.fft.rfft(padded, axis=0) * transfer[:, None, None], n=n, axis=0)
    return cols[pad : pad + h]
