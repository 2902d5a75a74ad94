"""The camera-view method (the add-on's Camera View): use the plate camera's field of view
(which Blender knows).

The paper (§3.1) ignores the camera: it stretches region X over the whole back face, so what
lies behind the object lands roughly, not where it really is. With the horizontal field of
view the plate is a pinhole image (docs/conventions.md):

    f = (W / 2) / tan(hfov / 2);  direction d (z > 0) is seen at
    px = W/2 - f d.x / d.z,  py = H/2 - f d.y / d.z      (continuous plate coordinates)

so every direction the plate sees is placed exactly. Three kinds of texel:

- **seen** (the texel's centre projects into the plate): the mean of n x n bilinear samples
  of the plate at the projections of n x n directions spread evenly over the texel
  (`supersample_taps`, n = SUPERSAMPLE), on level 0 of the mip pyramid while the samples are
  less than 4 pixels apart, else on the level where they are 2-4 pixels apart — a box filter
  over the texel's footprint, as a renderer supersamples a pixel. (One trilinear tap at the
  footprint's mip level blurs far more: 34 dB against 58 dB where the plate sees, on the
  accuracy study's ground truth; docs/accuracy.md.)
- **near** (unseen, less than `extend_fade` degrees from the plate's view): the direction is
  clamped, in azimuth and elevation, onto the plate's view, and the plate is read there through a
  blur that grows with the angle between the direction and its clamped twin — sky continues
  from the top band, ground from the bottom band, the sides from the side bands; the blur is
  capped at a share of the plate height. With the angle this extension fades (a smoothstep)
  into
- **the fill**: a robust average of the plate by elevation and side (in the camera frame).
  Per elevation: the log-average (per channel) of the plate pixels within `fill_width`
  degrees of the texel's elevation, the window's centre held inside the plate's own range of
  elevations, so near the horizon it is the rows at that elevation and above or below the
  plate the top or bottom band; beyond the plate the window widens by `fill_spread` degrees
  per degree, so far from the plate the fill tends to the whole plate's. A log-average because
  a sun or a lit window in view makes a plain mean far too bright for the directions that show
  neither; but a log-average is darker than the light the plate holds, so it is brightened
  toward the arithmetic mean's luminance by `fill_energy` (0.5: the geometric mean of the two).
  Per side (`fill_sides`): the plate's left half gives the profile for the left, its right half
  for the right (`side_weight`: ahead of the camera by the azimuth up to the plate's edges,
  behind it returning to an even blend straight behind); both share the band's brightness, so
  only their colour differs, and `fill_saturation` desaturates the tint they share (the
  plate's tint is a poor guess for what it does not show) while keeping the difference between
  them: what is left of the object in the plate stays on the left.

Fade and fill are defined in angles, not texels, so the map's width does not change them.
"""

from __future__ import annotations

import math

import numpy as np

from .layouts import cube_directions
from .parallel import CHUNK, for_blocks
from .products import matmul

FILL_BINS = 181  # the fill profile: 1-degree bins of camera-frame elevation, -90 .. 90
FILL_ROWS = 96  # the fill is computed on the first mip level at most this many rows high


def intrinsics_from_hfov(width: int, height: int, hfov_deg: float):
    """(fx, fy, cx, cy) in plate pixels of a centred pinhole with square pixels."""
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return f, f, width / 2.0, height / 2.0


