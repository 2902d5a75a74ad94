"""The camera view's seen texels (camera_view.py): where the plate sees a texel's centre, the
texel is the mean of n x n bilinear samples of the plate at the projections of n x n directions
spread evenly over it (n = SUPERSAMPLE), on level 0 of the mip pyramid while the samples are less
than 4 pixels apart, else on the level where they are 2-4 pixels apart: a box filter over the
texel's footprint, as a renderer supersamples a pixel. (One trilinear tap at the footprint's mip
level blurs far more: 34 dB against 58 dB where the plate sees, on the accuracy study's ground
truth; docs/accuracy.md.) supersample.py keeps these samples compactly and reads them per frame.
"""

from __future__ import annotations

import numpy as np

from .layouts import directions_at
from .parallel import CHUNK, chunks, for_blocks


def seen_footprints(layout, size, directions, width, height, intrinsics, ids=None):
    """The texels whose centre the plate sees, and their footprints on the plate.

    directions: (T, 3) texel-centre directions; or, with `ids` (the texels known to be seen,
    flat indices), theirs only (len(ids), 3). Returns (ids (S,) int64 flat texel indices,
    rect (4, S) float64 x0, x1, y0, y1 in plate pixels: the rectangle between the projections
    of the texel's corners (each side the mean of its two corners), widened to at least one
    pixel about the centre's projection and clipped to the plate).
    """
    fx, fy, cx, cy = intrinsics

    def project(d):
        d = np.asarray(d, np.float64)
        z = d[:, 2]
        ahead = z > 1e-9
        zs = np.where(ahead, z, 1.0)
        px = cx - fx * d[:, 0] / zs
        py = cy - fy * d[:, 1] / zs
        return px, py, ahead & (px >= 0) & (px <= width) & (py >= 0) & (py <= height)

    if ids is None:
        ids = np.concatenate(
            [a + np.flatnonzero(project(directions[a:b])[2]) for a, b in chunks(len(directions))]
            or [np.zeros(0, np.int64)]
        )
        directions = directions[ids]
    px, py, _ = project(directions)
    corners = {}
    ok = np.ones(ids.size, bool)
    for dx in (-0.5, 0.5):
        for dy in (-0.5, 0.5):
            c = directions_at(layout, size, ids, dx, dy)
            ok &= c[:, 2] > 1e-9
            cz = np.where(c[:, 2] > 1e-9, c[:, 2], 1.0)
            corners[dx, dy] = (cx - fx * c[:, 0] / cz, cy - fy * c[:, 1] / cz)
    ids = ids[ok]
    px, py = px[ok], py[ok]

    def side(a, b, axis):
        return 0.5 * (corners[a][axis][ok] + corners[b][axis][ok])

    xa, xb = side((-0.5, -0.5), (-0.5, 0.5), 0), side((0.5, -0.5), (0.5, 0.5), 0)
    ya, yb = side((-0.5, -0.5), (0.5, -0.5), 1), side((-0.5, 0.5), (0.5, 0.5), 1)
    x0, x1 = np.minimum(xa, xb), np.maximum(xa, xb)
    y0, y1 = np.minimum(ya, yb), np.maximum(ya, yb)
    # Never empty (the filter then tends to bilinear interpolation at the centre).
    x0, x1 = np.minimum(x0, px - 1e-3), np.maximum(x1, px + 1e-3)
    y0, y1 = np.minimum(y0, py - 1e-3), np.maximum(y1, py + 1e-3)
    rect = np.stack(
        (
            np.clip(x0, 0, width),
            np.clip(x1, 0, width),
            np.clip(y0, 0, height),
            np.clip(y1, 0, height),
        )
    )
    return ids, rect


SUPERSAMPLE = 4  # seen texels: n x n bilinear samples over the footprint


def supersample_levels(rect, shapes, n: int = SUPERSAMPLE) -> np.ndarray:
    """(S,) int32: the mip level each seen texel is sampled on. Level 0 while the samples are
    less than 4 pixels apart (a rectangle `rect` (4, S) at most 4 n pixels wide); beyond, the
    level on which they are 2 to 4 pixels apart (so the bilinear samples never skip pixels)."""
    x0, x1, y0, y1 = rect
    spacing = np.maximum(np.maximum(x1 - x0, y1 - y0), 1e-9) / n
    level = np.floor(np.log2(np.maximum(spacing, 1.0))) - 1
    return np.clip(level, 0, len(shapes) - 1).astype(np.int32)


