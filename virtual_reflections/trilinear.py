"""Trilinear samples of the mip pyramid, stored compactly and read with NumPy or OpenCV.

A trilinear sample is bilinear on mip level L and on level L + 1, blended by the next
level's share. Instead of its 8 pyramid rows and weights (64 bytes), a texel keeps its
position on level L (x, y: float32, in that level's bordered pixel coordinates, pixel
centres at integers, see mipmap.py) and the share (float16): on level L + 1 the position is
(x / 2 + 1/4, y / 2 + 1/4). Texels are grouped by L (runs, each padded to a whole number of
ROW texels), so within a run the level, its row length and its offset in the flat pyramid
are numbers, not arrays; `rank` (int32) takes the runs' results back to map order. With
the rank: 14 bytes per texel.

Two back ends give the same samples (`gather`):

- NumPy (always there): per block of a run, the 8 rows and weights are worked out and read
  with one `take` and a weighted sum — the arithmetic of `table._bilinear`.
- OpenCV's `remap` (optional, used when `cv2` imports; VR_GATHER=numpy forces NumPy): each
  run is two remaps (levels L and L + 1) and a blend. Its bilinear weights are rounded to
  1/32 of a pixel (INTER_BITS = 5), so it differs from NumPy's by up to 1/64 of the step
  between neighbouring pixels (tests/engine/test_trilinear.py measures it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .opencv import backend, cv2
from .parallel import for_blocks

ROW = 256  # texels per row of a run: OpenCV remaps runs as (n / ROW, ROW) images
BLOCK = 8192  # texels per block of NumPy work: its taps stay in the cache
REMAP_ROWS = 16384  # rows of ROW texels per OpenCV remap (it takes fewer than 2^15 rows)


@dataclass(frozen=True, eq=False)
class Trilinear:
    """Trilinear samples grouped by their lower mip level (see the module docstring).

    levels: the lower level of each run; starts: run r is rows starts[r] .. starts[r + 1] - 1.
    x, y: (n,) float32 positions on the run's level (bordered pixel coordinates).
    upper: (n,) float16, the next level's share. rank: (T,) int32, each texel's row.
    """

    levels: tuple
    starts: tuple
    x: np.ndarray
    y: np.ndarray
    upper: np.ndarray
    rank: np.ndarray


def trilinear_samples(px, py, lod, top: int) -> Trilinear:
    """The compact samples of texels at level-0 plate positions (px, py) (T,) float32 with
    mip level `lod` (T,) float32 in [0, top]: bilinear on floor(lod) (at most top - 1) and the
    next level, blended by the fraction (as `table._bilinear`)."""
    lo = np.minimum(lod.astype(np.int32), max(top - 1, 0)).astype(np.uint8)
    counts = np.bincount(lo, minlength=top + 1)
    order = np.argsort(lo, kind="stable")  # map order within a level: reads stay local
    levels, starts, rank = [], [0], np.empty(lo.size, np.int32)
    padded = sum(-(-int(c) // ROW) * ROW for c in counts)
    x = np.ones(padded, np.float32)  # padding: pixel (0, 0) of the level, share 0
    y = np.ones(padded, np.float32)
    upper = np.zeros(padded, np.float16)
    taken = 0
    for level, count in enumerate(counts):
        count = int(count)
        if not count:
            continue
        ids = order[taken : taken + count]
        taken += count
        a = starts[-1]
        scale = np.float32(2.0**-level)
        x[a : a + count] = px[ids] * scale + np.float32(0.5)  # +1 border, -0.5 to centres
        y[a : a + count] = py[ids] * scale + np.float32(0.5)
        upper[a : a + count] = np.clip(lod[ids] - np.float32(level), 0.0, 1.0)
        rank[ids] = np.arange(a, a + count, dtype=np.int32)
        levels.append(level)
        starts.append(a + -(-count // ROW) * ROW)
    for array in (x, y, upper, rank):
        array.flags.writeable = False
    return Trilinear(tuple(levels), tuple(starts), x, y, upper, rank)


def gather(samples: Trilinear, source, shapes, offsets, out, use: str | None = None) -> None:
    """out (T, 3) float32 = the samples read from the flat bordered pyramid `source` (levels
    of `shapes` at row `offsets`), with `use` ("numpy", "opencv"; default `backend()`)."""
    use = use or backend()
    top = len(shapes) - 1
    values = np.empty((samples.starts[-1], 3), np.float32)
    for r, level in enumerate(samples.levels):
        a, b = samples.starts[r], samples.starts[r + 1]
        nxt = min(level + 1, top)
        if use == "opencv":
            images = _level(source, shapes, offsets, level), _level(source, shapes, offsets, nxt)
            for c in range(a, b, REMAP_ROWS * ROW):  # OpenCV remaps fewer than 2^15 rows
                _run_opencv(samples, c, min(c + REMAP_ROWS * ROW, b), *images, nxt > level, values)
        else:
            stride = (shapes[level][1] + 2, shapes[nxt][1] + 2)
            start = (int(offsets[level]), int(offsets[nxt]))
            _run_numpy(samples, a, b, stride, start, nxt > level, source, values)
    count = samples.rank.size

    def back(a, b):  # the runs' rows -> map order
        np.take(values, samples.rank[a:b], axis=0, out=out[a:b])

    for_blocks(back, count)


def _level(source, shapes, offsets, level):
    h, w = shapes[level]
    return source[int(offsets[level]) : int(offsets[level + 1])].reshape(h + 2, w + 2, 3)


def _run_numpy(samples, a, b, stride, start, halve, source, values) -> None:
    """Rows a .. b - 1 of one run, in blocks over the cores: 8 taps each, one take, a sum."""

    def block(c, d):
        n = d - c
        index = np.empty((n, 2, 4), np.int32)
        weight = np.empty((n, 2, 4), np.float32)
        x, y = samples.x[c:d], samples.y[c:d]
        up = samples.upper[c:d].astype(np.float32)
        for j, share in ((0, 1.0 - up), (1, up)):
            if j:
                if halve:
                    x = x * np.float32(0.5) + np.float32(0.25)
                    y = y * np.float32(0.5) + np.float32(0.25)
            x0, y0 = np.floor(x), np.floor(y)
            ax, ay = x - x0, y - y0
            base = y0.astype(np.int32)
            base *= stride[j]
            base += x0.astype(np.int32)
            base += start[j]
            tap = index[:, j]
            tap[:, 0] = base
            tap[:, 1] = base + 1
            base += stride[j]
            tap[:, 2] = base
            tap[:, 3] = base + 1
            bx, by = share - share * ax, 1 - ay  # the level's share folded into x
            ax *= share
            w = weight[:, j]
            np.multiply(bx, by, out=w[:, 0])
            np.multiply(ax, by, out=w[:, 1])
            np.multiply(bx, ay, out=w[:, 2])
            np.multiply(ax, ay, out=w[:, 3])
        taps = np.take(source, index.reshape(n, 8), axis=0, mode="clip")
        np.einsum("tkc,tk->tc", taps, weight.reshape(n, 8), out=values[c:d])

    span = b - a
    for_blocks(lambda c, d: block(a + c, a + d), span, min_rows=BLOCK, max_rows=BLOCK)


def _run_opencv(samples, a, b, image, image_next, halve, values) -> None:
    """Rows a .. b - 1 of one run: two remaps (levels L, L + 1) and their blend."""
    cv = cv2()
    x = samples.x[a:b].reshape(-1, ROW)
    y = samples.y[a:b].reshape(-1, ROW)
    low = cv.remap(image, x, y, cv.INTER_LINEAR, borderMode=cv.BORDER_REPLICATE)
    if halve:
        x = x * np.float32(0.5) + np.float32(0.25)
        y = y * np.float32(0.5) + np.float32(0.25)
    high = cv.remap(image_next, x, y, cv.INTER_LINEAR, borderMode=cv.BORDER_REPLICATE)
    low = low.reshape(-1, 3)
    high = high.reshape(-1, 3)
    up = samples.upper[a:b]

    def blend(c, d):
        res = values[a + c : a + d]
        np.subtract(high[c:d], low[c:d], out=res)
        res *= up[c:d, None]
        res += low[c:d]

    for_blocks(blend, b - a)
