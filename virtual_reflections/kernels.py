"""The per-frame gathers compiled with Numba (optional: backends.py imports this module only
when `numba` imports; Blender bundles it not, and every kernel here has a NumPy path that
stays the reference).

Each kernel does in one pass, over the cores, what the NumPy path does in several: the same
taps, the same float32 weights worked out the same way (trilinear.py, supersample.py,
extension.py, fill.py), summed in float32, so the maps agree with NumPy's to float32
rounding (tests/engine/test_kernels.py). Reading the taps where they lie instead of copying
them into a (n, taps, 3) array first is what makes them faster: NumPy's `take` of 12-byte
rows is about 8 ns a tap, a compiled loop reads them from the cache.

Compiled on first use and cached on disk (Numba's cache, in the user's cache folder or
NUMBA_CACHE_DIR: backends.cache_folder, never beside this file): a new process pays ~1 s for
the first map (importing Numba, loading the kernels), the first ever ~10 s to compile them.
This module imports nothing of the engine (backends.py loads it under one name whatever the
package is called): ROW repeats trilinear.ROW, which a test holds equal.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

ONE = np.float32(1.0)
HALF = np.float32(0.5)
QUARTER = np.float32(0.25)
TWO = np.float32(2.0)
ROW = 2048  # trilinear.ROW: a run's rows as (row % ROW, row // ROW)
FUSED = 4  # levels of the pyramid made together, in stripes (`pyramid`)


@njit(inline="always")
def _weights(x, y, share):
    """The bilinear weights of (x, y) as trilinear._run_numpy works them out (the level's
    share folded into x), and the top-left pixel (x0, y0) as integers."""
    x0 = np.floor(x)
    y0 = np.floor(y)
    ax = x - x0
    ay = y - y0
    bx = share - share * ax
    by = ONE - ay
    ax = ax * share
    return bx * by, ax * by, bx * ay, ax * ay, np.int64(x0), np.int64(y0)


@njit(inline="always")
def _flat(array):
    """A C-contiguous array's values along one axis, read below with unsigned indices: no
    fix-up for negative indices and no multiply by a row length per read (the trilinear
    kernel 7.1 against 9.4 ms, docs/benchmarks.md)."""
    return array.reshape(array.size)


@njit(inline="always")
def _u(n):
    return np.uint64(n)


@njit(inline="always")
def _sum(src, a, b, c, d, w00, w01, w10, w11):
    """The weighted sum (3 float32) of pixels a, b, c, d of src (a `_flat` (n, 3) array)."""
    a, b, c, d = _u(3) * _u(a), _u(3) * _u(b), _u(3) * _u(c), _u(3) * _u(d)
    one, two = _u(1), _u(2)
    return (
        w00 * src[a] + w01 * src[b] + w10 * src[c] + w11 * src[d],
        w00 * src[a + one] + w01 * src[b + one] + w10 * src[c + one] + w11 * src[d + one],
        w00 * src[a + two] + w01 * src[b + two] + w10 * src[c + two] + w11 * src[d + two],
    )


@njit(inline="always")
def _put(out, t, v0, v1, v2):
    """Pixel t of out (a `_flat` (n, 3) array) = (v0, v1, v2)."""
    o = _u(3) * _u(t)
    out[o] = v0
    out[o + _u(1)] = v1
    out[o + _u(2)] = v2


@njit(inline="always")
def _g(geometry, r, j, k):
    """geometry[r, j, k] of the `_flat` (runs, 3, 5) geometry (`_trilinear`)."""
    return geometry[_u((r * 3 + j) * 5 + k)]


@njit(inline="always")
def _level(r, j, source, plate, geometry, x, y, share):
    """share x the bilinear sample (3 float32) at (x, y) (bordered coordinates, pixel centres
    at integers) of level j of run r (0: L, 1: the next; `_trilinear`'s geometry). A level of
    the flat bordered pyramid is read as NumPy's take reads it (the row base + (0, 1, stride,
    stride + 1), clipped to the array); the plate itself, unbordered, a pixel to the left and
    up, each coordinate held to its edge (what the border repeats)."""
    w00, w01, w10, w11, x0, y0 = _weights(x, y, share)
    stride = _g(geometry, r, j, 1)
    if _g(geometry, r, j, 4) == 0:
        a = min(max(_g(geometry, r, j, 0) + y0 * stride + x0, 0), source.size // 3 - stride - 2)
        return _sum(source, a, a + 1, a + stride, a + stride + 1, w00, w01, w10, w11)
    right, bottom = _g(geometry, r, j, 2), _g(geometry, r, j, 3)
    c0 = min(max(x0 - 1, 0), right)
    c1 = min(max(x0, 0), right)
    r0 = min(max(y0 - 1, 0), bottom) * stride
    r1 = min(max(y0, 0), bottom) * stride
    return _sum(plate, r0 + c0, r0 + c1, r1 + c0, r1 + c1, w00, w01, w10, w11)


@njit(inline="always")
def _trilinear(row, r, x, y, upper, shares, geometry, source, plate):
    """The trilinear sample (3 float32) of row `row` of run `r` (trilinear.py). geometry:
    (runs, 3, 5) int64: per level of the run (L, next) its offset in `source`, row length,
    last column, last row, and 1 when it is the plate itself (unbordered) rather than a level
    of `source`; then (single: the run reads level L alone, halve: next = L + 1, 0, 0, 0)."""
    xr = x[_u(row)]
    yr = y[_u(row)]
    if _g(geometry, r, 2, 0) != 0:  # single
        return _level(r, 0, source, plate, geometry, xr, yr, ONE)
    up = shares[_u(upper[_u(row)])]
    a0, a1, a2 = _level(r, 0, source, plate, geometry, xr, yr, ONE - up)
    if _g(geometry, r, 2, 1) != 0:  # halve
        xr = xr * HALF + QUARTER
        yr = yr * HALF + QUARTER
    b0, b1, b2 = _level(r, 1, source, plate, geometry, xr, yr, up)
    return a0 + b0, a1 + b1, a2 + b2


@njit(parallel=True, cache=True)
def trilinear_map(x, y, upper, shares, rank, starts, geometry, source, plate, out):
    """out (H, W, 3) = every texel's trilinear sample, texel (i, j) read at its row of the
    runs (rank (H, W, 2) int16: row % ROW, row // ROW; run r holds rows starts[r] ..
    starts[r + 1] - 1, a whole number of ROW rows)."""
    # Runs hold whole rows of ROW texels: the run of every ROW-row block, looked up.
    blocks = np.empty(starts[-1] // ROW, np.int64)
    for r in range(starts.size - 1):
        blocks[starts[r] // ROW : starts[r + 1] // ROW] = r
    height, width = rank.shape[0], rank.shape[1]
    rank, geometry, source, plate = _flat(rank), _flat(geometry), _flat(source), _flat(plate)
    out = _flat(out)
    for i in prange(height):
        _trilinear_row(i, width, blocks, x, y, upper, shares, rank, geometry, source, plate, out)


@njit(inline="always")
def _trilinear_row(i, width, blocks, x, y, upper, shares, rank, geometry, source, plate, out):
    """`trilinear_map`'s row i (of `width` texels; rank and out `_flat`)."""
    for j in range(width):
        t = i * width + j
        block = rank[_u(2 * t + 1)]
        row = np.int64(block) * ROW + np.int64(rank[_u(2 * t)])
        r = blocks[_u(block)]
        v0, v1, v2 = _trilinear(row, r, x, y, upper, shares, geometry, source, plate)
        _put(out, t, v0, v1, v2)


