"""Trilinear samples of the mip pyramid, stored compactly and read with NumPy or OpenCV.

A trilinear sample is bilinear on mip level L and on level L + 1, blended by the next
level's share. Instead of its 8 pyramid rows and weights (64 bytes), a texel keeps its
position on level L (x, y: float32, in that level's bordered pixel coordinates, pixel
centres at integers, see mipmap.py) and the share (float16): on level L + 1 the position is
(x / 2 + 1/4, y / 2 + 1/4). Texels are grouped by L (runs, each padded to a whole number of
ROW texels; within a level, those with share 0 apart: their runs read level L alone), so
within a run the level, its row length and its offset in the flat pyramid are numbers, not
arrays; `rank` (two int16) takes the runs' results back to map order. With the rank: 14
bytes per texel.

Three back ends give the same samples (`gather`; backends.py picks one):

- NumPy (always there): per block of a run, the 8 rows and weights are worked out and read
  with one `take` and a weighted sum.
- OpenCV's `remap` (optional, used when `cv2` imports; VR_GATHER=numpy forces NumPy): each
  run is two remaps (levels L and L + 1) and a blend (`blendLinear`), and the way back to map
  order one nearest-pixel remap; level 0 may be the plate itself (`gather`'s `plate`). Its
  bilinear weights are rounded to 1/32 of a pixel (INTER_BITS = 5): it differs from NumPy's
  by at most 1/32 of the largest step between neighbouring pixels
  (tests/engine/test_compact_samples.py measures it).
- Numba (optional, used first when `numba` imports): one compiled pass over the map's texels,
  each read at its row of the runs with the NumPy path's weights (kernels.py); level 0 may be
  the plate itself, as for OpenCV.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .backends import backend, cv2, given, kernels, run
from .parallel import for_blocks
from .taps import weighted_sum

ROW = 2048  # texels per row of a run (a power of 2): OpenCV remaps runs as (n / ROW, ROW) images
MAX_ROWS = 32767  # OpenCV's images have fewer rows and columns (and int16 holds them)
# Runs of a table at most: two per mip level, and a plate is less than 2^31 pixels a side
# (the flat pyramid's rows are int32), so fewer than 32 levels.
MAX_RUNS = 64
# The most texels a table's compact form holds whatever the plate: ROW * MAX_ROWS rows of
# the runs, less the padding of every run to whole rows of ROW.
MAX_TEXELS = ROW * MAX_ROWS - MAX_RUNS * (ROW - 1)
BLOCK = 32768  # texels per block of NumPy work (8192 was 15-25 % slower: more Python per tap)
STEP = 8 * BLOCK  # texels per block of `trilinear_samples`' work (its keys and places)


@dataclass(frozen=True, eq=False)
class Trilinear:
    """Trilinear samples grouped by their lower mip level (see the module docstring).

    levels: the lower level of each run; starts: run r is rows starts[r] .. starts[r + 1] - 1;
    singles: whether the run's texels have no share on the next level (read as one sample).
    x, y: (n,) float32 positions on the run's level (bordered pixel coordinates).
    upper: (n,) float16, the next level's share.
    rank: (H, W, 2) int16, each texel's row of the runs as (row % ROW, row // ROW): the
    runs' results seen as an image ROW wide, a nearest-pixel map back to map order; None for
    samples read in the runs' own order (`gather_runs`, extension.py).
    """

    levels: tuple
    starts: tuple
    x: np.ndarray
    y: np.ndarray
    upper: np.ndarray
    rank: np.ndarray
    singles: tuple = ()  # per run: True when its shares are all 0 (one bilinear sample each)

    def keep_rows(self, keep: np.ndarray, counts) -> Trilinear:
        """The runs without their rows where `keep` is False: `keep` holds, run by run, one
        bool per used row (the first counts[r] rows of run r; the rest is padding). The
        runs are padded again to whole rows of ROW; the result has no rank (it is read by
        `gather_runs`, in run order)."""
        xs, ys, ups, levels, singles, starts = [], [], [], [], [], [0]
        offset = 0
        for r, count in enumerate(counts):
            mine = keep[offset : offset + count]
            offset += count
            n = int(mine.sum())
            if not n:
                continue
            rows = slice(self.starts[r], self.starts[r] + count)
            pad = -(-n // ROW) * ROW - n  # padding: pixel (0, 0) of the level, share 0
            xs += [self.x[rows][mine], np.ones(pad, np.float32)]
            ys += [self.y[rows][mine], np.ones(pad, np.float32)]
            ups += [self.upper[rows][mine], np.zeros(pad, np.float16)]
            levels.append(self.levels[r])
            singles.append(self.singles[r])
            starts.append(starts[-1] + n + pad)
        x, y, upper = (np.concatenate(v) for v in (xs, ys, ups))
        for array in (x, y, upper):
            array.flags.writeable = False
        return Trilinear(tuple(levels), tuple(starts), x, y, upper, None, tuple(singles))


def trilinear_samples(px, py, lod, top: int, shape) -> Trilinear:
    """The compact samples of texels at level-0 plate positions (px, py) (T,) float32 with
    mip level `lod` (T,) float32 in [0, top]: bilinear on floor(lod) (at most top - 1) and the
    next level, blended by the fraction; `shape`: the map's (H, W) (a subset of texels: (n, 1))."""
    total = lod.size
    keys = 2 * top + 2
    # Runs by level, and within a level first the texels that read the next level, then those
    # that do not (share 0: magnified, lod clipped to 0): their runs are one bilinear sample.
    # Worked in blocks of the map over the cores: each block's keys and counts, then each
    # texel's row in the runs (in map order within a run: reads stay local).
    key, share, counts_per = _classify(lod, top, keys)
    counts = counts_per.sum(0)
    # Each run padded to whole rows of ROW texels; per key its first row in the runs, and
    # per block where its texels of each key start.
    padded = -(-counts // ROW) * ROW
    first = np.concatenate(([0], np.cumsum(padded)[:-1]))
    starts_per = first + np.cumsum(counts_per, axis=0) - counts_per  # (blocks, keys)
    x = np.empty(int(padded.sum()), np.float32)
    y = np.empty(x.size, np.float32)
    upper = np.zeros(x.size, np.float16)
    for k in np.flatnonzero(padded - counts):  # padding: pixel (0, 0) of the level, share 0
        x[first[k] + counts[k] : first[k] + padded[k]] = 1.0
        y[first[k] + counts[k] : first[k] + padded[k]] = 1.0
    rank = _place(px, py, key, share, counts_per, starts_per, (x, y, upper))
    used = np.flatnonzero(counts)
    levels = [int(run) // 2 for run in used]
    singles = [bool(run % 2) for run in used]
    starts = [0, *(int(v) for v in (first + padded)[used])]
    if starts[-1] > ROW * MAX_ROWS:
        raise ValueError(f"{total} texels: more than this table's compact form holds")
    rank = rank.reshape(tuple(shape) + (2,))
    for array in (x, y, upper, rank):
        array.flags.writeable = False
    return Trilinear(tuple(levels), tuple(starts), x, y, upper, rank, tuple(singles))


def _classify(lod, top: int, keys: int):
    """Each texel's run key (2 x its lower level, + 1 when it reads that level alone) (T,)
    uint8, its share of the next level (T,) float16, and per block of STEP texels the count
    of each key (blocks, keys) int64."""
    total = lod.size
    key = np.empty(total, np.uint8)
    share = np.empty(total, np.float16)
    counts_per = np.zeros((-(-total // STEP), keys), np.int64)

    def classify(i):
        a, b = i * STEP, min((i + 1) * STEP, total)
        lo = np.minimum(lod[a:b].astype(np.int32), max(top - 1, 0))
        frac = lod[a:b] - lo.astype(np.float32)
        np.maximum(frac, 0.0, out=frac)  # (np.clip's own loop is ~5x slower)
        np.minimum(frac, 1.0, out=frac)
        share[a:b] = frac
        # A share that float16 rounds to 0 (at most 2^-25) is 0: compared in float32, whose
        # loops are compiled (float16's are emulated, several times slower).
        lo *= 2
        lo += frac <= np.float32(2.0**-25)
        key[a:b] = lo
        counts_per[i] = _counts(key[a:b], keys)

    _each(classify, counts_per.shape[0])
    return key, share, counts_per


def _place(px, py, key, share, counts_per, starts_per, runs) -> np.ndarray:
    """Write each texel's sample into `runs` (x, y, upper) at its row of its key's run (from
    `starts_per`, (blocks, keys)); returns each texel's row as (rank, row // ROW) (T, 2) int16."""
    x, y, upper = runs
    total = key.size
    blocks, keys = counts_per.shape
    scales = (2.0 ** -(np.arange(keys) // 2)).astype(np.float32)
    rank = np.empty((total, 2), np.int16)

    def place(i):
        a, b = i * STEP, min((i + 1) * STEP, total)
        k = key[a:b]
        present = np.flatnonzero(counts_per[i])
        row = np.empty(b - a, np.int32)  # each texel's row of the runs, in map order
        # A block holds a few keys (levels change slowly over a map): each key's texels,
        # in map order, are consecutive in the runs from the block's start for the key.
        for kk in present:
            n = int(counts_per[i][kk])
            start = int(starts_per[i][kk])
            out = slice(start, start + n)
            if len(present) == 1:  # the whole block: slices, not indices
                ids, local = slice(a, b), slice(None)
            else:
                local = np.flatnonzero(k == kk)
                ids = local + a
            np.multiply(px[ids], scales[kk], out=x[out])
            x[out] += np.float32(0.5)  # +1 border, -0.5 to centres
            np.multiply(py[ids], scales[kk], out=y[out])
            y[out] += np.float32(0.5)
            upper[out] = share[ids]
            row[local] = np.arange(start, start + n, dtype=np.int32)
        np.bitwise_and(row, ROW - 1, out=rank[a:b, 0], casting="unsafe")  # row % ROW
        np.right_shift(row, ROW.bit_length() - 1, out=rank[a:b, 1], casting="unsafe")

    _each(place, blocks)
    return rank


def _counts(key: np.ndarray, keys: int) -> np.ndarray:
    """np.bincount(key, minlength=keys) for a non-empty key array that changes value
    rarely (a map's levels change slowly along its rows), counted by runs of equal keys: a
    tenth of bincount's time (~0.35 against 3.5 ns a texel, measured)."""
    starts = np.flatnonzero(key[1:] != key[:-1])
    starts += 1
    lengths = np.diff(starts, prepend=0, append=key.size)
    first = np.concatenate(([key[0]], key[starts]))
    return np.bincount(first, weights=lengths, minlength=keys).astype(np.int64)


def _each(fn, count):
    """fn(i) for i in range(count), over the cores."""

    def run(a, b):
        for i in range(a, b):
            fn(i)

    for_blocks(run, count, min_rows=1, max_rows=1)


def gather(samples: Trilinear, source, shapes, offsets, out, use=None, plate=None) -> None:
    """out (T, 3) float32 = the samples read from the flat bordered pyramid `source` (levels
    of `shapes` at row `offsets`), with `use` ("numpy", "opencv", "numba"; default
    `backend()`). `plate`: level 0 itself ((H, W, 3) float32, no border), for OpenCV and
    Numba when `source` does not hold level 0 (read past the edge as the border: the edge)."""
    use = use or backend()
    if use == "numba":
        args = compiled_args(samples, source, shapes, offsets, plate)
        image = out.reshape(samples.rank.shape[:2] + (3,))
        starts = np.asarray(samples.starts)
        run(kernels().trilinear_map, *args[:4], samples.rank, starts, *args[4:], image)
        return
    values = gather_runs(samples, source, shapes, offsets, use, plate)
    height, width = samples.rank.shape[:2]
    if use == "opencv" and max(height, width) < MAX_ROWS:  # a nearest-pixel remap
        cv = cv2()
        image = values.reshape(-1, ROW, 3)
        cv.remap(image, samples.rank, None, cv.INTER_NEAREST, dst=out.reshape(height, width, 3))
        return
    rank = samples.rank.reshape(-1, 2)

    def back(a, b):  # the runs' rows -> map order
        rows = rank[a:b, 1].astype(np.int32)
        rows *= ROW
        rows += rank[a:b, 0]
        np.take(values, rows, axis=0, out=out[a:b])

    for_blocks(back, rank.shape[0], max_rows=BLOCK)


def gather_runs(samples: Trilinear, source, shapes, offsets, use=None, plate=None, counts=None):
    """The samples read as `gather` reads them, left in the runs' order: (rows, 3) float32,
    run r's values at rows starts[r] .. (padding rows hold pixel (0, 0) of their level).
    `counts`: per run, how many of its first rows are wanted; NumPy then reads only those
    (the rest of the run's rows are left undefined)."""
    use = use or backend()
    if plate is not None and use != "opencv":
        raise ValueError("the plate as level 0 is for the OpenCV back end")
    top = len(shapes) - 1
    values = np.empty((samples.starts[-1], 3), np.float32)
    for r, level in enumerate(samples.levels):
        a, b = samples.starts[r], samples.starts[r + 1]
        nxt = level if samples.singles[r] else min(level + 1, top)
        if use == "opencv":
            low, high = (
                (plate, 1)
                if v == 0 and plate is not None
                else (_level(source, shapes, offsets, v), 0)
                for v in (level, nxt)
            )  # (image, shift): the plate has no border, its pixel i is the level's i + 1
            _run_opencv(samples, a, b, low, high, nxt > level, values, samples.singles[r])
        else:
            stride = (shapes[level][1] + 2, shapes[nxt][1] + 2)
            start = (int(offsets[level]), int(offsets[nxt]))
            stop = b if counts is None else a + counts[r]
            _run_numpy(
                samples, a, stop, stride, start, nxt > level, source, values, samples.singles[r]
            )
    return values


def compiled_args(samples: Trilinear, source, shapes, offsets, plate=None) -> tuple:
    """What the compiled kernels (kernels.py) read of `samples`: (x, y, the shares' float16
    bits, their float32 values by bits, the runs' geometry (runs, 3, 5) int64, the flat
    pyramid, the plate's rows (or none))."""
    top = len(shapes) - 1
    geometry = np.zeros((len(samples.levels), 3, 5), np.int64)
    for r, level in enumerate(samples.levels):
        nxt = level if samples.singles[r] else min(level + 1, top)
        for j, v in enumerate((level, nxt)):
            h, w = shapes[v]
            if v == 0 and plate is not None:
                geometry[r, j] = (0, w, w - 1, h - 1, 1)
            else:
                geometry[r, j] = (int(offsets[v]), w + 2, w + 1, h + 1, 0)
        geometry[r, 2, :2] = (samples.singles[r], nxt > level)
    rows = None if plate is None else plate_rows(plate)
    upper = samples.upper.view(np.uint16)
    return samples.x, samples.y, upper, _shares(), geometry, given(source, 3), given(rows, 3)


def plate_rows(plate) -> np.ndarray:
    """The plate as (H * W, 3) C-contiguous float32 rows (a view when it is already)."""
    return np.ascontiguousarray(plate, np.float32).reshape(-1, 3)


@functools.cache
def _shares() -> np.ndarray:
    """(65536,) float32: every float16 share by its bits (the compiled kernels' lookup)."""
    with np.errstate(invalid="ignore", over="ignore"):
        bits = np.arange(65536, dtype=np.uint32).astype(np.uint16)
        shares = bits.view(np.float16).astype(np.float32)
    shares.flags.writeable = False
    return shares


def _level(source, shapes, offsets, level):
    h, w = shapes[level]
    return source[int(offsets[level]) : int(offsets[level + 1])].reshape(h + 2, w + 2, 3)


def _run_numpy(samples, a, b, stride, start, halve, source, values, single=False) -> None:
    """Rows a .. b - 1 of one run, in blocks over the cores: 8 taps each, one take, a sum."""

    def block(c, d):  # taps plane by plane (8, n): every step works on whole (n,) rows
        n = d - c
        taps = 4 if single else 8  # a single run: level L alone, its share 1
        index = np.empty((taps, n), np.int32)
        weight = np.empty((taps, n), np.float32)
        x, y = samples.x[c:d], samples.y[c:d]
        up = samples.upper[c:d].astype(np.float32)
        shares = ((0, np.float32(1.0)),) if single else ((0, 1.0 - up), (1, up))
        for j, share in shares:
            if j and halve:
                x = x * np.float32(0.5) + np.float32(0.25)
                y = y * np.float32(0.5) + np.float32(0.25)
            x0, y0 = np.floor(x), np.floor(y)
            ax, ay = x - x0, y - y0
            base = y0.astype(np.int32)
            base *= stride[j]
            base += x0.astype(np.int32)
            base += start[j]
            # Taps (0, 0), (1, 0), (0, 1), (1, 1): rows base + [0, 1, stride, stride + 1].
            k = 4 * j
            index[k] = base
            np.add(base, 1, out=index[k + 1])
            np.add(base, stride[j], out=index[k + 2])
            np.add(base, stride[j] + 1, out=index[k + 3])
            bx, by = share - share * ax, 1 - ay  # the level's share folded into x
            ax *= share
            np.multiply(bx, by, out=weight[k])
            np.multiply(ax, by, out=weight[k + 1])
            np.multiply(bx, ay, out=weight[k + 2])
            np.multiply(ax, ay, out=weight[k + 3])
        taps = np.take(source, index, axis=0, mode="clip")
        weighted_sum(taps, weight, values[c:d], rows_first=False)

    span = b - a  # a run of a few blocks' size still goes over the cores
    for_blocks(lambda c, d: block(a + c, a + d), span, min_rows=BLOCK // 4, max_rows=BLOCK)


def _run_opencv(samples, a, b, low, high, halve, values, single=False) -> None:
    """Rows a .. b - 1 of one run: two remaps (levels L, L + 1: (image, shift) each) and
    their blend (a single run: one remap). The remaps' coordinates and the blend's weights
    are worked out first, in blocks of rows over the engine's threads (on one thread they
    took ~12 ms of a 2048-wide frame of the paper's method, measured)."""
    cv = cv2()
    x = samples.x[a:b].reshape(-1, ROW)
    y = samples.y[a:b].reshape(-1, ROW)
    (low, low_shift), (high, high_shift) = low, high
    lx, ly = (np.empty_like(x), np.empty_like(y)) if low_shift else (x, y)
    if not single:  # the next level's coordinates, the blend's weights
        hx, hy, w0, w1 = (np.empty_like(x) for _ in range(4))
        upper = samples.upper[a:b].reshape(x.shape).view(np.uint16)

    def prepare(r0, r1):
        rows = slice(r0, r1)
        if low_shift:
            np.subtract(x[rows], np.float32(low_shift), out=lx[rows])
            np.subtract(y[rows], np.float32(low_shift), out=ly[rows])
        if single:
            return
        for src, dst in ((x, hx), (y, hy)):
            if halve:
                np.multiply(src[rows], np.float32(0.5), out=dst[rows])
                dst[rows] += np.float32(0.25)
            else:
                dst[rows] = src[rows]
            if high_shift:
                dst[rows] -= np.float32(high_shift)
        np.take(_scaled_shares(), upper[rows], out=w1[rows])
        np.subtract(np.float32(2.0**17), w1[rows], out=w0[rows])

    for_blocks(prepare, x.shape[0], min_rows=64, max_rows=64)

    def remap(image, x, y, dst=None):
        return cv.remap(image, x, y, cv.INTER_LINEAR, dst=dst, borderMode=cv.BORDER_REPLICATE)

    if single:
        remap(low, lx, ly, dst=values[a:b].reshape(x.shape + (3,)))
        return
    first, second = remap(low, lx, ly), remap(high, hx, hy)
    # The blend low + up (high - low) as OpenCV's blendLinear, which divides by the weights'
    # sum + 1e-5: weights scaled by 2^17 make that division exact in float32.
    cv.blendLinear(first, second, w0, w1, dst=values[a:b].reshape(first.shape))


@functools.cache
def _scaled_shares() -> np.ndarray:
    """(65536,) float32: every float16 share (by its bits) times 2^17, the blend's weight:
    one lookup per texel where NumPy's float16 conversion costs about twice as much."""
    with np.errstate(invalid="ignore", over="ignore"):  # the NaN and infinite bit patterns
        scaled = _shares() * np.float32(2.0**17)
    scaled.flags.writeable = False  # shared by every call
    return scaled