def clamp_to_view(directions, width, height, intrinsics):
    """Camera-frame `directions` (..., 3) clamped in azimuth and elevation onto the plate's
    view (the directions it sees): ((..., 2) float32 continuous plate position of the clamped
    direction, (...,) float32 angle in radians between the direction and its clamped twin;
    0 inside)."""
    fx, fy, cx, cy = intrinsics
    d = np.asarray(directions, dtype=np.float32)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    norm = np.sqrt(x * x + y * y + z * z)
    norm = np.where(norm > 0, norm, 1.0)
    azimuth = np.arctan2(x, z)  # + toward the plate's left
    elevation = np.arcsin(np.clip(y / norm, -1.0, 1.0))
    a = np.clip(azimuth, math.atan((cx - width) / fx), math.atan(cx / fx))
    cos_a = np.cos(a)
    # The frame's top and bottom edges at this azimuth: y / z = tan(e) / cos(a) = (cy - py) / fy.
    e = np.clip(elevation, np.arctan((cy - height) / fy * cos_a), np.arctan(cy / fy * cos_a))
    px = cx - fx * np.tan(a)
    py = cy - fy * np.tan(e) / cos_a
    position = np.stack((np.clip(px, 0.0, width), np.clip(py, 0.0, height)), axis=-1)
    cos_e = np.cos(e)
    clamped = np.stack((np.sin(a) * cos_e, np.sin(e), cos_a * cos_e), axis=-1)
    cosine = np.clip(np.einsum("...i,...i->...", d, clamped) / norm, -1.0, 1.0)
    angle = np.arccos(cosine)
    angle[cosine > 1.0 - 1e-6] = 0.0  # float32 round-off inside the plate's view
    return position.astype(np.float32), angle.astype(np.float32)


ANGLE_EPS = math.acos(1.0 - 1e-6)  # angles below count as inside the plate's view


def _latlong_columns(size: int, width, fx: float, cx: float, columns: range):
    """Per column of a `size`-wide lat-long (`columns`): (azimuth, + toward the plate's left;
    the azimuth clamped onto the plate's view, a; cos(a))."""
    az = -2.0 * np.pi * ((np.arange(columns.start, columns.stop) + 0.5) / size - 0.5)
    a = np.clip(az, math.atan((cx - width) / fx), math.atan(cx / fx))
    return az, a, np.cos(a)


def clamp_to_view_latlong(size: int, width, height, intrinsics, rows=None, cols=None):
    """`clamp_to_view` for the texel centres of a `size`-wide lat-long (the camera frame's),
    rows `rows` and columns `cols` (slices; default all): ((n, 2) float32 positions, (n,)
    float32 angles, (n,) bool seen), n texels row by row.

    A lat-long texel's azimuth is its column's and its elevation its row's, and the clamped
    elevation is the row's or one of the column's two limits: every trigonometric function
    is taken per row or per column, the map's texels only combine them."""
    fx, fy, cx, cy = intrinsics
    h = size // 2
    rows = range(h)[rows or slice(None)]
    el = -np.pi * ((np.arange(rows.start, rows.stop, rows.step) + 0.5) / h - 0.5)  # (n,)
    columns = range(size)[cols or slice(None)]
    az, a, cos_a = _latlong_columns(size, width, fx, cx, columns)
    lo = np.arctan((cy - height) / fy * cos_a)  # the frame's bottom and top at this azimuth
    hi = np.arctan(cy / fy * cos_a)
    px = np.clip(cx - fx * np.tan(a), 0.0, width).astype(np.float32)
    below, above = el[:, None] < lo, el[:, None] > hi  # (n, W)
    # The centre's projection lies in the plate (seen_footprints' test, per row and column).
    inside = (np.cos(az) > 1e-9) & (az == a) & (np.cos(el)[:, None] > 0) & ~below & ~above

    def pick(f):  # f(e) for the clamped elevation, from per-row and per-column values
        return np.where(below, f(lo), np.where(above, f(hi), f(el)[:, None])).astype(np.float32)

    py = cy - (fy / cos_a).astype(np.float32) * pick(np.tan)
    position = np.empty((len(rows), len(columns), 2), np.float32)
    position[..., 0] = px
    position[..., 1] = np.clip(py, 0.0, height)
    # The angle between the direction and its clamped twin, well conditioned for small ones:
    # sin^2(angle / 2) = sin^2((el - e) / 2) + cos(el) cos(e) sin^2((az - a) / 2).
    off = np.where(below, el[:, None] - lo, np.where(above, el[:, None] - hi, 0.0))
    half = np.sin(0.5 * off.astype(np.float32))
    half *= half
    side = np.sin(0.5 * (az - a)) ** 2  # (W,)
    half += pick(np.cos) * (np.cos(el)[:, None] * side).astype(np.float32)
    np.sqrt(np.clip(half, 0.0, 1.0, out=half), out=half)
    angle = 2.0 * np.arcsin(half)
    angle[angle < ANGLE_EPS] = 0.0  # as clamp_to_view: round-off inside the plate's view
    return position.reshape(-1, 2), angle.ravel(), inside.ravel()


