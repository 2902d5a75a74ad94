"""The unseen sky given the plate's own texture (`Params.sky_texture`; docs/scenes3d.md, "The
unseen sky's texture").

Above the world's horizon, where the plate does not see, the camera view's fill is one flat
colour per elevation: the sky prior (fill.py). With a texture share k > 0 each such texel
takes the plate's structure instead: its direction is folded into the plate's view (its
azimuth about the world's up reflected back and forth across the azimuths the plate shows at
or above the horizon, so the skyline the photo shows continues around the camera, mirrored at
each edge, without a seam; its elevation clamped to the plate's), read there from the mip
pyramid at the texel's own angular size, and the prior is multiplied by exp(k w (t - mean t)),
t the log-luminance of that sample (each channel clipped at 1: a sun counts as white), the
difference clipped to +-SKY_TEXTURE_CLIP. The weight w is 1 up to the highest elevation the
plate shows and falls to 0 over SKY_TEXTURE_FADE_DEG above it: the skyline goes round the
camera as a band and the sky above it stays the prior's smooth colour (clamped, the plate's
top row would converge on the zenith in stripes). The mean is weighted by solid angle times
w, so the sky's log-average stays the prior's; k sets the contrast (1: the plate's own).

`sky_texture` builds the layer's geometry once per table (an `Extension` of the sky texels,
read without a fade, their weights in the mean and their w); `modulate` applies it to a
frame's map.
"""

from __future__ import annotations

import math

import numpy as np

from .camera_view import clamp_to_view
from .extension import Extension, extension
from .extension import apply as apply_extension
from .fill import REC709_LUMA
from .layouts import directions_at
from .taps import put_rows, take_rows

SKY_TEXTURE_CLIP = 1.0  # natural-log units: a texel at most e times brighter or darker
SKY_TEXTURE_FADE_DEG = 30.0  # above the plate's highest elevation the texture fades out over this
GRID = 33  # plate positions a side sampled for the azimuths the plate shows
MIN_ABOVE = 0.05  # below this share of the plate above the horizon, its whole width counts


def horizon_frame(up) -> tuple:
    """(up, forward, left): unit camera-frame vectors, forward the camera's axis (+Z) laid
    on the world's horizon, left = up x forward (the plate's left, +X, for a level camera)."""
    u = np.asarray(up, np.float64)
    u = u / np.linalg.norm(u)
    for axis in ((0.0, 0.0, 1.0), (0.0, -1.0, 0.0)):  # looking straight up or down: its bottom
        f = np.asarray(axis) - np.dot(axis, u) * u
        if np.linalg.norm(f) > 1e-6:
            break
    f = f / np.linalg.norm(f)
    return u, f, np.cross(u, f)


def angles(directions, frame) -> tuple:
    """(elevation, azimuth) in radians of camera-frame `directions` (n, 3) in `frame`
    (`horizon_frame`): azimuth 0 forward, positive to the left."""
    u, f, left = frame
    d = np.asarray(directions, np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-30)
    return np.arcsin(np.clip(d @ u, -1.0, 1.0)), np.arctan2(d @ left, d @ f)


def view_extent(width: int, height: int, intrinsics, frame) -> tuple:
    """(lo, hi, top): the azimuths (radians) the plate shows at or above the world's horizon
    (its whole width when under MIN_ABOVE of it is above), and the highest elevation it shows."""
    fx, fy, cx, cy = intrinsics
    px, py = np.meshgrid(np.linspace(0, width, GRID), np.linspace(0, height, GRID))
    rays = np.stack([(cx - px) / fx, (cy - py) / fy, np.ones_like(px)], -1).reshape(-1, 3)
    elevation, azimuth = angles(rays, frame)
    above = elevation >= 0.0
    if above.mean() < MIN_ABOVE:
        above[:] = True
    return float(azimuth[above].min()), float(azimuth[above].max()), float(elevation.max())


def fold(azimuth, lo: float, hi: float):
    """Azimuths reflected back and forth into an interval (a triangle wave).

    Parameters
    ----------
    azimuth : float or ndarray
        Radians.
    lo, hi : float
        The interval; its period is 2 (hi - lo).

    Returns
    -------
    ndarray
        The folded azimuths, in [lo, hi]: inside it they are kept, past an end mirrored.
    """
    width = max(hi - lo, 1e-6)
    t = np.mod(np.asarray(azimuth) - lo, 2.0 * width)
    return lo + np.where(t > width, 2.0 * width - t, t)