def supersample_taps(
    layout, size, ids, intrinsics, level, shapes, offsets, n: int = SUPERSAMPLE, project=None
):
    """Taps (S, 4 n^2) int32 and weights (S, 4 n^2) float32 for the texels `ids`: the mean of
    n x n bilinear samples of the plate at the projections of n x n directions spread evenly
    over each texel (its footprint, sampled as a renderer supersamples a pixel), read on mip
    `level` (S,) (`supersample_levels`) of the flat bordered pyramid with level `offsets`.
    `project` maps (k, 3) directions to plate positions (px, py) (default: where the camera
    sees the direction, the distant model; ground.py passes where it sees the ground point)."""
    positions = supersample_positions(layout, size, ids, intrinsics, n, project)
    return mean_taps(positions, level, shapes, offsets)


def supersample_positions(layout, size, ids, intrinsics, n: int = SUPERSAMPLE, project=None):
    """The n x n sample positions of `supersample_taps`: n^2 pairs of (S,) plate
    coordinates (px, py) at level 0's scale."""
    fx, fy, cx, cy = intrinsics
    count = len(ids)
    positions = [(np.empty(count), np.empty(count)) for _ in range(n * n)]

    def block(a, b):  # texels a .. b - 1, over the cores
        for sy in range(n):
            for sx in range(n):
                d = directions_at(
                    layout, size, ids[a:b], (sx + 0.5) / n - 0.5, (sy + 0.5) / n - 0.5
                )
                px, py = positions[sy * n + sx]
                if project is None:
                    z = np.where(d[:, 2] > 1e-9, d[:, 2], 1e-9)
                    px[a:b] = np.clip(cx - fx * d[:, 0] / z, 0, None)
                    py[a:b] = np.clip(cy - fy * d[:, 1] / z, 0, None)
                else:
                    px[a:b], py[a:b] = project(d)

    for_blocks(block, count, min_rows=4096, max_rows=CHUNK)
    return positions


def mean_taps(positions, level, shapes, offsets):
    """Taps (S, 4 k) int32 and weights (S, 4 k) float32: the mean of k bilinear samples at
    ``positions`` (k pairs of (S,) continuous plate coordinates px, py, at level 0's scale),
    read on mip ``level`` (S,) of the flat bordered pyramid with level ``offsets``."""
    level = np.asarray(level, np.int64)
    count = level.size
    index = np.empty((count, len(positions), 4), np.int32)
    weight = np.empty((count, len(positions), 4), np.float32)
    share = np.float32(1.0 / len(positions))
    widths_all = np.array([s[1] for s in shapes], np.int32)
    heights_all = np.array([s[0] for s in shapes], np.int32)
    for a, b in chunks(count, 4096):  # the texels' taps written while in the cache
        lv = level[a:b]
        scale = 2.0 ** -lv.astype(np.float64)
        widths, heights = widths_all[lv], heights_all[lv]
        stride = widths + 2  # a bordered level's row length
        base = np.asarray(offsets, np.int64)[lv].astype(np.int32)
        for k, (px, py) in enumerate(positions):
            u, v = px[a:b] * scale - 0.5, py[a:b] * scale - 0.5
            i0, j0 = np.floor(u), np.floor(v)
            au, av = (u - i0).astype(np.float32), (v - j0).astype(np.float32)
            i0, j0 = i0.astype(np.int32), j0.astype(np.int32)
            c0 = np.minimum(np.maximum(i0, -1), widths) + 1
            c1 = np.minimum(np.maximum(i0 + 1, -1), widths) + 1
            r0 = base + (np.minimum(np.maximum(j0, -1), heights) + 1) * stride
            r1 = base + (np.minimum(np.maximum(j0 + 1, -1), heights) + 1) * stride
            tap, w = index[a:b, k], weight[a:b, k]
            tap[:, 0], tap[:, 1] = r0 + c0, r0 + c1
            tap[:, 2], tap[:, 3] = r1 + c0, r1 + c1
            bu, bv = 1.0 - au, 1.0 - av
            w[:, 0], w[:, 1] = bv * bu * share, bv * au * share
            w[:, 2], w[:, 3] = av * bu * share, av * au * share
    return index.reshape(count, -1), weight.reshape(count, -1)
