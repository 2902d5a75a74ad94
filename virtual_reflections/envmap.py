"""Plate in, environment map out: the engine's front door.

    env = environment_map(plate, bbox)                   # (512, 1024, 3) float32 lat-long
    env = environment_map(plate, bbox, layout="cube", size=256)   # (1536, 256, 3)

`plate` is scene-linear Rec.709, (H, W) or (H, W, C); `bbox` = (x0, y0, x1, y1) in plate
pixels (origin top-left, y down, x1/y1 exclusive). Frames and layouts: see layouts.py.
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from .backends import backend, given, kernels, run
from .colour import clean_plate
from .extension import apply as apply_extension
from .fill import FILL_BINS, fill_lookup, fill_profile, fill_values, prior_level
from .mipmap import build_pyramid, level_offsets, level_shapes, level_view, pyramid_size
from .parallel import CHUNK, for_blocks
from .params import Params
from .supersample import gather as gather_supersample
from .table import LookupTable, lookup_table
from .taps import put_rows, weighted_sum
from .trilinear import gather as gather_trilinear

DEFAULT_SIZE = {"latlong": 1024, "cube": 512}

_local = threading.local()


def _scratch(name: str, shape: tuple) -> np.ndarray:
    """A float32 buffer reused by the calling thread across applies and tables, so a new
    frame or a new table does not pay for fresh memory (page faults) every time."""
    pool = _local.__dict__.setdefault("pool", {})
    size = int(np.prod(shape))
    buf = pool.get(name)
    if buf is None or buf.size < size:
        buf = pool[name] = np.empty(size, np.float32)
    return buf[:size].reshape(shape)


def apply_table(table: LookupTable, plate: np.ndarray, pyramids: dict | None = None) -> np.ndarray:
    """Apply a lookup table to a plate: one filtered gather.

    Parameters
    ----------
    table : LookupTable
        Built for this plate's size (`lookup_table`, `build_table`).
    plate : (H, W, 3) float32 ndarray
        Clean scene-linear Rec.709 pixels (`colour.clean_plate`), origin top-left, y down.
    pyramids : dict, optional
        Kept by the caller for this plate while its pixels are unchanged: the plate's mip
        pyramid is built once per set of levels and kept here, so several maps of one plate
        (several objects, a regeneration) share it.

    Returns
    -------
    (h, w, 3) float32 ndarray
        The environment map in `table.layout`, scene-linear Rec.709.

    Raises
    ------
    ValueError
        The plate's size is not the one the table was built for.
    """
    seg = table.segmentation
    if plate.shape[:2] != (seg.height, seg.width):
        raise ValueError(
            f"plate is {plate.shape[1]}x{plate.shape[0]}, table was built for "
            f"{seg.width}x{seg.height}"
        )
    first = table.first_level
    # With OpenCV or Numba, the paper's table reads level 0 from the plate itself (no
    # border: their reads repeat the edge), so the pyramid need not copy it.
    use = backend()
    direct = (
        first == 0
        and table.levels > 1
        and table.trilinear is not None
        and table.index is None
        and table.supersample is None
        and not table.groups
        and table.fill is None
        and use != "numpy"
    )
    if direct:
        first = 1
    rows = pyramid_size(seg.height, seg.width, table.levels, first)
    fill = table.fill
    extra = FILL_BINS * fill.sides if fill is not None else 0
    key = (seg.height, seg.width, table.levels, first)
    source = None if pyramids is None else pyramids.get(key)
    if source is None:
        if pyramids is None:
            source = _scratch("pyramid", (rows + extra, 3))
        else:  # with room for any table's fill rows after it
            source = pyramids[key] = np.empty((rows + 2 * FILL_BINS, 3), np.float32)
        build_pyramid(plate, table.levels, first, out=source[:rows])
    pyramid = source[:rows]
    shapes = level_shapes(seg.height, seg.width, table.levels)
    offsets = level_offsets(shapes, first)
    if fill is not None:
        level = level_view(pyramid, shapes, fill.level, first)
        fill_profile(
            level,
            fill.bins,
            fill.window,
            fill.counts,
            fill.saturation,
            out=source[fill.base :],
            energy=fill.energy,
            sky=fill.sky,
            sky_gain=fill.sky_gain,
            sky_tint=fill.sky_tint,
        )
    out = np.empty((table.shape[0] * table.shape[1], 3), np.float32)
    if table.fill_texels is not None:  # the fill everywhere, the groups written over it
        steps, side = table.fill_texels
        lookup = fill_lookup(source[fill.base : fill.base + extra].reshape(-1, FILL_BINS, 3))
        width = table.shape[1]

        def fill_rows(a, b):
            texels = slice(a * width, b * width)
            mine = steps[a:b] if steps.size == table.shape[0] else steps[texels]
            fill_values(mine, side, lookup, out[texels])

        if use == "numba":  # one compiled pass over the map
            run(kernels().fill_rows, steps, given(side), lookup, width, out)
        elif steps.size == table.shape[0]:  # one step per row: one matrix product
            fill_values(steps, side, lookup, out)
        else:
            # (blocks of 8192 texels took twice as long on a 4096-wide map: the pool's cost)
            for_blocks(fill_rows, table.shape[0], min_rows=8, max_rows=max(1, CHUNK // width))
    if table.trilinear is not None:  # every texel, the groups written over it
        level0 = np.ascontiguousarray(plate, np.float32) if direct else None
        gather_trilinear(table.trilinear, pyramid, shapes, offsets, out, plate=level0)
    if table.index is not None:
        _gather(source, table.texels, table.index, table.weight, out)
    if table.extension is not None:  # over the fill written above
        apply_extension(table.extension, pyramid, shapes, offsets, out)
    if table.supersample is not None:  # level 0 read from the plate itself
        rows = np.ascontiguousarray(plate, np.float32).reshape(-1, 3)
        gather_supersample(table.supersample, source, out, plate=rows)
    for texels, index, weight in table.groups:
        _gather(source, texels, index, weight, out)
    return out.reshape(table.shape + (3,))


def prior_parts(table: LookupTable, plate: np.ndarray, pyramids: dict | None = None):
    """Split a map at its sky prior (fill.py): the map without it and the prior's weight.

    The prior is the fill above the world's horizon, every direction there the plate does not
    show. The map is linear in the prior, so (map with a neutral prior of level 1 - map with it
    black) / that level is each texel's weight (probe.py puts an HDRI in its place).

    Parameters
    ----------
    table : LookupTable
        As for `apply_table`.
    plate : (H, W, 3) float32 ndarray
        Clean scene-linear Rec.709 pixels of the table's plate size.
    pyramids : dict, optional
        As for `apply_table`; both gathers share one pyramid.

    Returns
    -------
    tuple of ((h, w, 3) float32, (h, w) float32) or None
        The map with the prior black, and each texel's weight of the prior in 0..1; None when
        the table has no prior (no world horizon, `Params.up`).
    """
    fill = table.fill
    if fill is None or fill.sky is None or not (fill.sky < 1).any():
        return None
    store = {} if pyramids is None else pyramids  # both gathers share one pyramid
    neutral = (1.0, 1.0, 1.0)  # the weight is the share of a neutral prior of level 1
    without, lit = (
        apply_table(
            dataclasses.replace(
                table, fill=dataclasses.replace(fill, sky_gain=g, sky_tint=neutral)
            ),
            plate,
            store,
        )
        for g in (0.0, 1.0)
    )
    seg, first = table.segmentation, table.first_level
    source = store[(seg.height, seg.width, table.levels, first)]
    pyramid = source[: pyramid_size(seg.height, seg.width, table.levels, first)]
    shapes = level_shapes(seg.height, seg.width, table.levels)
    level = prior_level(level_view(pyramid, shapes, fill.level, first), fill.bins, fill.energy)
    lit -= without
    weight = lit.mean(axis=-1)
    weight *= np.float32(1.0 / max(level, 1e-30))
    return without, np.clip(weight, 0.0, 1.0, out=weight)


def _gather(source, texels, index, weight, out) -> None:
    """out[texels] = the weighted sum of source[index] per row (texels None: every row)."""
    if backend() == "numba":
        every = given(texels, dtype=np.int64)  # empty: every row
        run(kernels().weighted_rows, source, index, weight, every, out)
        return
    buffer = _scratch("taps", index.shape + (3,))

    def gather(a, b):  # one block of texels: its taps, then their weighted sum
        taps = np.take(source, index[a:b], axis=0, mode="clip", out=buffer[a:b])
        if texels is None:
            weighted_sum(taps, weight[a:b], out[a:b])
        else:
            sums = np.empty((b - a, 3), np.float32)
            weighted_sum(taps, weight[a:b], sums)
            put_rows(out, texels[a:b], sums)

    for_blocks(gather, index.shape[0])


def environment_map(
    plate: np.ndarray,
    bbox,
    params: Params = Params(),
    layout: str = "latlong",
    size: int | None = None,
) -> np.ndarray:
    """The paper's environment map of a plate around one object.

    NaN/Inf pixels are replaced (`colour.clean_plate`); the table is cached, so calling again
    with the same plate size, bounds, params and layout costs only the gather.

    Parameters
    ----------
    plate : (H, W) or (H, W, C) ndarray
        Scene-linear Rec.709 pixels, origin top-left, y down.
    bbox : sequence of 4 floats
        The object's bounds (x0, y0, x1, y1) in plate pixels, x1/y1 exclusive.
    params : Params, optional
        The method and its parameters (default: the paper's).
    layout : {"latlong", "cube"}, optional
        The map's layout (docs/conventions.md).
    size : int, optional
        A lat-long's width or a cube's face size; default `DEFAULT_SIZE[layout]`.

    Returns
    -------
    (h, w, 3) float32 ndarray
        A lat-long (size / 2, size) or a cube (6 size, size), scene-linear Rec.709.

    Raises
    ------
    ValueError
        Bad bounds, params, layout or size.
    """
    clean = clean_plate(plate).pixels
    h, w = clean.shape[:2]
    size = DEFAULT_SIZE[layout] if size is None and layout in DEFAULT_SIZE else size
    table = lookup_table(w, h, tuple(float(v) for v in bbox), params, layout, size)
    return apply_table(table, clean)