@njit(parallel=True, cache=True)
def extension_runs(x, y, upper, shares, firsts, counts, done, geometry, texels, weight,
                   source, plate, out):  # fmt: skip
    """out[texels] = the extension (extension.py): run r's first counts[r] rows (from
    firsts[r]) are texels[done[r] ..]; faded into the fill already in `out` by `weight`
    (a 0-length weight: the extension alone)."""
    fade = weight.size > 0
    geometry, source, plate, out = _flat(geometry), _flat(source), _flat(plate), _flat(out)
    for i in prange(texels.size):
        r = np.searchsorted(done, i, side="right") - 1
        row = firsts[r] + (i - done[r])
        v0, v1, v2 = _trilinear(row, r, x, y, upper, shares, geometry, source, plate)
        t = texels[i]
        if fade:
            w = weight[i]
            o = _u(3) * _u(t)
            f0, f1, f2 = out[o], out[o + _u(1)], out[o + _u(2)]
            v0, v1, v2 = (v0 - f0) * w + f0, (v1 - f1) * w + f1, (v2 - f2) * w + f2
        _put(out, t, v0, v1, v2)


@njit(parallel=True, cache=True)
def supersample_runs(base, fx, fy, starts, strides, on_plate, texels, source, plate, out):
    """out[texels] = the mean of each texel's K bilinear samples (supersample.py): sample j
    of row i reads rows base[i, j] + (0, 1, stride, stride + 1) of the plate (its run on
    level 0) or of the flat pyramid, weighted by its uint16 steps fx, fy."""
    k = base.shape[1]
    scale = np.float32(1.0 / 65535)
    share = np.float32(1.0 / k)
    runs = starts.size - 1
    source, plate, out = _flat(source), _flat(plate), _flat(out)
    for i in prange(starts[runs]):
        r = np.searchsorted(starts, i, side="right") - 1
        stride = strides[r]
        src = plate if on_plate[r] else source
        acc0 = np.float32(0.0)
        acc1 = np.float32(0.0)
        acc2 = np.float32(0.0)
        for j in range(k):
            b = np.int64(base[i, j])
            ax = np.float32(fx[i, j]) * scale
            ay = np.float32(fy[i, j]) * scale
            bx = ONE - ax
            by = (ONE - ay) * share
            ay = ay * share
            w00 = by * bx
            w01 = by * ax
            w10 = ay * bx
            w11 = ay * ax
            s0, s1, s2 = _sum(src, b, b + 1, b + stride, b + stride + 1, w00, w01, w10, w11)
            acc0 += s0
            acc1 += s1
            acc2 += s2
        _put(out, texels[i], acc0, acc1, acc2)


