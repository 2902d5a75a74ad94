"""The paper's cube (§3.1): where on the plate each direction of the environment looks.

Directions are in the camera frame (docs/conventions.md): +Z is the viewing direction (the
plate's centre), +Y is up on the plate, +X is the plate's *left* (-X its right).

Every direction is first put on the unit cube around the object:

    back  (+Z) <- region X         left (+X) <- L        top    (+Y) <- T
    front (-Z) <- the ring F       right(-X) <- R        bottom (-Y) <- B

and then mapped to the plate by the paper's construction, written in cube coordinates so
that neighbouring faces meet without seams:

- back face: (h, w) = (x/z, y/z) in [-1, 1]^2 maps piecewise-linearly onto X with the cube
  centre on the object's centre lines (so left of the object lands on the left half);
- side faces: the depth t = (1 - z/|a|)/2 (0 at the back edge, 1 at the front edge, a the
  dominant axis) interpolates between the edge of X and the edge of `inner`, the
  coordinate along the edge is split at the object's centre line on both;
- front face: four triangles F'_L, F'_R, F'_T, F'_B meet at the centre. Each is fed by the
  trapezoid of the ring F on its side "with inverted orientation": the triangle's base
  (on the cube edge) takes `inner`'s edge, its apex (the centre, directly behind the
  camera) takes the image border. With n triangles (n/4 per side) each sub-triangle has
  its apex at one border point, as the paper cuts them; n = 0 is the continuous limit
  where each radial line of the face maps to its own border point.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from .segmentation import Segmentation


def _split(a, at_plus, mid, at_minus):
    """Piecewise-linear map of a in [-1, 1]: -1 -> at_minus, 0 -> mid, +1 -> at_plus."""
    return mid + a * np.where(a >= 0, at_plus - mid, mid - at_minus)


def _typed(rect, dtype):
    """A rectangle's x0, y0, x1, y1 as numbers of ``dtype``."""
    return SimpleNamespace(**{k: dtype(getattr(rect, k)) for k in ("x0", "y0", "x1", "y1")})


def _lerp(a, b, t):
    return a + t * (b - a)


def _where(mask):
    """The indices where `mask` holds, or a slice when it holds everywhere (a lat-long's slab
    of rows near a pole is one face: its arrays are then views, not gathered copies)."""
    return slice(None) if mask.all() else np.flatnonzero(mask)


def plate_positions(directions: np.ndarray, seg: Segmentation, triangles: int = 0) -> np.ndarray:
    """Plate positions seen along camera-frame `directions`.

    directions: (..., 3) float, need not be normalised (zero vectors give the centre of X).
    Returns (..., 2) continuous plate coordinates (x right, y down, within [0, W] x [0, H]),
    float32 for float32 input, else float64; pixel (px, py) has its centre at
    (px + 0.5, py + 0.5).
    """
    d = np.asarray(directions)
    dtype = np.float32 if d.dtype == np.float32 else np.float64
    shape = d.shape[:-1]
    d = d.reshape(-1, 3).astype(dtype, copy=False)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    out = np.empty((d.shape[0], 2), dtype=dtype)

    # The segmentation's numbers in the directions' precision: float32 directions are worked
    # on in float32 (Python floats in np.where would make every temporary float64).
    X, inner = _typed(seg.x, dtype), _typed(seg.inner, dtype)
    cx, cy = (dtype(v) for v in seg.centre)
    W, H = dtype(seg.width), dtype(seg.height)

    # Face choice as OpenEXR's CubeMap::faceAndPixelPosition: x wins ties, then y.
    on_x = (ax >= ay) & (ax >= az)
    on_y = ~on_x & (ay >= az)
    on_z = ~(on_x | on_y)
    back = on_z & (z > 0)

    with np.errstate(divide="ignore", invalid="ignore"):
        # Back face (+Z): region X.
        idx = _where(back)
        r = 1 / z[idx]
        out[idx, 0] = _split(x[idx] * r, X.x0, cx, X.x1)
        out[idx, 1] = _split(y[idx] * r, X.y0, cy, X.y1)

        # Left / right faces (+X / -X): regions L and R. t: 0 at the back edge, 1 at the front.
        idx = _where(on_x & (ax > 0))
        r = 1 / ax[idx]
        left = x[idx] > 0
        w, t = y[idx] * r, 0.5 - 0.5 * z[idx] * r
        out[idx, 0] = _lerp(np.where(left, X.x0, X.x1), np.where(left, inner.x0, inner.x1), t)
        out[idx, 1] = _lerp(_split(w, X.y0, cy, X.y1), _split(w, inner.y0, cy, inner.y1), t)

        # Top / bottom faces (+Y / -Y): regions T and B.
        idx = _where(on_y)
        r = 1 / ay[idx]
        top = y[idx] > 0
        h, t = x[idx] * r, 0.5 - 0.5 * z[idx] * r
        out[idx, 1] = _lerp(np.where(top, X.y0, X.y1), np.where(top, inner.y0, inner.y1), t)
        out[idx, 0] = _lerp(_split(h, X.x0, cx, X.x1), _split(h, inner.x0, cx, inner.x1), t)

        # Front face (-Z): the ring F, four triangles with inverted orientation.
        idx = _where(on_z & ~back)
        r = 1 / az[idx]
        h, w = x[idx] * r, y[idx] * r
        horiz = np.abs(h) >= np.abs(w)  # in F'_L or F'_R, else F'_T or F'_B
        major = np.where(horiz, h, w)
        rad = 1.0 - np.abs(major)  # 0 on the cube edge, 1 at the face centre
        s = np.nan_to_num(np.where(horiz, w, h) / np.abs(major), nan=0.0, posinf=1.0, neginf=-1.0)
        if triangles:
            k = triangles // 4
            i = np.clip(np.floor((s + 1.0) * (0.5 * k)), 0, k - 1)
            apex_s = (2.0 * i + 1.0) / k - 1.0
        else:
            apex_s = s
        plus = major > 0  # toward +X (left) or +Y (top)
        # Base on `inner`, apex on the image border, both split at the centre lines.
        base_fixed = np.where(
            horiz, np.where(plus, inner.x0, inner.x1), np.where(plus, inner.y0, inner.y1)
        )
        apex_fixed = np.where(plus, 0.0, np.where(horiz, W, H))
        base_along = np.where(
            horiz, _split(s, inner.y0, cy, inner.y1), _split(s, inner.x0, cx, inner.x1)
        )
        apex_along = np.where(horiz, _split(apex_s, 0.0, cy, H), _split(apex_s, 0.0, cx, W))
        fixed = _lerp(base_fixed, apex_fixed, rad)
        along = _lerp(base_along, apex_along, rad)
        out[idx, 0] = np.where(horiz, fixed, along)
        out[idx, 1] = np.where(horiz, along, fixed)

    # The zero vector (no face): the centre of X (|x| + |y| + |z| is 0 for it alone).
    zero = np.flatnonzero((ax + ay) + az == 0)
    if zero.size:
        out[zero] = (cx, cy)
    # Within the plate: the lower bound over the whole array at once (contiguous), the upper
    # per column (np.clip with per-column bounds is slow).
    np.maximum(out, 0.0, out=out)
    for axis, size in ((0, W), (1, H)):
        column = out[:, axis]
        np.minimum(column, size, out=column)
    return out.reshape(shape + (2,))
