"""Metrics closer to what an eye sees (issue 41, item 1), on LDR display values (sRGB-encoded,
clipped to [0, 1]: `metrics.to_display`):

- `flip_ldr`: LDR-ꟻLIP (Andersson et al. 2020, the ``flip-evaluator`` package: the study's
  dependency, never the extension's) of a prediction against the truth, the mean of its
  per-pixel error map over a mask: 0 identical, 1 the most different; lower is better. The
  default 67 pixels per degree (a 0.7 m viewing distance from a 3840-pixel, 0.7 m wide screen).
- `detail_ratio`: how much structure a prediction has where the truth has it: the RMS gradient
  of display luminance (Rec. 709 weights of the display values) inside the mask eroded by
  `ERODE` pixels (so no gradient crosses the mask's rim), the prediction's over the truth's. 1:
  as much texture as the truth; 0: flat (a constant colour); above 1: more (noise). The same
  ratio on the mask's upper half (`upper_half`) measures the part of a mirror the plate never
  sees.

Every ``mask`` is an ``(H, W)`` bool array; images ``(H, W, 3)`` display values.
"""

from __future__ import annotations

import math

import numpy as np

ERODE = 2  # pixels taken off the mask's rim before the gradients are measured
PPD = 67.0  # ꟻLIP's pixels per degree of visual angle (its default)
LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709, on display values


def flip_ldr(pred: np.ndarray, truth: np.ndarray, mask=None, ppd: float = PPD) -> float:
    """Mean LDR-ꟻLIP error of display images ``pred`` against ``truth`` over ``mask``."""
    try:
        import flip_evaluator
    except ImportError as error:  # the study's requirement, not the extension's
        raise RuntimeError(
            "FLIP needs the flip-evaluator package: pip install -r requirements/blender45.txt"
        ) from error
    ref = np.ascontiguousarray(np.clip(truth, 0.0, 1.0), dtype=np.float32)
    test = np.ascontiguousarray(np.clip(pred, 0.0, 1.0), dtype=np.float32)
    error, _, _ = flip_evaluator.evaluate(
        ref, test, "LDR", applyMagma=False, computeMeanError=False, parameters={"ppd": ppd}
    )
    error = np.asarray(error, dtype=np.float64).reshape(ref.shape[:2])
    return float(error.mean() if mask is None else error[np.asarray(mask, bool)].mean())


def erode(mask: np.ndarray, pixels: int = ERODE) -> np.ndarray:
    """``mask`` without the pixels within ``pixels`` (Chebyshev distance: a square) of a pixel
    outside it; outside the image counts as outside."""
    m = np.asarray(mask, bool)
    if pixels <= 0:
        return m.copy()
    padded = np.pad(m, pixels, constant_values=False)
    h, w = m.shape
    out = np.ones_like(m)
    for dy in range(2 * pixels + 1):
        for dx in range(2 * pixels + 1):
            out &= padded[dy : dy + h, dx : dx + w]
    return out


def upper_half(mask: np.ndarray) -> np.ndarray:
    """The pixels of ``mask`` in the upper half of its rows (above the middle of its screen
    box; row 0 at the top)."""
    m = np.asarray(mask, bool)
    rows = np.nonzero(m.any(axis=1))[0]
    if rows.size == 0:
        return m.copy()
    middle = (rows[0] + rows[-1] + 1) / 2.0
    return m & (np.arange(m.shape[0])[:, None] < middle)


def detail(image: np.ndarray, mask: np.ndarray, inside=None) -> float:
    """RMS gradient magnitude of ``image``'s display luminance over ``mask`` eroded by ERODE
    pixels (and within ``inside`` when given); NaN when no pixel is left."""
    lum = np.asarray(image, dtype=np.float64)[..., :3] @ LUMA
    gy, gx = np.gradient(lum)
    keep = erode(mask)
    if inside is not None:
        keep &= np.asarray(inside, bool)
    if not keep.any():
        return math.nan
    return math.sqrt(float(np.mean((gx * gx + gy * gy)[keep])))


def detail_ratio(pred: np.ndarray, truth: np.ndarray, mask: np.ndarray, inside=None) -> float:
    """`detail` of ``pred`` over the truth's (same pixels); NaN when the truth is flat there."""
    theirs = detail(truth, mask, inside)
    if not theirs > 0.0:
        return math.nan
    return detail(pred, mask, inside) / theirs