@njit(parallel=True, cache=True)
def weighted_rows(source, index, weight, texels, out):
    """out[texels[i]] (every row i when texels is empty) = sum_k weight[i, k] source[index[i, k]]
    (indices beyond the source read its last row, as NumPy's take with mode "clip")."""
    last = source.shape[0] - 1
    every = texels.size == 0
    source, out = _flat(source), _flat(out)
    for n in prange(index.shape[0]):
        i = np.int64(n)
        acc0 = np.float32(0.0)
        acc1 = np.float32(0.0)
        acc2 = np.float32(0.0)
        for k in range(index.shape[1]):
            j = _u(3) * _u(min(max(np.int64(index[i, k]), 0), last))
            w = weight[i, k]
            acc0 += w * source[j]
            acc1 += w * source[j + _u(1)]
            acc2 += w * source[j + _u(2)]
        _put(out, i if every else np.int64(texels[i]), acc0, acc1, acc2)


@njit(parallel=True, cache=True)
def fill_rows(steps, side, lookup, width, out):
    """The fill of a lat-long (fill.fill_values): out (rows * width, 3) from each row's step
    (steps (rows,)) or each texel's (steps (rows * width,)) in `lookup` (sides, n, 3), the
    two sides blended by side (3 width,) (the left's weight per column and channel; a
    0-length side: the left side alone)."""
    rows = out.shape[0] // width
    per_row = steps.size == rows
    blend = side.size > 0
    right = _u(3 * lookup.shape[1]) if lookup.shape[0] > 1 else _u(0)
    lookup, out = _flat(lookup), _flat(out)
    for n in prange(rows):
        r = np.int64(n)
        for col in range(width):
            t = r * width + col
            s = _u(3) * _u(steps[r] if per_row else steps[t])
            o = _u(3) * _u(t)
            for c in range(3):
                left = lookup[s + _u(c)]
                if blend:
                    w = side[_u(3 * col + c)]
                    out[o + _u(c)] = left * w + lookup[right + s + _u(c)] * (ONE - w)
                else:
                    out[o + _u(c)] = left


@njit(parallel=True, cache=True)
def halve(src, dst):
    """dst ((h + 1) // 2, (w + 1) // 2, 3) = the means of src's (h, w, 3) 2 x 2 blocks, as
    mipmap._halve works them out (`_halve_row`)."""
    for i in prange(dst.shape[0]):
        _halve_row(src, 0, src.shape[0], src.shape[1], np.int64(i), dst, 0)


