"""Colour: sRGB transfer functions and plate clean-up. Working space: scene-linear Rec.709.

Every array here says its space: `srgb` means sRGB-encoded (IEC 61966-2-1) values in [0, 1],
`linear` means scene-linear with Rec.709 primaries (what Blender calls "Linear Rec.709").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """Decode sRGB-encoded values with the sRGB EOTF (0.5 -> 0.214).

    Parameters
    ----------
    srgb : array_like
        sRGB-encoded values, nominally in [0, 1].

    Returns
    -------
    float32 ndarray
        Scene-linear values, same shape.
    """
    v = np.asarray(srgb, dtype=np.float32)
    return np.where(v <= 0.04045, v / 12.92, ((np.maximum(v, 0) + 0.055) / 1.055) ** 2.4).astype(
        np.float32
    )


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Encode scene-linear values to sRGB in [0, 1] (clipped first).

    Parameters
    ----------
    linear : array_like
        Scene-linear values.

    Returns
    -------
    float32 ndarray
        sRGB-encoded values in [0, 1], same shape.
    """
    v = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.where(v <= 0.0031308, v * 12.92, 1.055 * v ** (1 / 2.4) - 0.055).astype(np.float32)


# Linear Display P3 (DCI-P3 primaries, D65 white) -> CIE XYZ (D65), applied to column vectors
# (xyz = M @ rgb): SMPTE EG 432-1. The add-on's colour conversion without OpenColorIO uses it
# for Display P3 plates (Blender's API converts from XYZ D65 to the working space).
DISPLAY_P3_TO_XYZ_D65 = np.array(
    [[0.486571, 0.265668, 0.198217], [0.228975, 0.691739, 0.079287],
     [0.000000, 0.045113, 1.043944]], dtype=np.float64
)  # fmt: skip

_SRGB8_LUT = srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0)


def decode_uint(pixels: np.ndarray) -> np.ndarray:
    """Decode integer sRGB-encoded pixels to scene-linear floats (uint8 through a table).

    Parameters
    ----------
    pixels : uint8 or uint16 ndarray
        sRGB-encoded, full range.

    Returns
    -------
    float32 ndarray
        Scene-linear, same shape.
    """
    if pixels.dtype == np.uint8:
        return _SRGB8_LUT[pixels]
    return srgb_to_linear(pixels.astype(np.float32) / float(np.iinfo(pixels.dtype).max))


@dataclass(frozen=True)
class Cleaned:
    """A plate made safe to use (`clean_plate`).

    Attributes
    ----------
    pixels : (H, W, 3) float32 ndarray
        Scene-linear Rec.709.
    nonfinite : int
        How many values were NaN or +-Inf (replaced by 0 or the largest finite).
    """

    pixels: np.ndarray
    nonfinite: int  # how many values were NaN or +-Inf (replaced by 0 or the largest finite)


def as_rgb(pixels: np.ndarray) -> np.ndarray:
    """(H, W), (H, W, 1..4+) -> (H, W, 3): grey becomes RGB, alpha and extras are dropped."""
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] < 1:
        raise ValueError(f"a plate must be an (H, W) or (H, W, C) array, got shape {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"the plate is empty ({a.shape[1]}x{a.shape[0]} pixels)")
    if a.shape[2] < 3:
        return np.repeat(a[..., :1], 3, axis=2)
    return a[..., :3]


def clean_plate(linear: np.ndarray) -> Cleaned:
    """Make a plate safe to use: RGB float32 with NaN/Inf replaced.

    NaN and -Inf become 0, +Inf the largest finite value of the plate (or 0 if none).

    Parameters
    ----------
    linear : (H, W) or (H, W, C) ndarray
        Scene-linear pixels; grey becomes RGB, alpha and further channels are dropped.

    Returns
    -------
    Cleaned
        `pixels` (H, W, 3) float32 scene-linear Rec.709, and `nonfinite`, how many values
        were replaced.

    Raises
    ------
    ValueError
        Not an (H, W) or (H, W, C) array, or an empty one.
    """
    rgb = np.ascontiguousarray(as_rgb(linear), dtype=np.float32)
    bad = ~np.isfinite(rgb)
    count = int(np.count_nonzero(bad))
    if count:
        finite = rgb[~bad]
        top = float(finite.max()) if finite.size else 0.0
        rgb = np.nan_to_num(rgb, nan=0.0, posinf=top, neginf=0.0)
    return Cleaned(rgb, count)
