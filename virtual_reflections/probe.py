"""An on-set HDRI (a probe) for what the plate does not show.

Camera View + Ground fills the directions no plate pixel shows above the horizon with a sky
prior: a colour and level guessed from the plate (fill.sky_prior, `Params.sky_gain`). When
the artist has the HDRI shot on set (a chrome ball or a panorama, usually already the scene's
world), nothing there has to be guessed: every direction above the horizon that the plate does
not show takes the HDRI along it instead, and everything the plate shows (and the ground below
the horizon) stays the plate's.

The prior is the whole fill above the horizon and enters a map linearly (every gather is a
weighted sum), so a map built with the prior black and one built with it at a known level give
each texel's weight of it exactly (`envmap.prior_parts`); `with_probe` then adds the probe in
its place.

Frames: the probe is a lat-long image in Blender's equirectangular convention (world +X the
centre column, +Y a quarter of the width to the left of it, the zenith the top row; top row
first here), scene-linear Rec.709. `Probe.rotation` turns a camera-frame direction
(docs/conventions.md) into the probe image's own frame: the camera's orientation and the
world's mapping, composed by the caller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .fill import REC709_LUMA
from .layouts import texel_directions

ABOVE_DEG = 2.0  # plate pixels this far above the horizon are compared with the probe
MIN_SHARE = 0.01  # share of the plate that must be above it for an exposure comparison


@dataclass(frozen=True, eq=False)
class Probe:
    """An HDRI at infinity (the module docstring gives its frames).

    Attributes
    ----------
    pixels : (h, w, 3) float32 ndarray
        A scene-linear lat-long in Blender's equirectangular layout, top row first; any
        finite values.
    rotation : (3, 3) float64 ndarray
        A proper rotation from the camera frame to the image's frame.
    key : object
        What the caller made it of, so a change shows in its caches.
    """

    pixels: np.ndarray
    rotation: np.ndarray
    key: tuple = ()  # the caller's name for what it was made of (a cache's key)
    _maps: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        pixels, rotation = self.pixels, np.asarray(self.rotation, np.float64)
        if pixels.ndim != 3 or pixels.shape[2] != 3 or min(pixels.shape[:2]) < 1:
            raise ValueError(f"the probe must be (h, w, 3) pixels, got shape {pixels.shape}")
        if rotation.shape != (3, 3) or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-4):
            raise ValueError("the probe's rotation must be a 3x3 rotation matrix")
        if not np.isfinite(pixels).all():
            raise ValueError("the probe has NaN or infinite pixels")

    def latlong(self, width: int) -> np.ndarray:
        """The probe resampled on the texels of a lat-long map `width` wide ((width / 2,
        width, 3) float32, the map's frame): box-filtered first to about the map's
        resolution, so a small bright source (the sun) keeps its energy. Kept per width."""
        found = self._maps.get(width)
        if found is None:
            source = _shrink(self.pixels, max(1, self.pixels.shape[1] // width))
            directions = texel_directions("latlong", width, dtype=np.float32)
            turn = self.rotation.T.astype(np.float32)
            found = self._maps[width] = sample(source, directions @ turn)
        return found


def shrink_to(pixels: np.ndarray, width: int) -> np.ndarray:
    """An image no wider than a width: the mean of every k x k block, k = w // width rounded up.

    What a map `width` wide reads of a larger HDRI (`Probe.latlong` shrinks by whole blocks too),
    so an 8K HDRI need not be kept whole.

    Parameters
    ----------
    pixels : (h, w, 3) ndarray
    width : int

    Returns
    -------
    (h // k, w // k, 3) float32 ndarray
        `pixels` as float32 when already that narrow.
    """
    k = -(-pixels.shape[1] // max(int(width), 1))
    return _shrink(pixels, k)


def _shrink(pixels: np.ndarray, k: int) -> np.ndarray:
    """The mean of every k x k block (the edges' partial blocks dropped)."""
    k = min(k, pixels.shape[0])  # a block no taller than the image
    if k <= 1:
        return np.asarray(pixels, np.float32)
    h, w = (pixels.shape[0] // k) * k, (pixels.shape[1] // k) * k
    blocks = pixels[:h, :w].reshape(h // k, k, w // k, k, 3)
    return blocks.mean(axis=(1, 3), dtype=np.float64).astype(np.float32)


def sample(pixels: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear sample of a lat-long image in Blender's equirectangular layout along
    `directions` (..., 3) given in the image's own frame (+Z up) -> (..., 3) float32. The seam
    wraps; rows clamp at the poles (as Blender's Environment Texture, Linear)."""
    h, w = pixels.shape[:2]
    d = np.asarray(directions, np.float32)  # a texel is far wider than float32's error
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    z = np.clip(d[:, 2] / np.where(length > 0, length, 1.0), -1.0, 1.0)
    x = np.arctan2(d[:, 1], d[:, 0])
    x *= np.float32(-w / (2.0 * math.pi))
    x += np.float32(0.5 * w - 0.5)
    y = np.arccos(z)
    y *= np.float32(h / math.pi)
    y -= np.float32(0.5)
    x0 = np.floor(x)
    y0 = np.clip(np.floor(y), 0, h - 1)
    fx = (x - x0)[:, None]
    fy = np.clip(y - y0, 0.0, 1.0)[:, None]
    y0 = y0.astype(np.intp)
    y1 = np.minimum(y0 + 1, h - 1)
    x0 = np.mod(x0.astype(np.intp), w)
    x1 = x0 + 1
    x1[x1 == w] = 0
    flat = np.ascontiguousarray(pixels, np.float32).reshape(-1, 3)
    top, bottom = y0 * w, y1 * w
    out = flat[top + x0] * (1 - fx) + flat[top + x1] * fx
    out *= 1 - fy
    out += (flat[bottom + x0] * (1 - fx) + flat[bottom + x1] * fx) * fy
    return out.reshape(shape + (3,))


def with_probe(without: np.ndarray, weight: np.ndarray, probe_map: np.ndarray) -> np.ndarray:
    """A map with the probe in place of its sky prior.

    Parameters
    ----------
    without : (h, w, 3) float32 ndarray
        The map with the prior black (`envmap.prior_parts`).
    weight : (h, w) float32 ndarray
        Each texel's weight of the prior, 0..1.
    probe_map : (h, w, 3) float32 ndarray
        The probe in the map's layout.

    Returns
    -------
    (h, w, 3) float32 ndarray
    """
    return without + weight[..., None] * probe_map


def exposure_ratio(plate: np.ndarray, intrinsics, up, probe: Probe) -> float | None:
    """How much brighter the plate is than the probe where both show the surroundings.

    A check for the artist, not a correction: the world's strength is theirs to set.

    Parameters
    ----------
    plate : (H, W, 3) float32 ndarray
        Scene-linear.
    intrinsics : (fx, fy, cx, cy)
        The plate camera in plate pixels.
    up : (x, y, z)
        The world's up in the camera frame.
    probe : Probe

    Returns
    -------
    float or None
        The median, over the plate's pixels at least ABOVE_DEG above the horizon, of their
        luminance over the probe's along the same direction (1: exposed as the plate); None
        when under MIN_SHARE of the plate is above the horizon or the pixels there are black.
    """
    height, width = plate.shape[:2]
    fx, fy, cx, cy = intrinsics
    step = max(1, int(math.sqrt(height * width / 20000)))  # about 20 000 pixels are enough
    py, px = np.mgrid[0:height:step, 0:width:step]
    d = np.stack([-(px + 0.5 - cx) / fx, -(py + 0.5 - cy) / fy, np.ones(px.shape)], axis=-1)
    u = np.asarray(up, np.float64) / np.linalg.norm(up)
    sine = (d @ u) / np.linalg.norm(d, axis=-1)
    above = sine > math.sin(math.radians(ABOVE_DEG))
    if above.mean() < MIN_SHARE:
        return None
    seen = plate[py[above], px[above]] @ REC709_LUMA
    shown = sample(probe.pixels, d[above] @ probe.rotation.T) @ REC709_LUMA
    good = (seen > 0) & (shown > 0)
    if good.sum() < 16:
        return None
    return float(np.exp(np.median(np.log(seen[good]) - np.log(shown[good]))))