def latlong_rows_near_view(size: int, width, height, intrinsics, reach: float) -> tuple:
    """(first, stop): the rows of a `size`-wide lat-long (the camera frame's) with a texel
    centre less than `reach` radians from the plate's view (or in it), one row of margin
    each side. A direction's angle to its clamped twin is at least their difference in
    elevation, and the clamped elevation lies between the frame's lowest bottom and highest
    top (`clamp_to_view_latlong`), so the other rows are farther than `reach` everywhere."""
    fx, fy, cx, cy = intrinsics
    h = size // 2
    _, _, cos_a = _latlong_columns(size, width, fx, cx, range(size))
    low = float(np.arctan((cy - height) / fy * cos_a).min())
    high = float(np.arctan(cy / fy * cos_a).max())
    el = -np.pi * ((np.arange(h) + 0.5) / h - 0.5)
    rows = np.flatnonzero((el > low - reach) & (el < high + reach))
    if not rows.size:
        return 0, 0
    return max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 2, h)


def latlong_cols_near_view(size: int, width, height, intrinsics, reach: float, rows) -> tuple:
    """(first, stop): the columns of a `size`-wide lat-long whose texel centres in rows
    `rows` ((first, stop), `latlong_rows_near_view`) may be less than `reach` radians from
    the plate's view (or in it), one column of margin each side (their levels read their
    neighbours). With e a texel's clamped elevation and a its clamped azimuth,
    sin^2(angle / 2) >= cos(el) cos(e) sin^2((az - a) / 2) (`clamp_to_view_latlong`), and
    cos(e) is least at the frame's bottom or top at that azimuth: a column where even that
    bound is beyond `reach` for the rows' widest elevation holds the fill alone."""
    fx, fy, cx, cy = intrinsics
    h = size // 2
    if rows[1] <= rows[0]:
        return 0, 0
    el = -np.pi * ((np.arange(rows[0], rows[1]) + 0.5) / h - 0.5)
    az, a, cos_a = _latlong_columns(size, width, fx, cx, range(size))
    cos_e = np.minimum(
        np.cos(np.arctan((cy - height) / fy * cos_a)), np.cos(np.arctan(cy / fy * cos_a))
    )
    bound = float(np.cos(el).min()) * cos_e * np.sin(0.5 * (az - a)) ** 2
    # A margin for the float32 angles the table compares with `reach`.
    cols = np.flatnonzero(bound < np.sin(0.5 * reach) ** 2 * 1.001 + 1e-9)
    if not cols.size:
        return 0, 0
    return max(int(cols[0]) - 2, 0), min(int(cols[-1]) + 3, size)


def plate_positions(
    directions: np.ndarray,
    width: int,
    height: int,
    hfov_deg: float | None = None,
    blur: float = 1.0,
    max_blur: float = 0.125,
    intrinsics=None,
) -> tuple[np.ndarray, np.ndarray]:
    """Plate positions and extra blur for camera-frame `directions` (..., 3).

    The camera is `intrinsics` = (fx, fy, cx, cy) in plate pixels (a shifted lens, non-square
    pixels), or a centred pinhole of horizontal field of view `hfov_deg`. Returns
    ((..., 2) float32 continuous plate coordinates, (...,) float32 mip level of the blur:
    log2 of `blur` x (angle to the plate's view in radians) x fx pixels, at most
    log2(max_blur x height)). Inside the plate's view the blur level is 0.
    """
    intrinsics = intrinsics or intrinsics_from_hfov(width, height, hfov_deg)
    position, angle = clamp_to_view(directions, width, height, intrinsics)
    pixels = blur * angle * intrinsics[0]
    cap = math.log2(max(max_blur * height, 1.0))
    lod = np.minimum(np.log2(np.maximum(pixels, 1.0)), cap)
    return position, lod.astype(np.float32)


