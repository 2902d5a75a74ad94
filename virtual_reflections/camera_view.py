"""The camera-view method (the add-on's Camera View): use the plate camera's field of view
(which Blender knows).

The paper (§3.1) ignores the camera: it stretches region X over the whole back face, so what
lies behind the object lands roughly, not where it really is. With the horizontal field of
view the plate is a pinhole image (docs/conventions.md):

    f = (W / 2) / tan(hfov / 2);  direction d (z > 0) is seen at
    px = W/2 - f d.x / d.z,  py = H/2 - f d.y / d.z      (continuous plate coordinates)

so every direction the plate sees is placed exactly. Three kinds of texel:

- **seen** (the texel's centre projects into the plate): the mean of n x n bilinear samples of
  the plate over the texel's footprint (seen_texels.py);
- **near** (unseen, less than `extend_fade` degrees from the plate's view): the direction is
  clamped, in azimuth and elevation, onto the plate's view, and the plate is read there through a
  blur that grows with the angle between the direction and its clamped twin — sky continues
  from the top band, ground from the bottom band, the sides from the side bands; the blur is
  capped at a share of the plate height (extension.py). With the angle this extension fades (a
  smoothstep, `fade_weight`) into
- **the fill**: a robust average of the plate by elevation and side (fill.py).

This module holds the geometry they share: the pinhole, the clamp onto the plate's view, the
texels near it and the fade.

Fade and fill are defined in angles, not texels, so the map's width does not change them.
"""

from __future__ import annotations

import math

import numpy as np


def intrinsics_from_hfov(width: int, height: int, hfov_deg: float):
    """The intrinsics of a centred pinhole with square pixels and a horizontal field of view.

    Parameters
    ----------
    width, height : int
        The plate's size in pixels.
    hfov_deg : float
        The horizontal field of view in degrees (0..180).

    Returns
    -------
    tuple of 4 floats
        (fx, fy, cx, cy) in plate pixels (origin top-left, y down; docs/conventions.md).
    """
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return f, f, width / 2.0, height / 2.0


def camera_intrinsics(width: int, height: int, hfov_deg: float | None = None, intrinsics=None):
    """The plate camera's intrinsics: those given, else a centred pinhole of `hfov_deg`.

    Parameters
    ----------
    width, height : int
        The plate's size in pixels.
    hfov_deg : float, optional
        The horizontal field of view in degrees, used without `intrinsics`.
    intrinsics : (fx, fy, cx, cy), optional
        The camera in plate pixels (a shifted lens, non-square pixels); overrides `hfov_deg`.

    Returns
    -------
    tuple of 4 floats
        (fx, fy, cx, cy) in plate pixels.
    """
    return intrinsics or intrinsics_from_hfov(width, height, hfov_deg)


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
    intrinsics = camera_intrinsics(width, height, hfov_deg, intrinsics)
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
