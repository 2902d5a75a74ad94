"""A box-filtered mip pyramid of a plate, stored as one flat array for single-gather lookups.

Level 0 is the plate; level l+1 averages 2 x 2 pixels of level l (an odd last row/column is
repeated). Level l's pixel (i, j) covers [j 2^l, (j+1) 2^l] x [i 2^l, (i+1) 2^l] in level-0
plate coordinates. Every level is stored with a one-pixel border that repeats its edge
pixels, so bilinear taps never need clamping: level l's pixel (i, j) is row
`offsets[l] + (i + 1) * (w + 2) + (j + 1)` of one (P, 3) float32 array, and a lookup table
can address any pixel of any level with a single index.

A pyramid from level `first` > 0 takes that level straight from the plate when its sides are
multiples of 2^first, so the finer levels are not written and read again (1080p to level 2
with OpenCV: 1.9 against 3.4 ms, measured).
"""

from __future__ import annotations

import numpy as np

from .backends import cv2, kernels, pyramid_backend, run
from .parallel import for_blocks


def level_shapes(height: int, width: int, levels: int | None = None) -> list[tuple[int, int]]:
    """The shape of every level of a plate's pyramid (without the border).

    Parameters
    ----------
    height, width : int
        The plate's size in pixels.
    levels : int, optional
        How many levels; default down to 1 x 1.

    Returns
    -------
    list of (h, w)
        Level 0 (the plate) first.
    """
    shapes = [(height, width)]
    while (shapes[-1] != (1, 1)) and (levels is None or len(shapes) < levels):
        h, w = shapes[-1]
        shapes.append(((h + 1) // 2, (w + 1) // 2))
    return shapes


def level_offsets(shapes, first: int = 0) -> np.ndarray:
    """Row offset of each (bordered) level in the flat array; the last entry is the total.

    Levels below `first` are not stored (no table needs them): their offsets are 0.
    """
    sizes = [(h + 2) * (w + 2) if i >= first else 0 for i, (h, w) in enumerate(shapes)]
    return np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)


def _halve(src: np.ndarray, dst: np.ndarray) -> None:
    """Average 2 x 2 blocks of src (h, w, 3) into dst ((h+1)//2, (w+1)//2, 3).

    Rows are summed with one contiguous add and scaled by 1/4 (exact); horizontal pairs are
    added channel by channel: three 2-D adds whose inner loops run along the row (an add of
    whole 3-float pixels loops 3 long; a (6, 3) matrix product, used before, took 1.8 times
    as long). The work goes in blocks of about 1 MB of summed rows over the cores: the
    temporaries stay small and cached instead of being fresh memory as large as the level.
    """
    h, w, _ = src.shape
    half = dst.shape[0]
    use = pyramid_backend()
    if use == "numba":  # the same arithmetic, compiled: one pass
        run(kernels().halve, src, dst)
        return
    if use == "opencv" and h > 1 and w > 1:
        _halve_opencv(src, dst)
        return

    def block(a, b):
        stop = min(b, h // 2)
        if stop > a:
            rows = src[2 * a : 2 * stop : 2] + src[2 * a + 1 : 2 * stop : 2]
            rows *= np.float32(0.25)
            _pairs(rows, dst[a:stop])
        if b == half and h % 2:  # an odd last row: repeated
            _pairs(src[-1:] * np.float32(0.5), dst[-1:])

    rows = min(max((1 << 20) // (12 * w), 16), 64)
    for_blocks(block, half, min_rows=rows, max_rows=rows)


def _halve_opencv(src: np.ndarray, dst: np.ndarray) -> None:
    """`_halve` with OpenCV's area resize for the even part (the same 2 x 2 means, to
    rounding); an odd last row or column as `_halve`."""
    h, w, _ = src.shape
    he, we = h - h % 2, w - w % 2
    cv = cv2()
    cv.resize(src[:he, :we], (we // 2, he // 2), dst=dst[: he // 2, : we // 2],
              interpolation=cv.INTER_AREA)  # fmt: skip
    if w % 2:  # the last column: pairs of rows, its own value repeated across
        dst[: he // 2, -1] = 0.5 * (src[0:he:2, -1] + src[1:he:2, -1])
    if h % 2:
        _pairs(src[-1:] * np.float32(0.5), dst[-1:])


def _pairs(rows: np.ndarray, dst: np.ndarray) -> None:
    """dst (n, (w+1)//2, 3) = the sums of horizontal pairs of rows (n, w, 3) (row pairs
    already summed and scaled); an odd last column is repeated (its value twice)."""
    w = rows.shape[1]
    we = w - w % 2
    for c in range(3):
        np.add(rows[:, 0:we:2, c], rows[:, 1:we:2, c], out=dst[:, : we // 2, c])
    if w % 2:
        dst[:, -1] = 2.0 * rows[:, -1]


def _fill_border(level: np.ndarray) -> None:
    """Repeat the edge pixels of a bordered level (h + 2, w + 2, 3) into its border."""
    level[0], level[-1] = level[1], level[-2]
    level[:, 0], level[:, -1] = level[:, 1], level[:, -2]


def pyramid_size(height: int, width: int, levels: int | None = None, first: int = 0) -> int:
    """Rows of the flat pyramid of a plate.

    Parameters
    ----------
    height, width : int
        The plate's size in pixels.
    levels : int, optional
        Levels `first` .. `levels` - 1 are held; default down to 1 x 1.
    first : int, optional

    Returns
    -------
    int
    """
    return int(level_offsets(level_shapes(height, width, levels), first)[-1])


def build_pyramid(plate: np.ndarray, levels: int | None = None, first: int = 0, out=None):
    """The flat bordered pyramid of a plate.

    Finer levels than `first` are only computed on the way; when the plate's sides are multiples
    of 2^first, level `first` comes straight from the plate (the means of 2^first x 2^first
    blocks, the same to rounding), see the module docstring.

    Parameters
    ----------
    plate : (H, W, 3) float32 ndarray
        Scene-linear.
    levels : int, optional
        Levels `first` .. `levels` - 1 are held; default down to 1 x 1.
    first : int, optional
    out : (pyramid_size(H, W, levels, first), 3) float32 ndarray, optional
        Written into when given.

    Returns
    -------
    (P, 3) float32 ndarray
        `out` when given.
    """
    plate = np.asarray(plate, dtype=np.float32)
    h, w = plate.shape[:2]
    shapes = level_shapes(h, w, levels)
    offsets = level_offsets(shapes, first)
    flat = np.empty((int(offsets[-1]), 3), dtype=np.float32) if out is None else out
    direct = 2 <= first < len(shapes) and h % (1 << first) == 0 and w % (1 << first) == 0
    skip = first if direct else 0
    if len(shapes) > 1 and (direct or first <= 1) and pyramid_backend() == "numba":
        _compiled(plate, shapes, offsets, max(skip, 1), flat)
        return flat
    previous = plate
    for i, (lh, lw) in enumerate(shapes):
        if 0 < i < skip:
            continue
        stored = None
        if i >= first:
            stored = flat[offsets[i] : offsets[i + 1]].reshape(lh + 2, lw + 2, 3)
        if i == 0:
            if stored is not None:
                _copy_plate(plate, stored)
        else:
            inner = stored[1:-1, 1:-1] if stored is not None else np.empty((lh, lw, 3), np.float32)
            if i == skip:
                _blocks(plate, inner, 1 << skip)
            else:
                _halve(previous, inner)
            previous = inner
        if stored is not None:
            _fill_border(stored)
    return flat


def _compiled(plate: np.ndarray, shapes, offsets, start: int, flat: np.ndarray) -> None:
    """`build_pyramid` with Numba's kernel: level 0 copied when it is stored, the levels from
    `start` (the plate's 2^start x 2^start block means) on made in one call, the same bits."""
    h, w = shapes[0]
    if offsets[1] > 0:  # level 0 stored
        level0 = flat[: offsets[1]].reshape(h + 2, w + 2, 3)
        _copy_plate(plate, level0)
        _fill_border(level0)
    levels = np.array([(offsets[i], lh, lw) for i, (lh, lw) in enumerate(shapes) if i >= start])
    run(kernels().pyramid, np.ascontiguousarray(plate), 1 << start, levels.astype(np.int64), flat)


def _copy_plate(plate: np.ndarray, level0: np.ndarray) -> None:
    """The plate into the inside of the bordered level 0, in blocks of rows over the cores."""
    inner = level0[1:-1, 1:-1]
    for_blocks(lambda a, b: np.copyto(inner[a:b], plate[a:b]), plate.shape[0], min_rows=128)


def _blocks(src: np.ndarray, dst: np.ndarray, k: int) -> None:
    """dst (h / k, w / k, 3) = the means of src's (h, w, 3) k x k blocks (h, w multiples of
    k): OpenCV's area resize, or k rows summed and scaled by 1 / k^2 (exact), then k
    columns added channel by channel, in blocks of rows over the cores (as `_halve`)."""
    h, w, _ = src.shape
    if pyramid_backend() == "opencv":
        cv2().resize(src, (w // k, h // k), dst=dst, interpolation=cv2().INTER_AREA)
        return

    def block(a, b):
        rows = src[k * a : k * b : k] + src[k * a + 1 : k * b : k]
        for i in range(2, k):
            rows += src[k * a + i : k * b : k]
        rows *= np.float32(1.0 / (k * k))
        for c in range(3):
            target = dst[a:b, :, c]
            np.add(rows[:, 0::k, c], rows[:, 1::k, c], out=target)
            for j in range(2, k):
                target += rows[:, j::k, c]

    per = min(max((1 << 20) // (12 * w), 4), 64)
    for_blocks(block, h // k, min_rows=per, max_rows=per)


def level_view(flat: np.ndarray, shapes, level: int, first: int = 0) -> np.ndarray:
    """One level of a flat pyramid as an image, without the border.

    Parameters
    ----------
    flat : (P, 3) float32 ndarray
        The pyramid (`build_pyramid`).
    shapes : list of (h, w)
        `level_shapes` of the plate.
    level : int
    first : int, optional
        The pyramid's first level.

    Returns
    -------
    (h, w, 3) float32 ndarray
        A view into `flat`.
    """
    offsets = level_offsets(shapes, first)
    h, w = shapes[level]
    return flat[offsets[level] : offsets[level + 1]].reshape(h + 2, w + 2, 3)[1:-1, 1:-1]