def fade_weight(angle: np.ndarray, fade_deg: float) -> np.ndarray:
    """Weight of the edge extension at `angle` (radians) from the plate's view: 1 at its edge,
    falling with a smoothstep to 0 at `fade_deg` degrees (float32)."""
    if fade_deg <= 0:
        return (angle <= 0).astype(np.float32)
    t = np.clip(angle / np.float32(math.radians(fade_deg)), 0.0, 1.0)
    return (1.0 - t * t * (3.0 - 2.0 * t)).astype(np.float32)


# --- seen texels: a supersampled box filter ------------------------------------------------


def directions_at(layout: str, size: int, ids: np.ndarray, dx: float, dy: float):
    """Directions (n, 3) through the texels `ids` (flat indices) shifted by (dx, dy) texels."""
    if layout == "latlong":
        # The trigonometry per row and per column of the map (as latlong_directions takes
        # it, so the values are the same), each texel a product of its row's and column's.
        row, col = np.divmod(ids, size)
        h = size // 2
        lat = -np.pi * ((np.arange(h) + 0.5 + dy) / h - 0.5)
        lon = -2.0 * np.pi * ((np.arange(size) + 0.5 + dx) / size - 0.5)
        cos_lat = np.cos(lat)[row]
        out = np.empty((len(ids), 3), np.float64)
        np.multiply(np.sin(lon)[col], cos_lat, out=out[:, 0])
        out[:, 1] = np.sin(lat)[row]
        np.multiply(np.cos(lon)[col], cos_lat, out=out[:, 2])
        return out
    row, col = np.divmod(ids, size)
    face, frow = np.divmod(row, size)
    return cube_directions(face, col + dx, frow + dy, size)


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
            [a + np.flatnonzero(project(directions[a:b])[2]) for a, b in _chunks(len(directions))]
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
    for a, b in _chunks(count, 4096):  # the texels' taps written while in the cache
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


# --- the fill: a robust average of the plate by elevation ---------------------------------------


def fill_level(shapes) -> int:
    """The mip level the fill is computed on: the first at most FILL_ROWS rows high."""
    for i, (h, _) in enumerate(shapes):
        if h <= FILL_ROWS:
            return i
    return len(shapes) - 1


def elevation_deg(directions, up=None) -> np.ndarray:
    """Elevation in degrees of (..., 3) directions above the horizon whose normal is ``up``
    (camera frame), or above the camera's own horizontal plane (up = +Y) without one."""
    d = np.asarray(directions, np.float64)
    norm = np.sqrt(np.einsum("...i,...i->...", d, d))
    norm = np.where(norm > 0, norm, 1.0)
    if up is None:
        height = d[..., 1]
    else:
        u = np.asarray(up, np.float64)
        height = d @ (u / np.linalg.norm(u))
    return np.degrees(np.arcsin(np.clip(height / norm, -1.0, 1.0)))


