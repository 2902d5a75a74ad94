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
    out = np.empty((d.shape[0], 2), dtype=dtype)

    # The segmentation's numbers in the directions' precision: float32 directions are worked
    # on in float32 (Python floats in np.where would make every temporary float64).
    X, inner = _typed(seg.x, dtype), _typed(seg.inner, dtype)
    centre = tuple(dtype(v) for v in seg.centre)
    size = (dtype(seg.width), dtype(seg.height))
    with np.errstate(divide="ignore", invalid="ignore"):
        m, front, cube = _back_and_sides(d, X, inner, centre, out)
        if front.any():
            _front_face(cube, _where(front), inner, centre, size, triangles, out)

    # The zero vector (no face): the centre of X (m is 0 for it alone).
    zero = np.flatnonzero(m == 0)
    if zero.size:
        out[zero] = centre
    # Within the plate: the lower bound over the whole array at once (contiguous), the upper
    # per column (np.clip with per-column bounds is slow).
    np.maximum(out, 0.0, out=out)
    for axis, extent in enumerate(size):
        column = out[:, axis]
        np.minimum(column, extent, out=column)
    return out.reshape(shape + (2,))


def _back_and_sides(d, X, inner, centre, out):
    """The back face and the four side faces in one formula, on every direction at once (no
    gathers), written to out (N, 2); returns (m (N,) the largest |coordinate|, front (N,)
    bool the directions on the front face, cube: (u, v) their cube points).

    With m = max(|x|, |y|, |z|), the cube point is (u, v) = (x, y) / m and the depth
    t = (1 - z / m) / 2, and the plate position lerps between the split maps of X and of
    `inner`: x = cx + u (sX + t (sI - sX)), sX and sI the slopes of the splits on u's side
    (likewise y). On the back face t = 0 (region X); on a side face the dominant coordinate
    is +-1 (X's and `inner`'s edges); the faces meet without seams, so ties need no rule.
    The front face (-Z) is worked out after, for its directions alone (`_front_face`).
    """
    dtype = d.dtype.type
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    m = np.maximum(np.abs(x), np.abs(y))
    front = np.negative(z) > m  # -Z beats both (as OpenEXR: x wins ties, then y)
    np.maximum(m, np.abs(z), out=m)
    r = np.reciprocal(m)
    t = z * r
    t *= dtype(-0.5)
    t += dtype(0.5)  # 0 at the back edge, 1 at the front
    cube = [d[:, axis] * r for axis in (0, 1)]  # the cube point (u, v)
    cx, cy = centre
    for axis, (x0, x1, i0, i1, c) in enumerate(
        ((X.x0, X.x1, inner.x0, inner.x1, cx), (X.y0, X.y1, inner.y0, inner.y1, cy))
    ):
        u = cube[axis]
        plus = u >= 0
        # Slopes on each side of the centre line: X's, and the step to inner's.
        s_plus, s_minus = x0 - c, c - x1
        d_plus, d_minus = (i0 - c) - s_plus, (c - i1) - s_minus
        slope = np.where(plus, d_plus, d_minus)
        slope *= t
        slope += np.where(plus, s_plus, s_minus)
        slope *= u
        slope += c
        out[:, axis] = slope
    return m, front, cube


def _front_face(cube, idx, inner, centre, size, triangles, out):
    """The front face (-Z) of the directions `idx`, written to out[idx].

    The ring F, four triangles with inverted orientation, F'_L and F'_R where |h| >= |w|,
    else F'_T and F'_B. A point (h, w) of the face, scaled by 1 / max(|h|, |w|) to the
    face's edge, (qh, qw), lies on its triangle's base (on `inner`, split at the centre
    lines) and its apex on the image border, at the same position along the edge (with n
    triangles: the sub-triangle's middle): the position lerps from base to apex by
    rad = 1 - max(|h|, |w|).
    """
    (cx, cy), (W, H) = centre, size
    h, w = cube[0][idx], cube[1][idx]  # on this face m = |z|
    abs_h = np.abs(h)
    big = np.maximum(abs_h, np.abs(w))
    horiz = abs_h >= big
    rad = 1 - big
    middle = big == 0  # straight behind the camera: as F'_R's apex line
    big[middle] = 1
    h[middle] = -1
    qh, qw = h / big, w / big  # the major coordinate is +-1, the minor s
    ah, aw = qh, qw
    if triangles:  # the minor coordinate at its sub-triangle's apex
        k = triangles // 4
        apex = np.clip(np.floor((np.where(horiz, qw, qh) + 1.0) * (0.5 * k)), 0, k - 1)
        apex = (2.0 * apex + 1.0) / k - 1.0
        ah, aw = np.where(horiz, qh, apex), np.where(horiz, apex, qw)
    border = W.dtype.type(0)
    out[idx, 0] = _lerp(_split(qh, inner.x0, cx, inner.x1), _split(ah, border, cx, W), rad)
    out[idx, 1] = _lerp(_split(qw, inner.y0, cy, inner.y1), _split(aw, border, cy, H), rad)
