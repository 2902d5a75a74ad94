"""The lookup table from map texels to filtered plate samples, built once and cached.

A table depends only on geometry: plate size, object bounds, parameters, layout and map
size. It stores, for every texel, the indices of 8 pyramid pixels (bilinear on two mip
levels) and their weights, so applying it to a plate — a new frame with unchanged bounds —
is one pyramid build and one gather.

Anti-aliasing: the texel's footprint on the plate (how far the plate position moves over
one texel, from the positions half a texel to either side) picks a mip level, so where a
large plate region is squeezed onto few texels (the ring F on the front face, the front
face's centre in the continuous limit) each texel averages the area it covers.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .layouts import map_shape, texel_directions
from .mipmap import level_offsets, level_shapes
from .params import Params
from .projection import plate_positions
from .segmentation import Segmentation, segment


@dataclass(frozen=True, eq=False)
class LookupTable:
    """Texel -> weighted pyramid pixels for one plate size, segmentation and map layout.

    index:  (T, 8) intp rows of the flat pyramid (see mipmap.py), T = map height * width.
    weight: (T, 8) float32, rows sum to 1.
    shape:  (H, W) of the map; `levels` pyramid levels are needed.
    """

    segmentation: Segmentation
    layout: str
    size: int
    shape: tuple[int, int]
    levels: int
    index: np.ndarray
    weight: np.ndarray
    position: np.ndarray  # (H, W, 2) plate position of each texel centre, for inspection
    lod: np.ndarray  # (H, W) float32 mip level of each texel


def _spans(q: np.ndarray, axis: int, wrap: bool, block: int) -> np.ndarray:
    """Distance on the plate to the nearer neighbour texel along `axis`, per texel.

    q: (H, W, 2) positions. Taking the nearer of the two neighbours keeps a texel next to a
    discontinuity (the seams between the paper's front-face triangles) from being blurred
    across it. `block` > 0 cuts the axis into blocks (cube faces) with no neighbours across.
    """
    n = q.shape[axis]
    step = np.hypot(*np.moveaxis(np.diff(q, axis=axis), -1, 0))  # (n-1) along axis
    if wrap:
        first = np.take(q, [0], axis=axis) - np.take(q, [n - 1], axis=axis)
        seam = np.hypot(*np.moveaxis(first, -1, 0))
        ahead = np.concatenate((step, seam), axis=axis)
        behind = np.concatenate((seam, step), axis=axis)
    else:
        pad = np.full_like(np.take(step, [0], axis=axis), np.inf)
        ahead = np.concatenate((step, pad), axis=axis)
        behind = np.concatenate((pad, step), axis=axis)
        if block:
            cut = np.arange(n)
            ahead = np.where(_along(cut % block == block - 1, axis, q.ndim - 1), np.inf, ahead)
            behind = np.where(_along(cut % block == 0, axis, q.ndim - 1), np.inf, behind)
    span = np.minimum(ahead, behind)
    return np.where(np.isfinite(span), span, 0.0)


def _along(mask: np.ndarray, axis: int, ndim: int) -> np.ndarray:
    shape = [1] * ndim
    shape[axis] = mask.size
    return mask.reshape(shape)


def _footprint(layout: str, size: int, position: np.ndarray) -> np.ndarray:
    """Plate pixels covered by one texel: (H, W) float64, from neighbouring texels."""
    latlong = layout == "latlong"
    across = _spans(position, 1, wrap=latlong, block=0)
    down = _spans(position, 0, wrap=False, block=0 if latlong else size)
    return np.maximum(across, down)


def _bilinear(px, py, lo, shapes, offsets):
    """Bilinear taps at level-0 positions (px, py) on mip levels lo and lo + 1.

    Returns index (T, 2, 4) intp and weight (T, 2, 4) float32 (unblended)."""
    level = np.minimum(lo[:, None] + np.arange(2), len(shapes) - 1)  # (T, 2)
    h = np.array([s[0] for s in shapes], dtype=np.intp)[level]
    w = np.array([s[1] for s in shapes], dtype=np.intp)[level]
    scale = np.exp2(-level.astype(np.float32))
    fx, fy = px[:, None] * scale - 0.5, py[:, None] * scale - 0.5
    x0, y0 = np.floor(fx), np.floor(fy)
    ax, ay = fx - x0, fy - y0
    x0, y0 = x0.astype(np.intp), y0.astype(np.intp)
    xa, xb = np.clip(x0, 0, w - 1), np.clip(x0 + 1, 0, w - 1)
    row_a = offsets[level] + np.clip(y0, 0, h - 1) * w
    row_b = offsets[level] + np.clip(y0 + 1, 0, h - 1) * w
    index = np.stack((row_a + xa, row_a + xb, row_b + xa, row_b + xb), -1)
    bx, by = 1 - ax, 1 - ay
    weight = np.stack((bx * by, ax * by, bx * ay, ax * ay), -1)
    return index, weight


def build_table(seg: Segmentation, layout: str, size: int, triangles: int = 0) -> LookupTable:
    """Build the table for a segmentation (uncached; see `lookup_table`)."""
    shape = map_shape(layout, size)
    position = plate_positions(texel_directions(layout, size), seg, triangles)
    footprint = _footprint(layout, size, position)
    shapes = level_shapes(seg.height, seg.width)
    offsets = level_offsets(shapes)
    top = len(shapes) - 1
    lod = np.clip(np.log2(np.maximum(footprint, 1e-12)), 0.0, top).astype(np.float32).ravel()
    lo = np.minimum(lod.astype(np.intp), max(top - 1, 0))
    blend = lod - lo
    px = position[..., 0].astype(np.float32).ravel()
    py = position[..., 1].astype(np.float32).ravel()
    index, weight = _bilinear(px, py, lo, shapes, offsets)
    weight[:, 0] *= (1 - blend)[:, None]
    weight[:, 1] *= blend[:, None]
    index, weight = index.reshape(-1, 8), weight.reshape(-1, 8)
    for a in (index, weight, position, lod):
        a.flags.writeable = False
    return LookupTable(
        segmentation=seg,
        layout=layout,
        size=size,
        shape=shape,
        levels=min(int(lo.max()) + 2, top + 1),
        index=index,
        weight=weight,
        position=position,
        lod=lod.reshape(shape),
    )


@functools.lru_cache(maxsize=16)
def lookup_table(
    width: int, height: int, bbox: tuple, params: Params, layout: str = "latlong", size: int = 1024
) -> LookupTable:
    """The cached table for a W x H plate, object `bbox` (x0, y0, x1, y1), params and layout."""
    seg = segment(width, height, bbox, params)
    return build_table(seg, layout, size, params.triangles)