def fill_geometry(
    shape,
    level: int,
    intrinsics,
    width_deg: float,
    spread: float = 0.0,
    sides: int = 1,
    up=None,
):
    """What the fill needs of a plate's geometry at mip `level` of shape (h, w).

    Returns (bins (h * w,) int64: each pixel's 1-degree elevation bin, plus FILL_BINS x its
    side (0: the plate's left half, 1: its right half; with `sides` = 1 every pixel is side 0),
    window (sides, 2, FILL_BINS) int64: for every side and bin of the profile the half-open
    range [lo, hi) of elevation bins it averages, counts (sides, FILL_BINS + 1) float64
    cumulative pixel counts per elevation bin). The window is the bins within `width_deg` of
    the bin's elevation, its centre held `width_deg` inside the plate's own range of elevations
    (so above the plate: the top band; below: the bottom band), widening by `spread` degrees
    per degree beyond. Elevations are above the horizon whose normal is `up` (camera frame;
    None: the camera's own, +Y).
    """
    fx, fy, cx, cy = intrinsics
    h, w = shape
    s = 2.0**level
    py, px = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = -((px + 0.5) * s - cx) / fx, -((py + 0.5) * s - cy) / fy
    elevation = elevation_deg(np.stack((dx, dy, np.ones_like(dx)), -1), up).ravel()
    ebin = np.clip(np.rint(elevation + 90.0), 0, FILL_BINS - 1).astype(np.int64)
    if sides == 2:
        side = ((px + 0.5) * s >= cx).ravel().astype(np.int64)  # 0: left (+X), 1: right
    else:
        side = np.zeros(ebin.size, np.int64)
    windows, counts = [], []
    for k in range(sides):
        mine = side == k
        if not mine.any():  # a plate one pixel wide: both sides are the whole plate
            mine = np.ones(ebin.size, bool)
        b, e = ebin[mine], elevation[mine]
        count = np.concatenate(([0.0], np.cumsum(np.bincount(b, minlength=FILL_BINS))))
        lo_e, hi_e = e.min() + width_deg, e.max() - width_deg
        centre = np.arange(FILL_BINS) - 90.0
        centre = (
            np.clip(centre, lo_e, hi_e) if lo_e <= hi_e else np.full(FILL_BINS, 0.5 * (lo_e + hi_e))
        )
        half = width_deg + spread * np.abs(np.arange(FILL_BINS) - 90.0 - centre)
        lo = np.clip(np.rint(centre - half + 90.0), 0, FILL_BINS - 1).astype(np.int64)
        hi = np.clip(np.rint(centre + half + 90.0), 0, FILL_BINS - 1).astype(np.int64) + 1
        # Never an empty window: widen to the nearest bins that hold pixels.
        empty = count[hi] - count[lo] <= 0
        if empty.any():
            lo[empty], hi[empty] = b.min(), b.max() + 1
        windows.append(np.stack((lo, hi)))
        counts.append(count)
    bins = ebin + FILL_BINS * side
    return bins, np.stack(windows), np.stack(counts)


REC709_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)
HORIZON_BIN = 90  # the bin of elevation 0: bins above it look above the horizon


def sky_share(window, counts) -> np.ndarray:
    """(sides * FILL_BINS,) float32: for each bin above the horizon, the share of its window's
    plate pixels that are above the horizon too (elevations measured from the world's horizon,
    `fill_geometry` with `up`); 1 for the bins at or below it. Where it is under 1 the window
    reaches down into what the plate shows below the horizon (ground, walls): `fill_profile`
    then blends toward a prior for the sky."""
    out = np.ones((window.shape[0], FILL_BINS), np.float64)
    for k in range(window.shape[0]):
        lo, hi = window[k]
        total = counts[k][hi] - counts[k][lo]
        start = np.maximum(lo, HORIZON_BIN + 1)
        above = np.where(hi > start, counts[k][hi] - counts[k][np.minimum(start, hi)], 0.0)
        share = np.where(total > 0, above / np.maximum(total, 1e-12), 0.0)
        bins = np.arange(FILL_BINS) > HORIZON_BIN
        out[k, bins] = share[bins]
    return out.ravel().astype(np.float32)


