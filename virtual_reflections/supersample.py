"""Supersampled texels, stored compactly, read with NumPy.

The camera view's seen texels are each the mean of K = n x n bilinear samples on one mip
level (seen_texels.supersample_taps). Instead of 4 K pyramid rows and weights (32 K bytes:
512 for n = 4), a sample keeps its top-left row of the flat pyramid (int32) and its position
between that pixel and the next in x and in y (uint16 steps of 1/65535): 8 K bytes. Texels
are grouped by level (runs), so within a run the level's row length is a number: per frame
a block's 4 K rows are the bases plus (0, 1, row, row + 1), its weights the products of the
fractions (the arithmetic of seen_texels.mean_taps; positions beyond the level's edge read
its edge), read with one `take` and a weighted sum.

Samples on level 0 read the plate itself (its rows unbordered, `gather`'s `plate`), not a
copy of it in the pyramid: a sample keeps a left pixel with a right neighbour (at most the
next-to-last) and a step up to 1, which reads the edge as the border would. So a table whose
other texels need no level 0 spares every frame the plate's copy into the pyramid.

With Numba (optional, backends.py) one compiled pass reads them (kernels.py), with these
weights. Not OpenCV's remap: its bilinear weights are rounded to 1/32, which moved the accuracy
study's mean PSNR where the plate sees from 57.08 to 57.02 dB (`python -m study evaluate
--quick`): these texels are what that figure measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .backends import backend, given, kernels, run
from .parallel import for_blocks
from .taps import put_rows, weighted_sum

BLOCK = 1024  # texels per block when building
GATHER_BLOCK = 2048  # texels per block of the per-frame gather (K samples, 4 K taps each;
# 1024 was 10-20 % slower on 2 cores: more Python between the NumPy calls)
STEPS = 65535  # a sample's position between two pixels, in uint16 steps


@dataclass(frozen=True, eq=False)
class Supersample:
    """texels: (S,) int64 flat map indices, grouped by level; strides, starts: run r is rows
    starts[r] .. starts[r + 1] - 1, on a level whose rows are strides[r] long; base: (S, K)
    int32 rows of the flat pyramid (of the plate's for a run on the plate); fx, fy: (S, K)
    uint16 steps; on_plate: per run, whether it is level 0 read from the plate itself."""

    texels: np.ndarray
    strides: tuple
    starts: tuple
    base: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    on_plate: tuple

    def without(self, drop: np.ndarray) -> Supersample:
        """These samples without the texels where the (T,) bool mask `drop` is set."""
        keep = ~drop[self.texels]
        counts = [int(keep[a:b].sum()) for a, b in zip(self.starts, self.starts[1:])]
        strides = tuple(v for v, c in zip(self.strides, counts) if c)
        on_plate = tuple(v for v, c in zip(self.on_plate, counts) if c)
        starts = tuple(np.cumsum([0] + [c for c in counts if c]).tolist())
        parts = [a[keep] for a in (self.texels, self.base, self.fx, self.fy)]
        _frozen(*parts)
        return Supersample(parts[0], strides, starts, *parts[1:], on_plate=on_plate)


def _frozen(*arrays):
    for a in arrays:
        a.flags.writeable = False


def supersamples(texels, positions, level, shapes, offsets) -> Supersample:
    """The compact form of `texels` (S,) read as the mean of the bilinear samples at
    `positions` (K pairs of (S,) level-0 plate coordinates px, py) on mip `level` (S,) of
    the flat bordered pyramid with level `offsets` (level 0: of the plate itself)."""
    level = np.asarray(level, np.int64)
    order = np.argsort(level, kind="stable")
    level = level[order]
    count, k = level.size, len(positions)
    base = np.empty((count, k), np.int32)
    fx = np.empty((count, k), np.uint16)
    fy = np.empty((count, k), np.uint16)
    widths = np.array([w for _, w in shapes], np.int64)
    heights = np.array([h for h, _ in shapes], np.int64)
    starts_all = np.asarray(offsets, np.int64)

    def block(a, b):  # texels a .. b - 1 in level order, over the cores
        lv = level[a:b]
        scale = 2.0**-lv
        width, height, start = widths[lv], heights[lv], starts_all[lv]
        at = order[a:b]
        for j, (px, py) in enumerate(positions):
            cols, ax = _cell(np.asarray(px[at], np.float64) * scale + 0.5, width)
            rows, ay = _cell(np.asarray(py[at], np.float64) * scale + 0.5, height)
            base[a:b, j] = start + rows * (width + 2) + cols
            fx[a:b, j], fy[a:b, j] = ax, ay

    def on_plate(a, b):  # texels a .. b - 1 on level 0: rows of the plate itself
        height, width = shapes[0]
        at = order[a:b]
        for j, (px, py) in enumerate(positions):
            cols, ax = _plate_cell(np.asarray(px[at], np.float64) - 0.5, width)
            rows, ay = _plate_cell(np.asarray(py[at], np.float64) - 0.5, height)
            base[a:b, j] = rows * width + cols
            fx[a:b, j], fy[a:b, j] = ax, ay

    plate_rows = int(np.searchsorted(level, 1))  # level order: level 0 first
    for_blocks(on_plate, plate_rows, min_rows=BLOCK, max_rows=32 * BLOCK)
    for_blocks(
        lambda a, b: block(plate_rows + a, plate_rows + b),
        count - plate_rows,
        min_rows=BLOCK,
        max_rows=32 * BLOCK,
    )
    runs, counts = np.unique(level, return_counts=True)
    starts = tuple(np.concatenate(([0], np.cumsum(counts))).tolist())
    ids = np.asarray(texels, np.int64)[order]
    _frozen(ids, base, fx, fy)
    strides = tuple(int(shapes[v][1]) + (0 if v == 0 else 2) for v in runs)
    on = tuple(bool(v == 0) for v in runs)
    return Supersample(ids, strides, starts, base, fx, fy, on_plate=on)


def _cell(u, size):
    """Bordered coordinates u (pixel centres at integers, u >= 0.5) on a level `size` wide:
    the left pixel and the step toward the next; beyond the last pixel (size + 1), its own."""
    i0 = np.floor(u)
    a = u - i0
    i0 = i0.astype(np.int64)
    edge = i0 >= size + 1
    i0 = np.where(edge, size, np.maximum(i0, 0))
    a = np.where(edge, 1.0, a)
    return i0, np.rint(a * STEPS).astype(np.uint16)


def _plate_cell(v, size):
    """Unbordered coordinates v (pixel centres at integers 0 .. size - 1) on the plate: the
    left pixel, at most size - 2 so that its right neighbour is a pixel, and the step toward
    it (up to 1); beyond the first or the last centre, that pixel (what the border reads)."""
    v = np.minimum(np.maximum(v, 0.0), size - 1.0)  # (np.clip's own loop is ~5x slower)
    i0 = np.minimum(np.floor(v), max(size - 2, 0))
    v -= i0  # the step, at most 1
    v *= STEPS
    return i0.astype(np.int64), np.rint(v, out=v).astype(np.uint16)


def gather(samples: Supersample, source, out, plate=None) -> None:
    """out[texels] (out: (T, 3) float32) = the mean of each texel's samples read from the
    flat bordered pyramid `source`, and for the runs on level 0 from `plate` ((H * W, 3)
    float32, the plate's rows)."""
    if any(samples.on_plate) and plate is None:
        raise ValueError("these samples read level 0 from the plate: pass it")
    if not all(samples.on_plate) and source is None:  # (the compiled pass reads unchecked)
        raise ValueError("these samples read the pyramid's levels: pass it")
    if backend() == "numba":
        run(kernels().supersample_runs, samples.base, samples.fx, samples.fy,
            np.asarray(samples.starts, np.int64), np.asarray(samples.strides, np.int64),
            np.asarray(samples.on_plate, np.bool_), samples.texels,
            given(source, 3), given(plate, 3), out)  # fmt: skip
        return
    k = samples.base.shape[1]
    scale = np.float32(1.0 / STEPS)
    share = np.float32(1.0 / k)
    for r, stride in enumerate(samples.strides):
        a = samples.starts[r]
        corners = (0, 1, stride, stride + 1)
        rows = plate if samples.on_plate[r] else source

        def block(c, d, a=a, corners=corners, rows=rows):
            c, d = a + c, a + d
            n = d - c
            # Corner-major (n, 4, K): every step works on whole (n, K) slabs.
            index = np.empty((n, 4, k), np.int32)
            base = samples.base[c:d]
            for j in range(4):
                np.add(base, corners[j], out=index[:, j])
            ax = samples.fx[c:d] * scale
            ay = samples.fy[c:d] * scale
            bx, by = 1 - ax, (1 - ay) * share
            ay *= share
            weight = np.empty((n, 4 * k), np.float32)
            w = weight.reshape(n, 4, k)
            np.multiply(by, bx, out=w[:, 0])
            np.multiply(by, ax, out=w[:, 1])
            np.multiply(ay, bx, out=w[:, 2])
            np.multiply(ay, ax, out=w[:, 3])
            taps = np.take(rows, index.reshape(n, -1), axis=0, mode="clip")
            sums = np.empty((n, 3), np.float32)
            weighted_sum(taps, weight, sums)
            put_rows(out, samples.texels[c:d], sums)

        for_blocks(block, samples.starts[r + 1] - a, min_rows=GATHER_BLOCK, max_rows=GATHER_BLOCK)