@njit(inline="always")
def _halve_row(src, s, h, w, i, dst, off):
    """Row i of the means of src's h x w pixels' 2 x 2 blocks (from row and column s: 1 for
    a bordered level) into dst's row i + off, from column off (1: a bordered level), as
    mipmap._halve works them out: each pair of rows summed and scaled by 1/4, then pairs of
    columns added; an odd last row or column repeated."""
    r = s + 2 * i
    wide = (w + 1) // 2
    if 2 * i + 1 < h:
        for j in range(w // 2):
            for c in range(3):
                left = (src[r, s + 2 * j, c] + src[r + 1, s + 2 * j, c]) * QUARTER
                right = (src[r, s + 2 * j + 1, c] + src[r + 1, s + 2 * j + 1, c]) * QUARTER
                dst[i + off, j + off, c] = left + right
        if w % 2:
            for c in range(3):
                pair = (src[r, s + w - 1, c] + src[r + 1, s + w - 1, c]) * QUARTER
                dst[i + off, wide - 1 + off, c] = TWO * pair
        return
    for j in range(w // 2):  # an odd last row: its own pairs, halved and added
        for c in range(3):
            dst[i + off, j + off, c] = src[r, s + 2 * j, c] * HALF + src[r, s + 2 * j + 1, c] * HALF
    if w % 2:
        for c in range(3):
            dst[i + off, wide - 1 + off, c] = TWO * (src[r, s + w - 1, c] * HALF)


@njit(inline="always")
def _blocks_row(src, k, i, dst, rows):
    """Row i of the means of src's k x k blocks (its sides multiples of k) into dst's row
    i + 1, from column 1 (a bordered level), as mipmap._blocks works them out: k rows summed
    in order and scaled by 1 / k^2, then k columns added in order; rows: a (width, 3)
    scratch row (contiguous reads of the plate: 1.5x faster than block by block)."""
    scale = np.float32(1.0 / (k * k))
    width = src.shape[1]
    summed = rows.reshape(3 * width)  # whole rows as flat runs of floats: vectorised
    top = src[k * i].reshape(3 * width)
    for t in range(3 * width):
        summed[t] = top[t]
    for p in range(1, k):
        row = src[k * i + p].reshape(3 * width)
        for t in range(3 * width):
            summed[t] += row[t]
    for t in range(3 * width):
        summed[t] *= scale
    for j in range(width // k):
        for c in range(3):
            total = rows[k * j, c]
            for q in range(1, k):
                total += rows[k * j + q, c]
            dst[i + 1, j + 1, c] = total


@njit(inline="always")
def _border(level):
    """Repeat a bordered level's edge pixels into its border: the first and last rows, then
    the first and last columns (mipmap._fill_border)."""
    h, w = level.shape[0], level.shape[1]
    for j in range(w):
        for c in range(3):
            level[0, j, c] = level[1, j, c]
            level[h - 1, j, c] = level[h - 2, j, c]
    for i in range(h):
        for c in range(3):
            level[i, 0, c] = level[i, 1, c]
            level[i, w - 1, c] = level[i, w - 2, c]


@njit(inline="always")
def _bordered(flat, levels, m):
    """Level m of `levels` as an (h + 2, w + 2, 3) view of flat."""
    o, h, w = levels[m, 0], levels[m, 1], levels[m, 2]
    return flat[o : o + (h + 2) * (w + 2)].reshape((h + 2, w + 2, 3))


@njit(parallel=True, cache=True)
def pyramid(plate, k, levels, flat):
    """The flat bordered pyramid's levels (mipmap.build_pyramid) in one call: levels (n, 3)
    int64 holds each level's row offset in flat, its height and width, from the first, the
    means of the (H, W, 3) plate's k x k blocks (k = 2: halved, else its sides multiples of
    k), to the last, each the one before halved. The first FUSED levels are made in stripes
    over the cores — a stripe is one row of the last of them, made from the rows above it
    while they are in the cache; the small rest one after the other."""
    n = levels.shape[0]
    depth = min(n, FUSED)
    for n_i in prange(levels[depth - 1, 1]):
        i = np.int64(n_i)
        rows = np.empty((plate.shape[1] if k > 2 else 0, 3), np.float32)
        for m in range(depth):
            span = np.int64(1) << (depth - 1 - m)
            level = _bordered(flat, levels, m)
            for r in range(i * span, min((i + 1) * span, levels[m, 1])):
                if m > 0:
                    above = _bordered(flat, levels, m - 1)
                    _halve_row(above, 1, levels[m - 1, 1], levels[m - 1, 2], r, level, 1)
                elif k == 2:
                    _halve_row(plate, 0, plate.shape[0], plate.shape[1], r, level, 1)
                else:
                    _blocks_row(plate, k, r, level, rows)
    for m in range(n):
        level = _bordered(flat, levels, m)
        if m >= depth:
            above = _bordered(flat, levels, m - 1)
            for i in range(levels[m, 1]):
                _halve_row(above, 1, levels[m - 1, 1], levels[m - 1, 2], i, level, 1)
        _border(level)