def fill_profile(
    level_pixels: np.ndarray,
    bins,
    window,
    counts,
    saturation: float = 1.0,
    out=None,
    energy: float = 0.0,
    sky=None,
    sky_gain: float = 1.0,
) -> np.ndarray:
    """The fill (sides * FILL_BINS, 3) float32 of one frame, sides = len(window): per side and
    elevation bin the log-average (per channel) of the pixels `level_pixels` (h, w, 3) in its
    window (see fill_geometry), brightened toward the arithmetic mean's luminance by `energy`
    (0: the log-average, robust but darker than the light the plate holds; 1: the mean's
    luminance; between: their geometric blend), its colour kept by `saturation` (0: grey of
    the same luminance).

    With two sides (the plate's left and right halves), both share the band's brightness (the
    mean of their R, G, B means) and differ only in colour: `saturation` then desaturates what
    they share and keeps the difference between them (a plate red on the left and blue on the
    right stays red on the left).

    `sky` ((sides * FILL_BINS,) from `sky_share`): where under 1, the bin is blended toward a
    neutral sky `sky_gain` times as bright as the whole plate (its log-average brightened by
    `energy` as above): what a plate without sky says of the sky (docs/scenes3d.md).
    """
    sides = window.shape[0]
    size = sides * FILL_BINS
    pixels = np.maximum(level_pixels.reshape(-1, 3), 0.0)
    eps = 1e-3 * pixels.mean(0) + 1e-12  # scale-free: black pixels count as 1/1000 of the mean
    logs = np.log(pixels + eps)
    out = np.empty((size, 3), np.float32) if out is None else out
    # Per channel, the sums of the logs (and of the pixels) in every bin of every side, once.
    sums = [
        [np.bincount(bins, source[:, c], size) for c in range(3)]
        for source in ((logs, pixels) if energy > 0 else (logs,))
    ]
    for k in range(sides):
        lo, hi = window[k]
        n = counts[k][hi] - counts[k][lo]
        rows = slice(k * FILL_BINS, (k + 1) * FILL_BINS)
        mean = np.empty((FILL_BINS, 3), np.float64)
        for c in range(3):
            for per_bin, target in zip(sums, (out, mean)):
                total = np.concatenate(([0.0], np.cumsum(per_bin[c][rows])))
                target[rows if target is out else slice(None), c] = (total[hi] - total[lo]) / n
            out[rows, c] = np.exp(out[rows, c]) - eps[c]
        if energy > 0:
            ratio = np.maximum(mean @ REC709_LUMA, 1e-30) / np.maximum(
                out[rows] @ REC709_LUMA, 1e-30
            )
            out[rows] *= (ratio**energy)[:, None].astype(np.float32)
    np.maximum(out, 0.0, out=out)
    if sides == 2:
        left, right = out[:FILL_BINS], out[FILL_BINS:]
        shared = 0.5 * (left.mean(1) + right.mean(1))[:, None]
        left *= shared / np.maximum(left.mean(1), 1e-30)[:, None]
        right *= shared / np.maximum(right.mean(1), 1e-30)[:, None]
        if saturation != 1.0:
            common = 0.5 * (left + right)
            luma = (common @ REC709_LUMA)[:, None]
            shift = np.float32(saturation - 1.0) * (common - luma)
            np.maximum(left + shift, 0.0, out=left)
            np.maximum(right + shift, 0.0, out=right)
    elif saturation != 1.0:
        luma = (out @ REC709_LUMA)[:, None]
        out[:] = luma + np.float32(saturation) * (out - luma)
    if sky is not None and (sky < 1).any():
        luma = pixels @ REC709_LUMA
        level = math.exp(float(np.log(luma + float(eps @ REC709_LUMA)).mean()))
        if energy > 0:
            level *= (max(float(luma.mean()), 1e-30) / max(level, 1e-30)) ** energy
        prior = np.float32(sky_gain * level)
        share = sky[:, None]
        out[:] = share * out + (1.0 - share) * prior
    return out


def side_weight(directions, intrinsics, width: int) -> np.ndarray:
    """(T,) float32 weight of the plate's left half in the fill of each camera-frame
    direction: 1 at and beyond the plate's left edge (azimuth), 0 at and beyond its right,
    0.5 straight ahead; behind the camera it returns linearly to 0.5 (straight behind: both
    halves alike)."""
    fx, _, cx, _ = intrinsics
    left, right = math.sin(math.atan(cx / fx)), math.sin(math.atan((width - cx) / fx))
    out = np.empty(len(directions), np.float32)
    for a, b in _chunks(out.size):  # the sine of the azimuth without the trigonometry
        d = np.asarray(directions[a:b], np.float64)
        x, z = d[:, 0], d[:, 2]
        r = np.hypot(x, z)
        sin_az = np.divide(x, r, out=np.zeros_like(r), where=r > 0)
        ahead = sin_az / np.where(x >= 0, left, right)
        s = np.where(z >= 0, np.clip(ahead, -1.0, 1.0), sin_az)
        out[a:b] = 0.5 + 0.5 * s
    return out