def folded(directions, width: int, height: int, intrinsics, up) -> tuple:
    """Camera-frame `directions` (n, 3) with their azimuth folded into the plate's view
    (`view_extent`, `fold`), their elevation kept: ((n, 3) float32, (n,) float32 w, the
    texture's weight: 1 up to the plate's highest elevation, 0 from SKY_TEXTURE_FADE_DEG
    above it)."""
    frame = horizon_frame(up)
    u, f, left = frame
    elevation, azimuth = angles(directions, frame)
    lo, hi, top = view_extent(width, height, intrinsics, frame)
    azimuth = fold(azimuth, lo, hi)
    ground = np.cos(elevation)[:, None]
    out = ground * (np.cos(azimuth)[:, None] * f + np.sin(azimuth)[:, None] * left)
    out += np.sin(elevation)[:, None] * u
    fade = np.clip(1.0 - (elevation - top) / math.radians(SKY_TEXTURE_FADE_DEG), 0.0, 1.0)
    return out.astype(np.float32), fade.astype(np.float32)


def solid_angles(layout: str, size: int, texels) -> np.ndarray:
    """(n,) float64: each texel's solid angle up to one factor (a lat-long's cos(latitude), a
    cube's 1 / (1 + s^2 + t^2)^1.5 = its largest direction component cubed)."""
    d = directions_at(layout, size, np.asarray(texels, np.int64), 0.0, 0.0)
    if layout == "latlong":
        return np.sqrt(np.maximum(1.0 - d[:, 1] ** 2, 0.0))
    return np.abs(d).max(1) ** 3


def sky_lod(layout: str, size: int, intrinsics, top: int) -> float:
    """The mip level the sky texels read: a texel's angular size at the map's densest (a
    lat-long's equator, a face's centre) in plate pixels, as log2, in [0, top]."""
    angle = (2.0 * math.pi if layout == "latlong" else 0.5 * math.pi) / size
    return min(math.log2(max(angle * intrinsics[0], 1.0)), float(top))


def sky_texture(texels, directions, width, height, intrinsics, up, lod, top, layout, size):
    """The layer's geometry for the sky `texels` (n,) with camera-frame `directions` (n, 3),
    read at mip level `lod` (`sky_lod`; the pyramid's last level `top`): (the `Extension` of
    those the texture reaches (w > 0), their weights in the log-average (solid angle times w,
    summing to 1) and their w, (m,) float32 each in its order), or None."""
    texels = np.asarray(texels, np.int64)
    turned, fade = folded(directions, width, height, intrinsics, up)
    reached = fade > 0.0
    if not reached.any():
        return None
    texels, turned = texels[reached], turned[reached]
    position, _ = clamp_to_view(turned, width, height, intrinsics)
    lod = np.full(texels.size, lod, np.float32)
    ext = extension(texels, position[:, 0], position[:, 1], lod, top)
    order = np.argsort(texels)[np.searchsorted(np.sort(texels), ext.texels)]
    fade = fade[reached][order]
    weight = solid_angles(layout, size, ext.texels) * fade
    weight = (weight / weight.sum()).astype(np.float32)
    for array in (weight, fade):
        array.flags.writeable = False
    return ext, weight, fade


def modulate(ext: Extension, weight, fade, contrast, source, shapes, offsets, out, buffer):
    """out[texels] (the prior written there) times exp(contrast w (t - mean t)), t the
    log-luminance of each texel's sample of the pyramid `source` (module docstring). The
    samples are the extension's own pass (its back end's: Numba's compiled one where it
    imports), written into `buffer` ((T, 3) float32, the map's size) and read back."""
    apply_extension(ext, source, shapes, offsets, buffer)
    rows = take_rows(buffer, ext.texels)
    t = np.log(np.maximum(np.minimum(rows, 1.0) @ REC709_LUMA, 1e-3))
    t -= float(weight @ t)
    t *= fade
    np.clip(t, -SKY_TEXTURE_CLIP, SKY_TEXTURE_CLIP, out=t)
    factor = np.exp(np.float32(contrast) * t).astype(np.float32)
    prior = take_rows(out, ext.texels)
    prior *= factor[:, None]
    put_rows(out, ext.texels, prior)
