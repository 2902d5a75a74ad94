"""The lookup table from map texels to filtered plate samples, built once and cached.

A table depends only on geometry: plate size, object bounds, parameters, layout and map
size. It stores, for every texel, a filtered sample of the plate's mip pyramid, so applying
it to a plate — a new frame with unchanged bounds — is one pyramid build and one gather. The
paper's method keeps every texel as a trilinear sample (bilinear on two mip levels) in the
compact form of trilinear.py (14 bytes a texel: its position on the lower level and the next
level's share, grouped by level); the other groups keep rows of the flat pyramid and weights.

Anti-aliasing: the texel's footprint on the plate (how far the plate position moves over
one texel, from the positions half a texel to either side) picks a mip level, so where a
large plate region is squeezed onto few texels (the ring F on the front face, the front
face's centre in the continuous limit) each texel averages the area it covers.

The camera-view method (camera_view.py) has three groups of texels, each with its own
number of taps: those the plate sees (4 x 4 bilinear samples over the footprint, 64 taps),
those near the plate's view (one trilinear sample of the blurred edge extension, faded into
the fill: extension.py) and the rest (the fill only: the profile interpolated by elevation,
and with `fill_sides` the left and the right profile weighted by `fill.side_weight`).
The fill profiles are computed per frame and stored after the pyramid, so they are one more
block of rows the same gathers read. The fill is written over every texel first (on a
lat-long not as taps: every texel keeps its elevation as one uint16 step, one per row without
a world horizon, read by `fill.fill_values`), the other groups over it.

Building works in blocks of texels (or rows) over the cores, so its temporaries stay small
whatever the map's size; on a lat-long the camera-view geometry is taken per row and per
column (a texel's azimuth is its column's, its elevation its row's).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import camera_view, ground, seen_texels, sky_texture
from .cache import bounded
from .extension import extension
from .fill import (
    fill_bins_latlong,
    fill_geometry,
    fill_level,
    fill_taps,
    side_weight,
    sky_share,
)
from .layers import (
    EdgeExtension,
    FillProfile,
    FillSteps,
    Layer,
    SkyTexture,
    Supersamples,
    Taps,
    TrilinearTexels,
)
from .layouts import directions_at, latlong_directions, map_shape, texel_directions
from .mipmap import level_offsets, level_shapes
from .parallel import CHUNK, for_blocks
from .params import Params
from .projection import plate_positions
from .segmentation import Segmentation, segment
from .supersample import supersamples
from .trilinear import MAX_TEXELS, trilinear_samples


@dataclass(frozen=True, eq=False)
class LookupTable:
    """Map texels -> filtered samples of the plate's mip pyramid, for one plate size and layout.

    Attributes
    ----------
    segmentation : Segmentation
        The object's regions on the plate the table was built for.
    layout : {"latlong", "cube"}
    size : int
        A lat-long's width or a cube's face size.
    shape : (int, int)
        (h, w) of the map.
    levels, first_level : int
        Pyramid levels `first_level` .. `levels` - 1 are read (mipmap.py).
    layers : tuple of layers.Layer
        The texels' samples, written in order, each over the ones before it (layers.py): the
        paper's method one `TrilinearTexels`; the camera view's the fill (`FillSteps` on a
        lat-long, `Taps` of every texel on a cube), an `EdgeExtension` and `Supersamples`;
        the ground method's those and the ground's `Taps`.
    fill : layers.FillProfile or None
        The camera view's fill profile, computed per frame after the pyramid.
    """

    segmentation: Segmentation
    layout: str
    size: int
    shape: tuple[int, int]
    levels: int
    first_level: int
    layers: tuple[Layer, ...]
    fill: FillProfile | None = None

    def reads_plate_level0(self) -> bool:
        """Whether every layer can read level 0 from the plate itself (`Layer.plate_level0`).

        Returns
        -------
        bool
        """
        return bool(self.layers) and all(layer.plate_level0 for layer in self.layers)


def _spans(q: np.ndarray, axis: int, wrap: bool, block: int, start: int = 0) -> np.ndarray:
    """Squared distance on the plate to the nearer neighbour texel along `axis`, per texel.

    q: (H, W, 2) positions. Taking the nearer of the two neighbours keeps a texel next to a
    discontinuity (the seams between the paper's front-face triangles) from being blurred
    across it. `block` > 0 cuts the axis into blocks (cube faces) with no neighbours across;
    `start`: the index along `axis` of q's first texel (q a slab of the map).
    """
    n = q.shape[axis]
    step = _squared_steps(q, axis)  # (H, W): to the next texel (the last: to the first)
    ahead = step
    behind = np.roll(step, 1, axis=axis)
    last = [slice(None)] * step.ndim
    if not wrap:
        last[axis] = slice(n - 1, n)
        ahead[tuple(last)] = np.inf
        last[axis] = slice(0, 1)
        behind[tuple(last)] = np.inf
    if block:
        cut = np.arange(start, start + n)
        ahead = np.where(_along(cut % block == block - 1, axis, step.ndim), np.inf, ahead)
        behind = np.where(_along(cut % block == 0, axis, step.ndim), np.inf, behind)
    span = np.minimum(ahead, behind)
    span[~np.isfinite(span)] = 0.0
    return span


def _squared_steps(q: np.ndarray, axis: int) -> np.ndarray:
    """(H, W) squared distance from each texel's position in q (H, W, 2) to the next one's
    along `axis` (the last texel's: to the first's), in q's precision."""

    def part(a, b):
        index = [slice(None)] * q.ndim
        index[axis] = slice(a, b)
        return tuple(index)

    d = np.empty_like(q)
    np.subtract(q[part(1, None)], q[part(None, -1)], out=d[part(None, -1)])
    np.subtract(q[part(None, 1)], q[part(-1, None)], out=d[part(-1, None)])
    np.multiply(d, d, out=d)
    return np.add(d[..., 0], d[..., 1])


def _along(mask: np.ndarray, axis: int, ndim: int) -> np.ndarray:
    shape = [1] * ndim
    shape[axis] = mask.size
    return mask.reshape(shape)


def _lod(layout: str, size: int, position: np.ndarray, band=None, cols=None) -> np.ndarray:
    """Mip level per texel: log2 of the plate pixels one texel covers, (H, W) float32.
    Computed in slabs of rows (each with its neighbour rows) over the cores; with `band`
    (first, stop) only those rows (the others 0); with `cols` (first, stop) of a lat-long
    only those columns (the others undefined; the first and last of them read only one
    neighbour, as if at the map's edge)."""
    height, width = position.shape[:2]
    first, stop = band or (0, height)
    lod = np.empty((height, width), np.float32)
    lod[:first] = 0.0
    lod[stop:] = 0.0
    c0, c1 = cols or (0, width)
    part = (c0, c1) != (0, width)

    def band_rows(a, b):
        a, b = first + a, first + b
        lo, hi = max(a - 1, 0), min(b + 1, height)
        slab = position[lo:hi, c0:c1]
        lod[a:b, c0:c1] = _slab_lod(layout, size, slab, lo, a, b, wrap=not part)

    for_blocks(band_rows, stop - first, min_rows=16, max_rows=max(1, CHUNK // width))
    return lod


def _slab_lod(
    layout: str, size: int, slab: np.ndarray, lo: int, a: int, b: int, wrap: bool = True
) -> np.ndarray:
    """`_lod` of the map's rows a .. b - 1 from `slab`, the positions of rows lo .. lo +
    len(slab) - 1 (those rows and their neighbours that exist: lo = max(a - 1, 0)). wrap:
    a lat-long's rows wrap around (False: `slab` holds only some of its columns)."""
    latlong = layout == "latlong"
    across = _spans(slab[a - lo : b - lo], 1, wrap=latlong and wrap, block=0)
    down = _spans(slab, 0, wrap=False, block=0 if latlong else size, start=lo)
    squared = np.maximum(np.maximum(across, down[a - lo : b - lo]), 1e-12)
    return 0.5 * np.log2(squared, dtype=np.float32)


def _frozen(*arrays):
    for a in arrays:
        if a is not None:
            a.flags.writeable = False


def _build_camera_view(
    seg: Segmentation, layout: str, size: int, params: Params, level0: bool = False
) -> LookupTable:
    """The camera-view method's table (see the module docstring and camera_view.py).
    `level0`: the pyramid keeps level 0 even when none of these texels read it there."""
    width, height = seg.width, seg.height
    intrinsics = params.lens.at(width, height)
    extend = params.extend
    filled = extend.fade is not None
    clamped = _clamped(layout, size, width, height, intrinsics, extend.fade)
    position, angle, _, directions, band, _, cols = clamped
    shapes = level_shapes(height, width)
    top = len(shapes) - 1
    seen, seen_level, near = _seen_and_near(
        layout, size, width, height, intrinsics, extend.fade, clamped
    )
    # The near texels' mip levels: the plate's footprint, or the extension's blur where wider.
    pixels = extend.blur * angle[near] * intrinsics[0]
    blur = np.minimum(np.log2(np.maximum(pixels, 1.0)), math.log2(max(extend.cap * height, 1.0)))
    lod_map = _lod(layout, size, position, band, cols).ravel()
    near_lod = np.clip(np.maximum(lod_map[near], blur), 0.0, top)
    level_fill = fill_level(shapes) if filled else None
    textured = filled and params.world.up is not None and params.world.sky_texture > 0.0
    sky_lod = sky_texture.sky_lod(layout, size, intrinsics, top) if textured else None
    reads = near_lod if sky_lod is None else np.append(near_lod, np.float32(sky_lod))
    first, levels = _camera_levels(top, seen_level, reads, level_fill, level0)
    layers, fill = [], None
    if filled:  # the fill, written over every texel first
        base = int(level_offsets(shapes[:levels], first)[-1])
        fill, coat = _camera_fill(
            layout, size, shapes, level_fill, base, intrinsics, width, params, directions
        )
        layers.append(coat)
    if textured:  # the unseen sky given the plate's texture, over the fill's prior
        layers += _sky_texture(layout, size, seen, directions, seg, intrinsics, params, sky_lod)
    # Near the plate's view: the blurred edge extension (a trilinear sample) faded into the
    # fill written before it (extension.py).
    px, py = position[..., 0].ravel()[near], position[..., 1].ravel()[near]
    near_ext = camera_view.fade_weight(angle[near], extend.fade) if filled else None
    edge = extension(near, px, py, near_lod, top, near_ext)
    if edge is not None:
        layers.append(EdgeExtension(edge))
    if seen.size:  # compact: 8 bytes a sample, not 32 (supersample.py)
        positions = seen_texels.supersample_positions(layout, size, seen, intrinsics)
        offsets = level_offsets(shapes, first)
        layers.append(Supersamples(supersamples(seen, positions, seen_level, shapes, offsets)))
    shape = map_shape(layout, size)
    return LookupTable(seg, layout, size, shape, levels, first, tuple(layers), fill)


def _sky_texture(layout, size, seen, directions, seg, intrinsics, params, lod) -> list:
    """[the SkyTexture layer] of the texels above the world's horizon the plate does not see
    (sky_texture.py), or [] when there are none."""
    up = np.asarray(params.world.up, np.float64)
    if directions is None:  # a lat-long: its texels' directions, once
        directions = directions_at(layout, size, np.arange(size * (size // 2)), 0.0, 0.0)
    sky = (directions @ (up / np.linalg.norm(up))) > 0.0
    sky[seen] = False
    texels = np.flatnonzero(sky)
    top = len(level_shapes(seg.height, seg.width)) - 1
    built = sky_texture.sky_texture(
        texels, directions[texels], seg.width, seg.height, intrinsics, params.world.up, lod,
        top, layout, size,
    )  # fmt: skip
    return [] if built is None else [SkyTexture(*built, params.world.sky_texture)]


def _seen_and_near(layout, size, width, height, intrinsics, fade, clamped):
    """The camera view's texels the plate sees ((S,) flat ids) with their supersamples' mip
    levels (S,), and those near the plate's view that the edge extension reaches ((N,) flat
    ids; `fade`: Extend.fade); `clamped`: `_clamped`'s. A lat-long's are looked for in
    `_clamped`'s block alone."""
    shape = map_shape(layout, size)
    _, angle, inside, directions, _, (start, stop), cols = clamped
    block = (slice(start, stop), slice(*cols))  # may be seen or near; flat ids from its own:
    ncols = cols[1] - cols[0]

    def ids(local):
        rows, columns = np.divmod(local, ncols)
        return (start + rows) * shape[1] + cols[0] + columns

    if layout == "latlong":  # a lat-long's texels are worked on row by row, not listed
        seen = ids(np.flatnonzero(inside.reshape(shape)[block]))
        centres = directions_at(layout, size, seen, 0.0, 0.0)
    else:
        seen, centres = None, directions
    seen, rect = seen_texels.seen_footprints(
        layout, size, centres, width, height, intrinsics, ids=seen
    )
    seen_level = seen_texels.supersample_levels(rect, level_shapes(height, width))
    unseen = np.ones(shape[0] * shape[1], bool)
    unseen[seen] = False
    unseen, near_angle = unseen.reshape(shape)[block], angle.reshape(shape)[block]
    # The edge extension's texels: those it reaches only (the fade is 0 from extend_fade
    # degrees on): most of a large map is the fill alone.
    if fade is not None and fade > 0:
        reach = np.float32(math.radians(fade))
        near = ids(np.flatnonzero(unseen & (near_angle < reach)))
    elif fade is not None:
        near = ids(np.flatnonzero(unseen & (near_angle <= 0)))
    else:
        near = ids(np.flatnonzero(unseen))
    return seen, seen_level, near


def _camera_levels(top: int, seen_level, near_lod, level_fill, level0: bool):
    """(first, levels): the pyramid levels the camera view's texels read, from the near
    texels' levels, the seen texels' (those on level 0 read the plate itself, supersample.py,
    unless `level0`: the ground method's taps may read it there) and the fill's (or None)."""
    pyramid_seen = seen_level if level0 else seen_level[seen_level > 0]
    used = [
        int(near_lod.min()) if near_lod.size else top,
        int(pyramid_seen.min()) if pyramid_seen.size else top,
    ]
    deepest = [
        int(near_lod.max()) + 1 if near_lod.size else 0,
        int(seen_level.max()) if seen_level.size else 0,
    ]
    if level_fill is not None:
        used.append(level_fill)
        deepest.append(level_fill)
    return min(min(used), max(top - 1, 0)), min(max(deepest) + 1, top + 1)


def _clamped(layout, size, width, height, intrinsics, fade):
    """Every texel the camera view may read the plate for, clamped onto the plate's view
    (camera_view.clamp_to_view): (position (H, W, 2) float32 plate positions, angle (T,)
    float32 radians to the clamped twin, inside (T,) bool whether the plate sees the texel's
    centre (a lat-long; None on a cube), directions (T, 3) float32 texel directions (a cube;
    None on a lat-long), band (first, stop) the rows the extension may reach, rows (first,
    stop) and cols (first, stop) the block worked on). A lat-long's texels outside the block
    are the fill alone: never projected, given a level or looked at; its trigonometry is per
    row and column. `fade`: Extend.fade (None: no fill, every texel extended)."""
    shape = map_shape(layout, size)
    count = shape[0] * shape[1]
    position = np.empty((count, 2), np.float32)
    angle = np.empty(count, np.float32)
    filled = fade is not None
    band, cols = (0, shape[0]), (0, shape[1])
    if layout != "latlong":
        directions = texel_directions(layout, size, dtype=np.float32).reshape(-1, 3)

        def project(a, b):
            position[a:b], angle[a:b] = camera_view.clamp_to_view(
                directions[a:b], width, height, intrinsics
            )

        for_blocks(project, count, max_rows=CHUNK)
        return position.reshape(shape + (2,)), angle, None, directions, band, band, cols
    inside = np.empty(count, bool)
    if filled:
        reach = math.radians(max(fade, 0.0))
        band = camera_view.latlong_rows_near_view(size, width, height, intrinsics, reach)
    start, stop = max(band[0] - 1, 0), min(band[1] + 1, shape[0])  # + the lod's neighbours
    if filled:
        cols = camera_view.latlong_cols_near_view(
            size, width, height, intrinsics, reach, (start, stop)
        )
    grid = (position.reshape(shape + (2,)), angle.reshape(shape), inside.reshape(shape))
    columns = slice(*cols)

    def project_rows(a, b):
        rows = slice(start + a, start + b)
        texels = camera_view.clamp_to_view_latlong(size, width, height, intrinsics, rows, columns)
        for array, values in zip(grid, texels, strict=True):
            array[rows, columns] = values.reshape(array[rows, columns].shape)

    for_blocks(project_rows, stop - start, min_rows=16, max_rows=max(1, CHUNK // size))
    return position.reshape(shape + (2,)), angle, inside, None, band, (start, stop), cols


def _camera_fill(layout, size, shapes, level, base, intrinsics, width, params, directions):
    """The camera view's fill (fill.py) by `params`' fill and world: (its FillProfile,
    computed per frame on mip `level` into the rows from `base`; the layer writing it over
    every texel: a lat-long's `FillSteps`, read by fill.fill_values, or a cube's `Taps`)."""
    options, world = params.fill, params.world
    up = world.up
    sides = 2 if options.sides else 1
    bins, window, counts = fill_geometry(
        shapes[level], level, intrinsics, options.width, options.spread, sides, up
    )
    fill = FillProfile(
        level,
        base,
        options.saturation,
        sides,
        options.energy,
        bins,
        window,
        counts,
        sky_share(sides) if up is not None else None,
        world.sky_gain,
        world.sky_tint,
        world.sky_from_plate,
        world.sky_tint_share,
    )
    _frozen(bins, window, counts)
    if layout != "latlong":  # the fill's taps for every texel, in order, before the others
        side = side_weight(directions, intrinsics, width) if sides == 2 else None
        return fill, Taps(None, *fill_taps(directions, base, side, up))
    # Compact: 2 bytes a texel, read per frame by fill_values; a texel's azimuth is its
    # column's: the side weights per column.
    toward = directions_at(layout, size, np.arange(size), 0, 0)
    side = side_weight(toward, intrinsics, width) if sides == 2 else None
    if up is None:  # a texel's elevation is its row's: one step per row
        steps = fill_bins_latlong(size)
    else:
        rows = size // 2
        steps = np.empty(rows * size, np.uint16)

        def fill_rows(a, b):
            fill_bins_latlong(size, up, slice(a, b), out=steps[a * size : b * size])

        for_blocks(fill_rows, rows, min_rows=16, max_rows=max(1, CHUNK // size))
    coat = FillSteps(steps, None if side is None else np.repeat(side, 3), base, sides)
    _frozen(coat.steps, coat.side)
    return fill, coat


def build_table(seg: Segmentation, layout: str, size: int, params=0) -> LookupTable:
    """Build the table for a segmentation, uncached (see `lookup_table`).

    Parameters
    ----------
    seg : Segmentation
    layout : {"latlong", "cube"}
    size : int
        A lat-long's width or a cube's face size.
    params : Params or int, optional
        The Params, or for the paper's method just the number of triangles (0: continuous).

    Returns
    -------
    LookupTable
    """
    if not isinstance(params, Params):
        params = Params(triangles=int(params))
    return BUILDERS[params.method](seg, layout, size, params)


def _build_paper(seg: Segmentation, layout: str, size: int, params: Params) -> LookupTable:
    """The paper's table: every texel one trilinear sample of its plate position (§3.1),
    at the mip level of its footprint."""
    triangles = params.regions.triangles
    shape = map_shape(layout, size)
    shapes = level_shapes(seg.height, seg.width)
    top = len(shapes) - 1
    if layout == "latlong":
        position, lod = _paper_latlong(seg, size, triangles, top)
    else:
        directions = texel_directions(layout, size, dtype=np.float32).reshape(-1, 3)
        count = directions.shape[0]
        position = np.empty((count, 2), np.float32)

        def project(a, b):
            position[a:b] = plate_positions(directions[a:b], seg, triangles)

        for_blocks(project, count, max_rows=CHUNK)
        position = position.reshape(shape + (2,))
        lod = np.clip(_lod(layout, size, position).ravel(), 0.0, top)
    # Model no more than the map needs: levels finer than any texel's are not stored.
    first = min(int(lod.min()), max(top - 1, 0))
    px, py = position[..., 0].ravel(), position[..., 1].ravel()
    samples = TrilinearTexels(trilinear_samples(px, py, lod, top, shape))
    levels = min(int(lod.max()) + 2, top + 1)
    return LookupTable(seg, layout, size, shape, levels, first, (samples,))


def _paper_latlong(seg: Segmentation, size: int, triangles: int, top: int):
    """The paper's plate positions (H, W, 2) float32 and mip levels (H W,) float32 (clipped
    to [0, top]) of a `size`-wide lat-long, in slabs of rows over the cores: each slab's
    directions (the same as `texel_directions`'), projected with its neighbour rows, whose
    positions its levels read while they are in cache (no map-sized array of directions)."""
    height, width = map_shape("latlong", size)
    position = np.empty((height, width, 2), np.float32)
    lod = np.empty((height, width), np.float32)
    fx = np.arange(width, dtype=np.float64)[None, :] + 0.5

    def rows(a, b):
        lo, hi = max(a - 1, 0), min(b + 1, height)
        fy = np.arange(lo, hi, dtype=np.float64)[:, None] + 0.5
        slab = plate_positions(latlong_directions(fx, fy, width, np.float32), seg, triangles)
        position[a:b] = slab[a - lo : b - lo]
        level = _slab_lod("latlong", size, slab, lo, a, b)
        np.minimum(np.maximum(level, 0.0, out=level), top, out=lod[a:b])

    for_blocks(rows, height, min_rows=16, max_rows=max(1, 4 * CHUNK // width))
    return position, lod.ravel()


def _build_ground(seg: Segmentation, layout: str, size: int, params: Params) -> LookupTable:
    """The ground method's table (ground.py): the camera view's table for this camera and
    horizon (cached, shared by every object position), with the texels whose ground point the
    plate shows taken out of its layers and given their ground taps (faded into the fill near
    the plate's borders)."""
    width, height = seg.width, seg.height
    distant = dataclasses.replace(params, method="camera", ground=None)
    base = _camera_table(width, height, distant, layout, size, True)  # level 0 for the ground
    intrinsics = params.lens.at(width, height)
    up = params.world.up
    shapes = level_shapes(height, width)
    offsets = level_offsets(shapes, base.first_level)
    levels = (base.first_level, base.levels - 1)
    directions = None
    if layout == "latlong":
        ids, share, index, weight = ground.ground_taps_latlong(
            size, params.ground, up, intrinsics, width, height, shapes, offsets, *levels
        )
    else:
        directions = texel_directions(layout, size, dtype=np.float32).reshape(-1, 3)
        ids, share, index, weight = ground.ground_taps(
            layout,
            size,
            directions,
            params.ground,
            up,
            intrinsics,
            width,
            height,
            shapes,
            offsets,
            *levels,
        )
    # The camera view's layers without the ground's texels, then the ground's.
    taken = np.zeros(base.shape[0] * base.shape[1], bool)
    taken[ids] = True
    layers = [layer.without(taken) for layer in base.layers]
    full = share >= 1.0
    if full.any():
        layers.append(Taps(ids[full], index[full], weight[full]))
    part = np.flatnonzero(~full)
    if part.size and base.fill is None:
        layers.append(Taps(ids[part], index[part], weight[part]))
    elif part.size:
        toward = directions[ids[part]] if directions is not None else None
        taps = (ids[part], share[part], index[part], weight[part])
        layers.append(_ground_blend(base, *taps, toward, intrinsics, up))
    kept = tuple(layer for layer in layers if layer is not None)
    return dataclasses.replace(base, segmentation=seg, layers=kept)


def _ground_blend(base, texels, share, index, weight, toward, intrinsics, up) -> Taps:
    """The ground's taps of `texels` faded into the fill of `base` (the camera view's table)
    by their `share` (n,): one set of taps, the ground's and the fill's. `toward`: their
    directions, or None on a lat-long (from their rows and columns)."""
    width = base.segmentation.width
    if toward is None:
        rows, cols = np.divmod(texels, base.shape[1])
        toward = latlong_directions(cols + 0.5, rows + 0.5, base.size)
    side = side_weight(toward, intrinsics, width) if base.fill.sides == 2 else None
    fill_index, fill_weight = fill_taps(toward, base.fill.base, side, up)
    w = share[:, None]
    return Taps(
        texels,
        np.concatenate((index, fill_index), axis=1),
        np.concatenate((weight * w, fill_weight * (1.0 - w)), axis=1),
    )


# Each method's table (Params.method -> its builder; methods.METHODS names them).
BUILDERS = {"paper": _build_paper, "camera": _build_camera_view, "ground": _build_ground}


def max_size(layout: str) -> int:
    """The largest map ``size`` of ``layout`` (a lat-long's width, a cube's face) whose table
    the compact form holds (trilinear.MAX_TEXELS texels): a lat-long is W x W / 2 texels, a
    cube six faces."""
    if layout == "latlong":
        return 2 * math.isqrt(MAX_TEXELS // 2)
    return math.isqrt(MAX_TEXELS // 6)


@bounded  # one budget in bytes for every table (cache.py)
def lookup_table(
    width: int, height: int, bbox: tuple, params: Params, layout: str = "latlong", size: int = 1024
) -> LookupTable:
    """The cached table for a plate size, an object's bounds, params and layout.

    The camera-view method's table depends on the camera, not on the object: one per plate size,
    camera and layout is shared by every object and pose (each gets its own segmentation); the
    ground method's adds, per object position, the texels that see the ground.

    Parameters
    ----------
    width, height : int
        The plate's size in pixels.
    bbox : tuple of 4 floats
        The object's bounds (x0, y0, x1, y1) in plate pixels (origin top-left, y down).
    params : Params
    layout : {"latlong", "cube"}, optional
    size : int, optional
        A lat-long's width or a cube's face size.

    Returns
    -------
    LookupTable
        Shared: kept in the byte-bounded cache (cache.py), never to be changed.

    Raises
    ------
    ValueError
        As `segment` for bad bounds; an unknown layout or a bad size (`layouts.map_shape`).
    """
    seg = segment(width, height, bbox, params)
    if params.method == "camera":
        return dataclasses.replace(
            _camera_table(width, height, params, layout, size, False), segmentation=seg
        )
    return build_table(seg, layout, size, params)


@bounded
def _camera_table(
    width: int, height: int, params: Params, layout: str, size: int, level0: bool
) -> LookupTable:
    """The camera-view method's table: it reads only the plate's size from the segmentation.
    `level0`: its pyramid keeps level 0 (the ground method's base, whose taps may read it)."""
    centre = (width / 2 - 1, height / 2 - 1, width / 2 + 1, height / 2 + 1)
    return _build_camera_view(segment(width, height, centre, params), layout, size, params, level0)
