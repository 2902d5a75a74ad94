"""Image metrics of the lighting-estimation literature, and the plate's own view of a map.

- `si_rmse`: scale-invariant RMSE (one scale for all channels, the least-squares `alpha`
  minimising `|alpha * pred - truth|`, as in Gardner et al. / StyleLight's evaluation), here
  divided by the truth's RMS so scenes of different brightness average fairly. Linear values.
- `angular_error`: the mean angle in degrees between the RGB vectors of prediction and truth
  (insensitive to per-pixel intensity: it measures colour). Linear values.
- `psnr`, `ssim`: on LDR display values, i.e. sRGB-encoded and clipped to [0, 1] (`to_display`);
  peak 1. SSIM as Wang et al. 2004 (Gaussian window sigma 1.5, K1 0.01, K2 0.03), per channel,
  averaged over the masked pixels.
- `plate_view_mask`: the texels of a lat-long map whose whole footprint lies inside the plate's
  view (the directions the plate itself sees); `psnr` over that mask is the "plate PSNR".

Every `mask` is an `(H, W)` bool array selecting the pixels (or texels) that count.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from virtual_reflections.colour import linear_to_srgb

from ..panorama import focal_length_pixels
from .spheres import latlong_directions

_EPS = 1e-12


def _select(image, mask):
    a = np.asarray(image, dtype=np.float64)
    return a.reshape(-1, a.shape[-1]) if mask is None else a[np.asarray(mask, bool)]


def to_display(linear: np.ndarray) -> np.ndarray:
    """Scene-linear -> LDR display values: sRGB-encoded, clipped to [0, 1], float32."""
    return linear_to_srgb(linear)


def si_rmse(pred: np.ndarray, truth: np.ndarray, mask=None) -> float:
    """Scale-invariant RMSE of linear `(H, W, 3)` images, relative to the truth's RMS.

    `alpha = <pred, truth> / <pred, pred>` over all masked values; then
    `sqrt(mean((alpha pred - truth)^2)) / sqrt(mean(truth^2))`. 0 is perfect; 1 is what a black
    prediction scores. A prediction that is zero everywhere keeps alpha = 0.
    """
    p, t = _select(pred, mask), _select(truth, mask)
    pp = float(np.sum(p * p))
    alpha = float(np.sum(p * t)) / pp if pp > _EPS else 0.0
    rms_truth = math.sqrt(float(np.mean(t * t)))
    return math.sqrt(float(np.mean((alpha * p - t) ** 2))) / max(rms_truth, _EPS)


def angular_error(pred: np.ndarray, truth: np.ndarray, mask=None) -> float:
    """Mean angle in degrees between the RGB vectors of linear `(H, W, 3)` images.

    A black pixel against a non-black one counts as 90 degrees (no colour at all); two black
    pixels as 0.
    """
    p, t = _select(pred, mask), _select(truth, mask)
    np_, nt = np.linalg.norm(p, axis=1), np.linalg.norm(t, axis=1)
    cos = np.sum(p * t, axis=1) / np.maximum(np_ * nt, _EPS)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    both_black = (np_ <= _EPS) & (nt <= _EPS)
    one_black = (np_ <= _EPS) ^ (nt <= _EPS)
    angle = np.where(both_black, 0.0, np.where(one_black, 90.0, angle))
    return float(np.mean(angle))


def psnr(pred: np.ndarray, truth: np.ndarray, mask=None, peak: float = 1.0) -> float:
    """PSNR in dB of two images in the same (display) units; `inf` when they are identical."""
    p, t = _select(pred, mask), _select(truth, mask)
    mse = float(np.mean((p - t) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(peak * peak / mse)


@functools.lru_cache(maxsize=8)
def _blur_matrix(n: int, sigma: float, radius: int) -> np.ndarray:
    """`(n, n)` matrix of a 1-D Gaussian filter with zero padding ('same' size)."""
    offset = np.arange(n)[None, :] - np.arange(n)[:, None]
    k = np.exp(-0.5 * (offset / sigma) ** 2) * (np.abs(offset) <= radius)
    return k / np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2).sum()


def _gaussian_blur(image: np.ndarray, sigma: float = 1.5, radius: int = 5) -> np.ndarray:
    """Separable Gaussian filter of `(H, W, C)` float64, 'same' size, zero padding (as two
    matrix products, which BLAS does fast)."""
    h, w, c = image.shape
    rows = (_blur_matrix(h, sigma, radius) @ image.reshape(h, w * c)).reshape(h, w, c)
    cols = _blur_matrix(w, sigma, radius) @ rows.transpose(1, 0, 2).reshape(w, h * c)
    return cols.reshape(w, h, c).transpose(1, 0, 2)


def ssim(pred: np.ndarray, truth: np.ndarray, mask=None, peak: float = 1.0) -> float:
    """Mean SSIM (Wang et al. 2004) of `(H, W, C)` display images over `mask`, channels averaged.

    Gaussian window sigma 1.5 (11 x 11), K1 = 0.01, K2 = 0.03, dynamic range `peak`. Windows at
    the sphere's rim also see the (black, identical) background; that is the same for every
    method, so rankings are unaffected.
    """
    x = np.asarray(pred, dtype=np.float64)
    y = np.asarray(truth, dtype=np.float64)
    if x.ndim == 2:
        x, y = x[..., None], y[..., None]
    c1, c2 = (0.01 * peak) ** 2, (0.03 * peak) ** 2
    c = x.shape[-1]
    blurred = _gaussian_blur(np.concatenate([x, y, x * x, y * y, x * y], axis=-1))
    mx, my, exx, eyy, exy = (blurred[..., k * c : (k + 1) * c] for k in range(5))
    sxx = exx - mx * mx
    syy = eyy - my * my
    sxy = exy - mx * my
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    s = s.mean(axis=-1)
    return float(s.mean() if mask is None else s[np.asarray(mask, bool)].mean())


def plate_view_mask(map_width: int, plate_width: int, plate_height: int, hfov_deg: float):
    """`(map_width/2, map_width)` bool: the lat-long texels (camera frame) the plate sees.

    A texel counts when its centre projects into the plate at least one texel footprint (in
    plate pixels, at the plate's centre) away from every edge, so its whole footprint, and the
    filter a map builder may use there, lies inside the plate. Projection (docs/conventions.md):
    `px = W/2 - f x / z`, `py = H/2 - f y / z`, `f = (W/2) / tan(hfov / 2)`.
    """
    f = focal_length_pixels(plate_width, hfov_deg)
    d = latlong_directions(map_width)
    z = d[..., 2]
    ahead = z > 1e-6
    zs = np.where(ahead, z, 1.0)
    px = 0.5 * plate_width - f * d[..., 0] / zs
    py = 0.5 * plate_height - f * d[..., 1] / zs
    margin = f * 2.0 * math.pi / map_width  # one texel, in plate pixels
    return (
        ahead
        & (px >= margin)
        & (px <= plate_width - margin)
        & (py >= margin)
        & (py <= plate_height - margin)
    )