def _chunks(count: int, size: int = 32768):
    """(start, stop) of consecutive blocks of `size` rows: per-texel work on large maps in
    blocks keeps its temporaries small (cached, not fresh memory)."""
    return ((a, min(a + size, count)) for a in range(0, count, size))


def fill_taps(directions, base: int, side=None, up=None):
    """The taps (T, 2) int32 and their weights (T, 2) float32 that interpolate the fill
    profile (rows `base` .. `base` + FILL_BINS - 1 of the source) at each direction's elevation.
    With `side` ((T,) weight of the left half, `side_weight`): (T, 4) taps, the left profile's
    two and the right profile's (rows `base` + FILL_BINS ..), weighted by side and 1 - side.
    Elevations are above the horizon whose normal is `up` (None: the camera's own)."""
    count = len(directions)
    index = np.empty((count, 2 if side is None else 4), np.int32)
    weight = np.empty(index.shape, np.float32)
    for a, b in _chunks(count):
        elevation = elevation_deg(directions[a:b], up).astype(np.float32)
        _taps_at(elevation, base, None if side is None else side[a:b], index[a:b], weight[a:b])
    return index, weight


FILL_STEPS = 64  # a lat-long's fill is read at elevations rounded to 1/64 of a bin


def fill_bins_latlong(size: int, up=None, rows=None, out=None):
    """Where the fill profile is read for the texel centres of a `size`-wide lat-long, rows
    `rows` (a slice; default all), texels row by row: (n,) uint16, the elevation in bins
    above -90 degrees times FILL_STEPS (rounded: 0.008 degrees at most), the compact form of
    `fill_taps` (whose side weight is the texel's column's). Without `up` a texel's elevation
    is its row's: then one value per row. `out`: (n,) uint16 to write into."""
    h = size // 2
    rows = range(h)[rows or slice(None)]
    el = -np.pi * ((np.arange(rows.start, rows.stop, rows.step) + 0.5) / h - 0.5)  # (n,)
    if up is None:  # one value per row
        steps = _steps(np.degrees(el).astype(np.float32))
    else:  # d . up = cos(el) (sin(az) ux + cos(az) uz) + sin(el) uy, d a unit vector
        ux, uy, uz = np.asarray(up, np.float64) / np.linalg.norm(up)
        az = -2.0 * np.pi * ((np.arange(size) + 0.5) / size - 0.5)
        across = (np.sin(az) * ux + np.cos(az) * uz).astype(np.float32)
        # A camera without roll (ux = 0) has its columns in mirrored pairs: the arcsines of
        # one half are the other's (taken only when the values agree exactly).
        half = size // 2
        mirrored = size % 2 == 0 and np.array_equal(across[:half], across[::-1][:half])
        cols = across[:half] if mirrored else across
        height = np.cos(el).astype(np.float32)[:, None] * cols
        height += np.float32(uy) * np.sin(el).astype(np.float32)[:, None]
        elevation = np.clip(height, -1.0, 1.0, out=height)
        np.arcsin(elevation, out=elevation)
        np.degrees(elevation, out=elevation)
        steps = _steps(elevation)
        if mirrored:  # the other half of the columns, mirrored
            steps = np.concatenate((steps, steps[:, ::-1]), axis=1)
    out = np.empty(steps.size, np.uint16) if out is None else out
    out[:] = steps.ravel()
    return out


