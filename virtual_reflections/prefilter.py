"""A lat-long map pre-filtered for a rough material: what a glossy surface reflects.

A mirror reflects one direction; a rough (GGX) surface the radiance around it, weighted by
its lobe. For the looks that read the map along the mirror direction (Replace, Modulate, Mix)
the map is convolved with that lobe once, so the lookup returns the blurred surroundings
(the "split sum" pre-filtering of real-time rendering, with the view along the normal).

The lobe: GGX with alpha = roughness^2 (Blender's Principled BSDF), its reflected directions
at normal incidence, fitted over the angle from the mirror direction by Gaussians over the
sphere of widths alpha x 1, 2, 4, ... (ggx_lobe.lobe: the heavy tail of GGX included; alpha,
not a scene, sets them). Gaussians at least `COARSE_TEXELS` texels wide run on a pyramid of
the map reduced by twos (each texel shared between the coarser texels around it as bilinear
reading shares them back, so a sun keeps its place and its energy); each level's sum is read
back up level by level. Column lengths are padded to products of 2, 3 and 5 for the FFT.

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

from .ggx_lobe import lobe

SHARP = 0.02  # roughness at or under which the map is left as it is (a mirror)
MIN_WEIGHT = 0.005  # Gaussians of the fit holding less of the lobe are left out
COARSE_TEXELS = 6.0  # a Gaussian at least this many texels wide runs on a reduced map
IDENTITY_TEXELS = 0.25  # one narrower than this (texels) leaves the map as it is


def lobe_sigmas(roughness: float) -> list[tuple[float, float]]:
    """The Gaussians of the lobe of a GGX surface (`ggx_lobe.lobe` without those under MIN_WEIGHT).

    Parameters
    ----------
    roughness : float
        Blender's, 0..1.

    Returns
    -------
    list of (weight, sigma)
        Sigma in radians; the weights sum to 1.
    """
    kept = [(w, s) for w, s in lobe(round(float(roughness), 4)) if w >= MIN_WEIGHT]
    total = sum(w for w, _ in kept)
    return [(w / total, s) for w, s in kept]


def prefilter_latlong(env: np.ndarray, roughness: float) -> np.ndarray:
    """Convolve a lat-long map with the GGX lobe of a roughness.

    Parameters
    ----------
    env : (H, W, C) ndarray
        A lat-long, H = W / 2, scene-linear.
    roughness : float
        Blender's, 0..1; at or under SHARP the map is left unchanged (a copy).

    Returns
    -------
    (H, W, C) float32 ndarray
    """
    env = np.asarray(env, np.float32)
    h, w = env.shape[:2]
    if w != 2 * h:
        raise ValueError(f"a lat-long map is twice as wide as high, got {w}x{h}")
    if not np.isfinite(roughness) or not 0.0 <= roughness <= 1.0:
        raise ValueError(f"roughness must be within 0..1, got {roughness}")
    if roughness <= SHARP:
        return env.copy()
    # Per reduction factor, the Gaussians that run at it; the map reduced by twos (a pyramid),
    # each level's Gaussians summed there, and the sums read back up level by level.
    levels: dict[int, list[tuple[float, float]]] = {}
    for weight, sigma in lobe_sigmas(roughness):
        levels.setdefault(_factor(h, sigma), []).append((weight, sigma))
    sources = {1: env}
    factor = 1
    while factor < max(levels):
        sources[factor * 2] = _downsample(sources[factor], 2)
        factor *= 2
    out = None
    while factor >= 1:
        source = sources[factor]
        if out is not None:
            out = _upsample(out, *source.shape[:2])
        if factor in levels:
            level = _level(source, levels[factor], h)
            out = level if out is None else out + level
        factor //= 2
    return out


def _level(source, gaussians, h):
    """The sum of ``gaussians`` ((weight, sigma) pairs) applied to ``source``, a level of the
    pyramid of a map ``h`` rows high."""
    spectrum = np.fft.rfft(source, axis=1)
    out = np.zeros_like(source)
    for weight, sigma in gaussians:
        if sigma / (np.pi / h) < IDENTITY_TEXELS:  # narrower than a texel: as it is
            out += np.float32(weight) * source
        else:
            out += np.float32(weight) * _gaussian(spectrum, source.shape, sigma)
    return out


def _factor(h, sigma):
    """The power of two the map of ``h`` rows is reduced by for a Gaussian of ``sigma``: the
    largest that keeps it COARSE_TEXELS / 2 texels wide and the map 8 rows high."""
    texels = sigma / (np.pi / h)
    factor = 1
    while (
        texels / (factor * 2) >= COARSE_TEXELS / 2
        and h // (factor * 2) >= 8
        and h % (factor * 2) == 0
    ):
        factor *= 2
    return factor


def _downsample(env, factor):
    """``env`` reduced by ``factor``: each texel's value shared between the coarse texels
    around its centre as `_upsample` would read it back (bilinear, transposed), so a light
    keeps its place and its energy; rows weighted by solid angle, columns wrapping round."""
    h = env.shape[0]
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    weight = np.cos(lat)[:, None, None]
    rows = _spread(env * weight, factor, wrap=False) / _spread(weight, factor, wrap=False)
    return (_spread(rows.swapaxes(0, 1), factor, wrap=True).swapaxes(0, 1) / factor).astype(
        np.float32
    )


def _spread(values, factor, wrap):
    """Along axis 0 of ``values`` (N, ...), N = K x factor: each of the N shared between the
    two of K nearest its centre, with the weights of linear interpolation (held at the ends,
    or wrapping round with ``wrap``); (K, ...), summing the shares."""
    n = values.shape[0]
    blocks = values.reshape(n // factor, factor, *values.shape[1:])
    pos = (np.arange(factor) + 0.5) / factor - 0.5  # each sub-texel's offset in coarse texels
    shape = (1, factor) + (1,) * (values.ndim - 1)
    own = (blocks * (1 - np.abs(pos)).reshape(shape)).sum(1)
    before = (blocks * np.maximum(-pos, 0).reshape(shape)).sum(1)  # to the texel before
    after = (blocks * np.maximum(pos, 0).reshape(shape)).sum(1)  # to the one after
    out = own
    if wrap:
        out = out + np.roll(before, -1, axis=0) + np.roll(after, 1, axis=0)
    else:
        out = out.copy()
        out[:-1] += before[1:]
        out[0] += before[0]
        out[1:] += after[:-1]
        out[-1] += after[-1]
    return out


def _upsample(small, h, w):
    """``small`` (h', w', C) read bilinearly at the texel centres of an (h, w) lat-long:
    columns wrapping round, rows held at the poles."""
    hs, ws = small.shape[:2]
    y = (np.arange(h) + 0.5) * hs / h - 0.5
    y0 = np.clip(np.floor(y).astype(int), 0, hs - 1)
    y1 = np.clip(y0 + 1, 0, hs - 1)
    fy = np.clip(y - y0, 0.0, 1.0)[:, None, None]
    x = (np.arange(w) + 0.5) * ws / w - 0.5
    x0 = np.floor(x).astype(int)
    fx = (x - x0)[None, :, None]
    x0, x1 = x0 % ws, (x0 + 1) % ws
    rows = small[y0] * (1 - fy) + small[y1] * fy
    return (rows[:, x0] * (1 - fx) + rows[:, x1] * fx).astype(np.float32)


def _gaussian(spectrum, shape, sigma):
    """A Gaussian of ``sigma`` radians over the sphere of the map of ``shape`` whose rows'
    Fourier transform is ``spectrum``, separably: rows then columns."""
    h, w = shape[:2]
    step = np.pi / h  # radians per texel
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    # Along each row: sigma / cos(lat) texels of longitude; at the poles a row is one point.
    along = sigma / (step * np.maximum(np.cos(lat), 0.5 / h))
    freq = np.fft.rfftfreq(w)  # cycles per texel
    transfer = np.exp(-2.0 * (np.pi * freq[None, :] * along[:, None]) ** 2)
    rows = np.fft.irfft(spectrum * transfer[..., None], n=w, axis=1)
    # Along each column: over the poles onto the column half a turn round, each texel
    # weighted by its solid angle (cos lat): the mean over the lobe, not over texels.
    down = sigma / step
    pad = _fast_pad(h, int(min(h, np.ceil(4.0 * down) + 1)))
    weight = np.cos(lat)[:, None, None]
    blurred = [
        _columns(rows * weight, w, pad, down),
        _columns(np.broadcast_to(weight, (h, 1, 1)), 1, pad, down),
    ]
    return (blurred[0] / np.maximum(blurred[1], 1e-12)).astype(np.float32)


def _fast_pad(h, pad):
    """The padding from ``pad`` up (at most ``h``) that makes the padded column h + 2 pad long
    a product of 2, 3 and 5, which the FFT takes fastest (a length with a large prime factor
    takes several times longer); ``pad`` when there is none."""
    for p in range(pad, h + 1):
        n = h + 2 * p
        for f in (2, 3, 5):
            while n % f == 0:
                n //= f
        if n == 1:
            return p
    return pad


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
