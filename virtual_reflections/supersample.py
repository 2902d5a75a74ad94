"""Supersampled texels, stored compactly and read with NumPy or OpenCV.

The camera view's seen texels are each the mean of K = n x n bilinear samples on one mip
level (camera_view.supersample_taps). Instead of 4 K pyramid rows and weights (32 K bytes:
512 for n = 4), a texel keeps its K positions on its level (x, y: float32, that level's
bordered pixel coordinates, pixel centres at integers, see mipmap.py): 8 K bytes. Texels are
grouped by level (runs), so within a run the level's size and offset are numbers.

The back ends (opencv.backend()): NumPy works out the 4 K rows and weights per block of
texels and reads them with one `take` and a weighted sum (the arithmetic of
camera_view.mean_taps: positions beyond the level's edge read its edge); OpenCV remaps each
run as an (S, K) image and averages its K columns (its bilinear weights rounded to 1/32).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .opencv import backend, cv2
from .parallel import for_blocks

BLOCK = 1024  # texels per block of NumPy work (K samples, 4 K taps each)
REMAP_ROWS = 16384  # texels per OpenCV remap (it takes fewer than 2^15 rows)


@dataclass(frozen=True, eq=False)
class Supersample:
    """texels: (S,) int64 flat map indices, grouped by level; levels, starts: run r is rows
    starts[r] .. starts[r + 1] - 1 on level levels[r]; x, y: (S, K) float32 positions."""

    texels: np.ndarray
    levels: tuple
    starts: tuple
    x: np.ndarray
    y: np.ndarray

    def without(self, drop: np.ndarray) -> Supersample:
        """These samples without the texels where the (T,) bool mask `drop` is set."""
        keep = ~drop[self.texels]
        counts = [int(keep[a:b].sum()) for a, b in zip(self.starts, self.starts[1:])]
        levels = tuple(v for v, c in zip(self.levels, counts) if c)
        starts = tuple(np.cumsum([0] + [c for c in counts if c]).tolist())
        parts = [self.texels[keep], self.x[keep], self.y[keep]]
        _frozen(*parts)
        return Supersample(parts[0], levels, starts, parts[1], parts[2])


def _frozen(*arrays):
    for a in arrays:
        a.flags.writeable = False


def supersamples(texels, positions, level) -> Supersample:
    """The compact form of `texels` (S,) read as the mean of the bilinear samples at
    `positions` (K pairs of (S,) level-0 plate coordinates px, py) on mip `level` (S,)."""
    level = np.asarray(level, np.int64)
    order = np.argsort(level, kind="stable")
    count = level.size
    k = len(positions)
    x = np.empty((count, k), np.float32)
    y = np.empty((count, k), np.float32)
    scale = 2.0 ** -level[order].astype(np.float64)
    for j, (px, py) in enumerate(positions):
        x[:, j] = np.asarray(px, np.float64)[order] * scale + 0.5  # +1 border, -0.5 centres
        y[:, j] = np.asarray(py, np.float64)[order] * scale + 0.5
    runs, counts = np.unique(level, return_counts=True)
    starts = tuple(np.concatenate(([0], np.cumsum(counts))).tolist())
    ids = np.asarray(texels, np.int64)[order]
    _frozen(ids, x, y)
    return Supersample(ids, tuple(int(v) for v in runs), starts, x, y)


def gather(samples: Supersample, source, shapes, offsets, out, use: str | None = None) -> None:
    """out[texels] (out: (T, 3) float32) = the mean of each texel's samples read from the
    flat bordered pyramid `source` (levels of `shapes` at rows `offsets`)."""
    use = use or backend()
    for r, level in enumerate(samples.levels):
        a, b = samples.starts[r], samples.starts[r + 1]
        h, w = shapes[level]
        if use == "opencv":
            cv = cv2()
            image = source[int(offsets[level]) : int(offsets[level + 1])].reshape(h + 2, w + 2, 3)
            for c in range(a, b, REMAP_ROWS):  # OpenCV remaps fewer than 2^15 rows
                d = min(c + REMAP_ROWS, b)
                read = cv.remap(image, samples.x[c:d], samples.y[c:d], cv.INTER_LINEAR,
                                borderMode=cv.BORDER_REPLICATE)  # fmt: skip
                # The mean of each row's K samples: one matrix product (n, 3 K) @ (3 K, 3).
                mean = np.tile(np.eye(3, dtype=np.float32), (read.shape[1], 1)) / read.shape[1]
                out[samples.texels[c:d]] = read.reshape(d - c, -1) @ mean
        else:
            _run_numpy(samples, a, b, (h, w), int(offsets[level]), source, out)


def _run_numpy(samples, a, b, shape, start, source, out) -> None:
    h, w = shape
    stride = w + 2
    k = samples.x.shape[1]
    share = np.float32(1.0 / k)

    def block(c, d):
        c, d = a + c, a + d
        x, y = samples.x[c:d], samples.y[c:d]
        i0, j0 = np.floor(x), np.floor(y)
        ax, ay = x - i0, y - j0
        i0, j0 = i0.astype(np.int32), j0.astype(np.int32)
        c0 = np.clip(i0, 0, w + 1)
        c1 = np.clip(i0 + 1, 0, w + 1)
        r0 = np.clip(j0, 0, h + 1) * stride + start
        r1 = np.clip(j0 + 1, 0, h + 1) * stride + start
        index = np.empty(x.shape + (4,), np.int32)
        weight = np.empty(x.shape + (4,), np.float32)
        index[..., 0], index[..., 1] = r0 + c0, r0 + c1
        index[..., 2], index[..., 3] = r1 + c0, r1 + c1
        bx, by = 1 - ax, (1 - ay) * share
        ay *= share
        weight[..., 0], weight[..., 1] = by * bx, by * ax
        weight[..., 2], weight[..., 3] = ay * bx, ay * ax
        n = d - c
        taps = np.take(source, index.reshape(n, -1), axis=0, mode="clip")
        out[samples.texels[c:d]] = np.einsum("tkc,tk->tc", taps, weight.reshape(n, -1))

    for_blocks(block, b - a, min_rows=BLOCK, max_rows=BLOCK)
