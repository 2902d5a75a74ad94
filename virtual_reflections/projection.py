"""The paper's cube (§3.1): where on the plate each direction of the environment looks.

Directions are in the camera frame (CONVENTIONS.md): +Z is the viewing direction (the
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

import numpy as np

from .segmentation import Segmentation


def _split(a, at_plus, mid, at_minus):
    """Piecewise-linear map of a in [-1, 1]: -1 -> at_minus, 0 -> mid, +1 -> at_plus."""
    return mid + np.where(a >= 0, a * (at_plus - mid), -a * (at_minus - mid))


def plate_positions(directions: np.ndarray, seg: Segmentation, triangles: int = 0) -> np.ndarray:
    """Plate positions seen along camera-frame `directions`.

    directions: (..., 3) float, need not be normalised (zero vectors give the centre of X).
    Returns (..., 2) float64 continuous plate coordinates (x right, y down, within [0, W] x
    [0, H]); pixel (px, py) has its centre at (px + 0.5, py + 0.5).
    """
    d = np.asarray(directions, dtype=np.float64)
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    out = np.empty((d.shape[0], 2))

    X, inner = seg.x, seg.inner
    cx, cy = seg.centre
    W, H = float(seg.width), float(seg.height)

    # Face choice as OpenEXR's CubeMap::faceAndPixelPosition: x wins ties, then y.
    on_x = (ax >= ay) & (ax >= az)
    on_y = ~on_x & (ay >= az)
    on_z = ~on_x & ~on_y

    with np.errstate(divide="ignore", invalid="ignore"):
        # Back face (+Z): region X.
        m = on_z & (z > 0)
        h, w = x[m] / z[m], y[m] / z[m]
        out[m, 0] = _split(h, X.x0, cx, X.x1)
        out[m, 1] = _split(w, X.y0, cy, X.y1)

        # Left / right faces (+X / -X): regions L and R.
        m = on_x & (ax > 0)
        s = np.sign(x[m])
        w, t = y[m] / ax[m], 0.5 * (1.0 - z[m] / ax[m])
        edge_x, edge_i = np.where(s > 0, X.x0, X.x1), np.where(s > 0, inner.x0, inner.x1)
        out[m, 0] = edge_x + t * (edge_i - edge_x)
        out[m, 1] = (1 - t) * _split(w, X.y0, cy, X.y1) + t * _split(w, inner.y0, cy, inner.y1)

        # Top / bottom faces (+Y / -Y): regions T and B.
        m = on_y
        s = np.sign(y[m])
        h, t = x[m] / ay[m], 0.5 * (1.0 - z[m] / ay[m])
        edge_x, edge_i = np.where(s > 0, X.y0, X.y1), np.where(s > 0, inner.y0, inner.y1)
        out[m, 1] = edge_x + t * (edge_i - edge_x)
        out[m, 0] = (1 - t) * _split(h, X.x0, cx, X.x1) + t * _split(h, inner.x0, cx, inner.x1)

        # Front face (-Z): the ring F, four triangles with inverted orientation.
        m = on_z & ~(z > 0)
        h, w = x[m] / az[m], y[m] / az[m]
        horiz = np.abs(h) >= np.abs(w)  # in F'_L or F'_R, else F'_T or F'_B
        major = np.where(horiz, h, w)
        r = 1.0 - np.abs(major)  # 0 on the cube edge, 1 at the face centre
        s = np.where(horiz, w, h) / np.abs(major)  # along the base, in [-1, 1]
        s = np.nan_to_num(s, nan=0.0, posinf=1.0, neginf=-1.0)
        if triangles:
            k = triangles // 4
            i = np.clip(np.floor((s + 1.0) * 0.5 * k), 0, k - 1)
            apex_s = -1.0 + (2.0 * i + 1.0) / k
        else:
            apex_s = s
        plus = major > 0  # toward +X (left) or +Y (top)
        # Base on `inner`, apex on the image border, both split at the centre lines.
        base_fixed = np.where(
            horiz, np.where(plus, inner.x0, inner.x1), np.where(plus, inner.y0, inner.y1)
        )
        apex_fixed = np.where(horiz, np.where(plus, 0.0, W), np.where(plus, 0.0, H))
        base_along = np.where(
            horiz, _split(s, inner.y0, cy, inner.y1), _split(s, inner.x0, cx, inner.x1)
        )
        apex_along = np.where(horiz, _split(apex_s, 0.0, cy, H), _split(apex_s, 0.0, cx, W))
        fixed = (1 - r) * base_fixed + r * apex_fixed
        along = (1 - r) * base_along + r * apex_along
        out[m, 0] = np.where(horiz, fixed, along)
        out[m, 1] = np.where(horiz, along, fixed)

    # The zero vector (no face): the centre of X.
    zero = (ax == 0) & (ay == 0) & (az == 0)
    out[zero] = (cx, cy)
    np.clip(out[:, 0], 0.0, W, out=out[:, 0])
    np.clip(out[:, 1], 0.0, H, out=out[:, 1])
    return out.reshape(shape + (2,))
