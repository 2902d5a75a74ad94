"""Map layouts and their texel directions, in the camera frame (see projection.py).

Lat-long (OpenEXR envmap LATLONG, ImfEnvmap's LatLongMap), W x H with W = 2H, top row first:
    latitude  = -pi  * ((y + 0.5) / H - 0.5)      (+pi/2 at the top)
    longitude = -2pi * ((x + 0.5) / W - 0.5)      (+pi at the left edge)
    direction = (sin(lon) cos(lat), sin(lat), cos(lon) cos(lat))
  So the centre column looks along +Z (the plate's centre), the left half holds +X (the
  plate's left): the plate appears upright and unmirrored around the map's centre, and the
  left/right edges look back toward the camera. (ImfEnvmap scales by W-1 and H-1 so its
  first and last columns sit on the seam; we use pixel centres, as docs/conventions.md says.)

Cube (OpenEXR envmap CUBE, ImfEnvmap's CubeMap), a vertical strip of six S x S faces, top to
bottom +X, -X, +Y, -Y, +Z, -Z, each oriented as CubeMap::pixelPosition defines. Within a face,
column c and row r (top row first) give a = 2c/(S-1) - 1, b = 2r/(S-1) - 1 and
    +X: ( 1, -b,  a)    -X: (-1, -b, -a)    +Y: ( a,  1, -b)
    -Y: ( a, -1,  b)    +Z: (-a, -b,  1)    -Z: ( a, -b, -1)
  Edge texels sit exactly on the cube's edges (ImfEnvmap's convention), so neighbouring
  faces repeat the same directions there. The +Z face is the paper's back face and shows
  the plate's region X upright and unmirrored.
"""

from __future__ import annotations

import numpy as np

LAYOUTS = ("latlong", "cube")
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")


def map_shape(layout: str, size: int) -> tuple[int, int]:
    """The shape of a map.

    Parameters
    ----------
    layout : {"latlong", "cube"}
    size : int
        A lat-long's width (even, >= 2) or a cube's face size (>= 2).

    Returns
    -------
    (height, width) : tuple of 2 ints
        (size / 2, size) for a lat-long, (6 size, size) for a cube.

    Raises
    ------
    ValueError
        An unknown layout or a bad size.
    """
    if layout == "latlong":
        if size < 2 or size % 2:
            raise ValueError(f"lat-long width must be an even number >= 2, got {size}")
        return size // 2, size
    if layout == "cube":
        if size < 2:
            raise ValueError(f"cube face size must be at least 2, got {size}")
        return 6 * size, size
    raise ValueError(f"unknown layout {layout!r}; use one of {', '.join(LAYOUTS)}")


def latlong_directions(fx: np.ndarray, fy: np.ndarray, width: int, dtype=np.float64) -> np.ndarray:
    """Directions at continuous lat-long pixel positions; pixel centres at +0.5.

    For a grid, pass `fx` as a row (1, W) and `fy` as a column (H, 1): the trigonometry then
    runs on 1-D arrays.

    Parameters
    ----------
    fx, fy : array_like
        Positions in pixels, x right, y down (row 0 at the top); they broadcast together.
    width : int
        The map's width (its height is width / 2).
    dtype : dtype, optional

    Returns
    -------
    (..., 3) ndarray of `dtype`
        Unit vectors in the camera frame (docs/conventions.md).
    """
    height = width // 2
    lat = -np.pi * (np.asarray(fy, dtype=np.float64) / height - 0.5)
    lon = -2.0 * np.pi * (np.asarray(fx, dtype=np.float64) / width - 0.5)
    shape = np.broadcast_shapes(lat.shape, lon.shape)
    c = np.cos(lat)
    out = np.empty(shape + (3,), dtype=dtype)
    np.multiply(np.sin(lon), c, out=out[..., 0])
    out[..., 1] = np.sin(lat)
    np.multiply(np.cos(lon), c, out=out[..., 2])
    return out


def cube_directions(face: np.ndarray, fc: np.ndarray, fr: np.ndarray, size: int) -> np.ndarray:
    """Directions at continuous in-face positions (fc, fr) of cube faces `face` (0..5).

    Integer positions are texel centres and S-1 spans the face (ImfEnvmap). Arguments
    broadcast together; returns (..., 3) float64 on the unit cube (not normalised).
    """
    face, fc, fr = np.broadcast_arrays(face, np.asarray(fc, np.float64), fr)
    scale = 2.0 / (size - 1)
    a, b = fc * scale - 1.0, np.asarray(fr, np.float64) * scale - 1.0
    out = np.empty(a.shape + (3,))
    for f, (ix, sx, iy, sy, iz, sz) in enumerate(_FACE_AXES):
        m = face == f
        if not m.any():
            continue
        ab = (None, a[m], b[m])
        out[m] = np.stack(
            [
                s * ab[i] if i else np.full(ab[1].shape, s)
                for i, s in ((ix, sx), (iy, sy), (iz, sz))
            ],
            -1,
        )
    return out


# Per face, each direction component as (source, sign): source 1 = a, 2 = b, 0 = constant.
_FACE_AXES = (
    (0, 1, 2, -1, 1, 1),  # +X: ( 1, -b,  a)
    (0, -1, 2, -1, 1, -1),  # -X: (-1, -b, -a)
    (1, 1, 0, 1, 2, -1),  # +Y: ( a,  1, -b)
    (1, 1, 0, -1, 2, 1),  # -Y: ( a, -1,  b)
    (1, -1, 2, -1, 0, 1),  # +Z: (-a, -b,  1)
    (1, 1, 2, -1, 0, -1),  # -Z: ( a, -b, -1)
)


def texel_directions(layout: str, size: int, offset=(0.0, 0.0), dtype=np.float64) -> np.ndarray:
    """Directions through every texel of a map, shifted by some texels.

    Lat-long texel centres are at +0.5; cube texel centres at integer positions (ImfEnvmap).

    Parameters
    ----------
    layout : {"latlong", "cube"}
    size : int
        A lat-long's width or a cube's face size.
    offset : (dx, dy), optional
        The shift in texels.
    dtype : dtype, optional

    Returns
    -------
    (H, W, 3) ndarray of `dtype`
        Unit vectors in the camera frame, for the shape `map_shape(layout, size)`.
    """
    height, width = map_shape(layout, size)
    dx, dy = offset
    if layout == "latlong":
        fx = np.arange(width, dtype=np.float64)[None, :] + 0.5 + dx
        fy = np.arange(height, dtype=np.float64)[:, None] + 0.5 + dy
        return latlong_directions(fx, fy, width, dtype)
    # Faces are whole blocks of rows: fill each one by broadcasting (no per-texel face lookup).
    scale = 2.0 / (size - 1)
    a = (np.arange(width, dtype=np.float64) + dx) * scale - 1.0  # along a row
    b = (np.arange(size, dtype=np.float64) + dy) * scale - 1.0  # down a face
    ab = (None, a[None, :], b[:, None])
    out = np.empty((6, size, size, 3), dtype=dtype)
    for f, (ix, sx, iy, sy, iz, sz) in enumerate(_FACE_AXES):
        for c, (i, s) in enumerate(((ix, sx), (iy, sy), (iz, sz))):
            out[f, :, :, c] = s * ab[i] if i else s
    return out.reshape(height, width, 3)


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
