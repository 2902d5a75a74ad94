"""Draw the paper's segmentation over a plate (like the paper's Fig. 2b, 3a and 9).

Regions are tinted — X, the side regions L/R/T/B and the four parts of the ring F each in
their own colour — and outlined: the object's box (dotted), the centre lines (dashed),
the face boundaries (diagonals) and, for n > 0, the n triangles cut from F.
"""

from __future__ import annotations

import numpy as np

from .segmentation import Rect, Segmentation

# Region colours (linear RGB): X, L, R, T, B, F_L, F_R, F_T, F_B.
REGION_NAMES = ("X", "L", "R", "T", "B", "F_L", "F_R", "F_T", "F_B")
REGION_COLOURS = np.array(
    [
        [1.0, 1.0, 1.0],
        [0.9, 0.1, 0.1],
        [0.1, 0.2, 0.9],
        [0.1, 0.8, 0.2],
        [0.9, 0.8, 0.1],
        [0.6, 0.0, 0.3],
        [0.0, 0.4, 0.6],
        [0.2, 0.5, 0.0],
        [0.6, 0.4, 0.0],
    ],
    dtype=np.float32,
)


def _ring_side(px, py, a: Rect, b: Rect):
    """For points between rectangle a (inside) and b (outside): 0 left, 1 right, 2 top,
    3 bottom — the side whose trapezoid holds them (the diagonals join the corners)."""
    eps = 1e-9
    out = np.stack(
        (
            (a.x0 - px) / max(a.x0 - b.x0, eps),
            (px - a.x1) / max(b.x1 - a.x1, eps),
            (a.y0 - py) / max(a.y0 - b.y0, eps),
            (py - a.y1) / max(b.y1 - a.y1, eps),
        )
    )
    return np.argmax(out, axis=0)


def region_labels(seg: Segmentation) -> np.ndarray:
    """(H, W) int8 index into REGION_NAMES for every plate pixel centre."""
    py, px = np.mgrid[0 : seg.height, 0 : seg.width].astype(np.float64) + 0.5
    X, inner = seg.x, seg.inner
    plate = Rect(0.0, 0.0, float(seg.width), float(seg.height))
    in_x = (px >= X.x0) & (px < X.x1) & (py >= X.y0) & (py < X.y1)
    in_inner = (px >= inner.x0) & (px < inner.x1) & (py >= inner.y0) & (py < inner.y1)
    labels = np.where(
        in_inner, 1 + _ring_side(px, py, X, inner), 5 + _ring_side(px, py, inner, plate)
    )
    return np.where(in_x, 0, labels).astype(np.int8)


def _draw_line(img, p, q, colour, width=1, dash=0):
    """Draw segment p->q (plate coordinates) into img (H, W, 3) in place."""
    h, w = img.shape[:2]
    length = float(np.hypot(q[0] - p[0], q[1] - p[1]))
    t = np.linspace(0.0, 1.0, max(2, int(length * 2) + 1))
    if dash:
        t = t[(np.floor(t * length / dash) % 2) == 0]
    x = p[0] + t * (q[0] - p[0])
    y = p[1] + t * (q[1] - p[1])
    r = width // 2
    for dx in range(-r, width - r):
        for dy in range(-r, width - r):
            xi = np.clip(np.floor(x).astype(int) + dx, 0, w - 1)
            yi = np.clip(np.floor(y).astype(int) + dy, 0, h - 1)
            img[yi, xi] = colour


def draw_segmentation(plate: np.ndarray, seg: Segmentation, triangles: int = 0) -> np.ndarray:
    """Draw the paper's regions on a plate.

    Parameters
    ----------
    plate : (H, W, 3) ndarray
        Scene-linear.
    seg : Segmentation
    triangles : int, optional
        The front face's n triangles (0: the continuous limit).

    Returns
    -------
    (H, W, 3) float32 ndarray
        Scene-linear, the plate with the regions drawn on it.
    """
    labels = region_labels(seg)
    img = 0.6 * np.asarray(plate, np.float32) + 0.4 * REGION_COLOURS[labels] * 0.5
    W, H = float(seg.width), float(seg.height)
    lw = max(1, int(round(min(W, H) / 300)))
    X, inner, (cx, cy) = seg.x, seg.inner, seg.centre
    white, black, yellow = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), (1.0, 0.85, 0.1)
    corners = lambda r: [(r.x0, r.y0), (r.x1, r.y0), (r.x1, r.y1), (r.x0, r.y1)]  # noqa: E731
    for rect in (X, inner):
        c = corners(rect)
        for i in range(4):
            _draw_line(img, c[i], c[(i + 1) % 4], white, lw)
    plate_c = corners(Rect(0, 0, W, H))
    for a, b, c in zip(corners(X), corners(inner), plate_c):
        _draw_line(img, a, b, white, lw)
        _draw_line(img, b, c, white, lw)
    # Centre lines split the side regions (paper Fig. 2b, dashed).
    _draw_line(img, (cx, 0), (cx, H), yellow, lw, dash=6 * lw)
    _draw_line(img, (0, cy), (W, cy), yellow, lw, dash=6 * lw)
    b = seg.bbox
    for p, q in zip(corners(b), corners(b)[1:] + corners(b)[:1]):
        _draw_line(
            img,
            (np.clip(p[0], 0, W), np.clip(p[1], 0, H)),
            (np.clip(q[0], 0, W), np.clip(q[1], 0, H)),
            black,
            lw,
            dash=2 * lw,
        )
    if triangles:
        for base, apex in triangle_edges(seg, triangles):
            _draw_line(img, base, apex, yellow, max(1, lw // 2))
    return img


def _split(s, at_plus, mid, at_minus):
    return mid + (s * (at_plus - mid) if s >= 0 else -s * (at_minus - mid))


def triangle_edges(seg: Segmentation, triangles: int):
    """The sides of the paper's n triangles in F: (base vertex, apex) pairs on the plate."""
    k = triangles // 4
    inner, (cx, cy) = seg.inner, seg.centre
    W, H = float(seg.width), float(seg.height)
    edges = []
    for i in range(k):
        s0, s1 = -1 + 2 * i / k, -1 + 2 * (i + 1) / k
        sm = 0.5 * (s0 + s1)
        for s in (s0, s1):
            edges.append(
                ((inner.x0, _split(s, inner.y0, cy, inner.y1)), (0.0, _split(sm, 0, cy, H)))
            )
            edges.append(((inner.x1, _split(s, inner.y0, cy, inner.y1)), (W, _split(sm, 0, cy, H))))
            edges.append(
                ((_split(s, inner.x0, cx, inner.x1), inner.y0), (_split(sm, 0, cx, W), 0.0))
            )
            edges.append(((_split(s, inner.x0, cx, inner.x1), inner.y1), (_split(sm, 0, cx, W), H)))
    return edges
