"""Plate in, environment map out: the engine's front door.

    env = environment_map(plate, bbox)                   # (512, 1024, 3) float32 lat-long
    env = environment_map(plate, bbox, layout="cube", size=256)   # (1536, 256, 3)

`plate` is scene-linear Rec.709, (H, W) or (H, W, C); `bbox` = (x0, y0, x1, y1) in plate
pixels (origin top-left, y down, x1/y1 exclusive). Frames and layouts: see layouts.py.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .backends import backend
from .colour import clean_plate
from .fill import FILL_BINS, prior_level
from .layers import Frame, SkyTexture, scratch
from .mipmap import build_pyramid, level_offsets, level_shapes, level_view, pyramid_size
from .params import Params
from .table import LookupTable, lookup_table

DEFAULT_SIZE = {"latlong": 1024, "cube": 512}


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
    # With OpenCV or Numba, a table whose layers can read level 0 from the plate itself (no
    # border: their reads repeat the edge) needs no copy of it in the pyramid.
    direct = (
        table.first_level == 0
        and table.levels > 1
        and table.reads_plate_level0()
        and backend() != "numpy"
    )
    first = 1 if direct else table.first_level
    source, pyramid = _pyramid(table, plate, first, pyramids)
    shapes = level_shapes(seg.height, seg.width, table.levels)
    if table.fill is not None:
        table.fill.write_profile(pyramid, shapes, first, source)
    level0 = np.ascontiguousarray(plate, np.float32) if direct else None
    offsets = level_offsets(shapes, first)
    frame = Frame(plate, source, pyramid, shapes, offsets, table.shape, level0)
    out = np.empty((table.shape[0] * table.shape[1], 3), np.float32)
    for layer in table.layers:  # each over the ones before it
        layer.write(frame, out)
    return out.reshape(table.shape + (3,))


def _pyramid(table: LookupTable, plate: np.ndarray, first: int, pyramids: dict | None):
    """(source, pyramid): the plate's bordered mip pyramid from level `first` to the table's
    last, with room after it for the table's fill profile (`FillProfile`), and the pyramid's rows of
    it; kept in `pyramids` when given (with room for any table's fill rows), else in a
    reused buffer."""
    seg = table.segmentation
    rows = pyramid_size(seg.height, seg.width, table.levels, first)
    key = (seg.height, seg.width, table.levels, first)
    source = None if pyramids is None else pyramids.get(key)
    if source is None:
        if pyramids is None:
            extra = FILL_BINS * table.fill.sides if table.fill is not None else 0
            source = scratch("pyramid", (rows + extra, 3))
        else:  # with room for any table's fill rows after it
            source = pyramids[key] = np.empty((rows + 2 * FILL_BINS, 3), np.float32)
        build_pyramid(plate, table.levels, first, out=source[:rows])
    return source, source[:rows]


def prior_parts(table: LookupTable, plate: np.ndarray, pyramids: dict | None = None):
    """Split a map at its sky prior (fill.py): the map without it and the prior's weight.

    The prior is the fill above the world's horizon, every direction there the plate does not
    show. The map is linear in the prior, so (map with a neutral prior of level 1 - map with it
    black) / that level is each texel's weight (probe.py puts an HDRI in its place). The
    plate's texture on the prior (`Params.sky_texture`) is left out: an HDRI in its place
    brings its own.

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
    layers = tuple(layer for layer in table.layers if not isinstance(layer, SkyTexture))
    table = dataclasses.replace(table, layers=layers)
    neutral = (1.0, 1.0, 1.0)  # the weight is the share of a neutral prior of level 1
    without, lit = (
        apply_table(
            dataclasses.replace(
                table,
                fill=dataclasses.replace(
                    fill, sky_gain=g, sky_tint=neutral, sky_from_plate=0.0, sky_tint_share=0.0
                ),
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