def _steps(elevation: np.ndarray) -> np.ndarray:
    """float32 elevations in degrees (worked on in place) as `fill_bins_latlong`'s steps."""
    e = elevation
    e += np.float32(90.0)
    np.clip(e, 0, FILL_BINS - 1, out=e)
    e *= np.float32(FILL_STEPS)
    np.rint(e, out=e)
    return e


def fill_lookup(profile) -> np.ndarray:
    """The fill profile (sides, FILL_BINS, 3) float32 interpolated at every step of
    `fill_bins_latlong`: (sides, (FILL_BINS - 1) * FILL_STEPS + 1, 3) float32, per frame."""
    p = np.ascontiguousarray(profile, np.float32)
    sides = p.shape[0]
    out = np.empty((sides, (FILL_BINS - 1) * FILL_STEPS + 1, 3), np.float32)
    t = (np.arange(FILL_STEPS) * (1.0 / FILL_STEPS)).astype(np.float32)
    step = p[:, 1:] - p[:, :-1]  # (sides, FILL_BINS - 1, 3)
    # Steps last while computing (long inner loops), then into place.
    ramp = step[..., None] * t  # (sides, FILL_BINS - 1, 3, FILL_STEPS)
    ramp += p[:, :-1, :, None]
    out[:, :-1].reshape(sides, FILL_BINS - 1, FILL_STEPS, 3)[:] = ramp.transpose(0, 1, 3, 2)
    out[:, -1] = p[:, -1]
    return out


def fill_values(steps, side, lookup, out) -> None:
    """The fill at lat-long texels from the compact form: out (n, 3) float32 = `lookup`
    (`fill_lookup`) at each texel's steps (`fill_bins_latlong`; or one per row), the two
    sides blended by `side` ((3 W,) float32: the left side's weight per column, repeated for
    R, G, B; n a whole number of rows), or one side's (side None)."""
    if steps.size < out.shape[0]:  # one step per row: each row's colours by column
        left = np.take(lookup[0], steps, axis=0)  # (rows, 3)
        if side is None:
            out.reshape(steps.size, -1, 3)[:] = left[:, None]
            return
        right = np.take(lookup[1], steps, axis=0)
        # Rows of 3 W floats = left * side + right * (1 - side), per channel: one matrix
        # product (rows, 6) @ (6, 3 W) writes them in order (BLAS, in pieces over the cores).
        mix = np.zeros((6, side.size), np.float32)
        for c in range(3):
            mix[c, c::3] = side[c::3]
            mix[3 + c, c::3] = 1 - side[c::3]
        matmul(np.concatenate((left, right), axis=1), mix, out.reshape(steps.size, -1))
        return
    if side is None:
        np.take(lookup[0], steps, axis=0, out=out)
        return
    np.take(lookup[1], steps, axis=0, out=out)
    left = np.take(lookup[0], steps, axis=0)
    left -= out
    flat = left.reshape(-1, side.size)  # rows of 3 W floats: long inner loops
    flat *= side
    out += left


def _taps_at(elevation, base, side, index, weight) -> None:
    """Write the fill's taps and weights (see `fill_taps`) for (n,) float32 elevations in
    degrees into index (n, 2 or 4) int32 and weight (n, 2 or 4) float32."""
    e = np.clip(elevation + np.float32(90.0), 0, FILL_BINS - 1)
    b0 = np.minimum(np.floor(e), FILL_BINS - 2)
    frac = e - b0
    first = base + b0.astype(np.int32)
    index[:, 0], index[:, 1] = first, first + 1
    if side is None:
        weight[:, 0], weight[:, 1] = 1 - frac, frac
        return
    # Column by column: NumPy is slow on (n, 2) slices (its inner loop is 2 long).
    index[:, 2], index[:, 3] = first + FILL_BINS, first + (FILL_BINS + 1)
    side = np.asarray(side, np.float32)
    other = 1 - side
    low = 1 - frac
    np.multiply(low, side, out=weight[:, 0])
    np.multiply(frac, side, out=weight[:, 1])
    np.multiply(low, other, out=weight[:, 2])
    np.multiply(frac, other, out=weight[:, 3])
