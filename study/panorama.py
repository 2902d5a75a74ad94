"""Panoramas and perspective plates: Blender's world lat-long <-> the product's camera frame.

Pure NumPy + OpenImageIO (never `bpy`): the sample plates, their ground-truth surroundings and
the tests are all built from Blender's bundled world HDRIs with these functions.

Frames (see docs/conventions.md):

- **Blender world**: right-handed, +Z up. Blender's Environment Texture (equirectangular) maps a
  world direction `d` as Cycles' `direction_to_equirectangular` does
  (`intern/cycles/kernel/camera/projection.h`, range `(-2pi, pi, -pi, pi)`):
  `u = 0.5 - atan2(d.y, d.x) / 2pi`, `v = 1 - acos(d.z) / pi`, with `v = 0` the *bottom* row
  (Cycles stores images bottom-up). In image pixels (origin top-left, y down, pixel centres at
  `+0.5`): `x = u * W`, `y = (1 - v) * H = acos(d.z) / pi * H`. So world +X is the centre column,
  +Y is at a quarter of the width, the zenith is the top edge.
- **Blender camera-local**: looks down -Z, +Y up, +X to the right of the render.
- **Camera frame** (the product's): looks down +Z, +Y up, +X to the plate's *left*; it is the
  Blender camera-local frame rotated 180 degrees about Y: `(x, y, z)_cam = (-x, y, -z)_local`.
- **Lat-long** (the product's, OpenEXR `LATLONG`): pixel centre `(x + 0.5, y + 0.5)` of a W x H
  (W = 2H) map has `lat = -pi ((y + 0.5) / H - 0.5)`, `lon = -2pi ((x + 0.5) / W - 0.5)` and the
  camera-frame direction `(sin(lon) cos(lat), sin(lat), cos(lon) cos(lat))`.

Colour: every image here is scene-linear Rec.709 float32 `(H, W, 3)`.
"""

from __future__ import annotations

import math

import numpy as np

from virtual_reflections.layouts import map_shape, texel_directions

__all__ = [
    "blender_equirect_direction",
    "blender_equirect_lookup",
    "blender_world_to_camera",
    "camera_frame_directions",
    "camera_rotation",
    "camera_rotation_euler",
    "camera_to_blender_world",
    "euler_xyz_to_matrix",
    "focal_length_pixels",
    "ground_truth_latlong",
    "lens_mm",
    "load_equirect",
    "perspective_plate",
    "sample_equirect",
]

# Camera frame <-> Blender camera-local: a 180 degree turn about Y flips the signs of x and z.
_CAM_TO_LOCAL = np.array([-1.0, 1.0, -1.0])


# --- Blender's equirectangular world map ----------------------------------------------------


def blender_equirect_lookup(directions_world, width, height):
    """Continuous pixel coordinates of Blender world directions in a Blender lat-long image.

    directions_world: `(..., 3)` Blender world directions (Z up), any non-zero length.
    width, height: size W x H of the equirectangular image (normally W = 2H).
    Returns `(..., 2)` float64 `(x, y)` in image pixels: origin at the top-left corner, y down,
    the centre of pixel `(i, j)` at `(i + 0.5, j + 0.5)`; x in `[0, W)`, y in `[0, H]`.
    This is Cycles' `direction_to_equirectangular` (u = 0.5 - atan2(y, x) / 2pi,
    v = 1 - acos(z) / pi, v up) turned into top-down pixel rows.
    """
    d = np.asarray(directions_world, dtype=np.float64)
    length = np.linalg.norm(d, axis=-1)
    z = np.clip(d[..., 2] / np.where(length > 0.0, length, 1.0), -1.0, 1.0)
    u = 0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2.0 * math.pi)
    x = np.mod(u * width, width)
    y = np.arccos(z) / math.pi * height
    return np.stack([x, y], axis=-1)


def blender_equirect_direction(pixel_xy, width, height):
    """Inverse of `blender_equirect_lookup`: Blender world unit directions of image positions.

    pixel_xy: `(..., 2)` continuous `(x, y)` pixel coordinates (origin top-left, y down, pixel
    centres at `+0.5`) in a W x H Blender lat-long image. Returns `(..., 3)` float64 unit
    directions in the Blender world frame (Z up).
    """
    xy = np.asarray(pixel_xy, dtype=np.float64)
    phi = math.pi - 2.0 * math.pi * xy[..., 0] / width  # atan2(d.y, d.x)
    theta = math.pi * xy[..., 1] / height  # angle from the zenith (+Z)
    sin_theta = np.sin(theta)
    return np.stack([sin_theta * np.cos(phi), sin_theta * np.sin(phi), np.cos(theta)], axis=-1)


def sample_equirect(image, directions_world):
    """Bilinear sample of a Blender lat-long image along Blender world directions.

    image: `(H, W, 3)` (or `(H, W, C)`) float32 scene-linear, Blender equirectangular convention.
    directions_world: `(..., 3)` Blender world directions (Z up).
    Returns `(..., C)` float32. Horizontal wrap (the seam is continuous); rows clamp at the
    poles. Bilinear matches the Environment Texture's default 'Linear' interpolation.
    """
    image = np.asarray(image, dtype=np.float32)
    height, width = image.shape[:2]
    xy = blender_equirect_lookup(directions_world, width, height)
    return bilinear_wrap(image, xy[..., 0] - 0.5, xy[..., 1] - 0.5)


def bilinear_wrap(image, x, y):
    """Bilinear samples `(..., C)` float32 of an `(H, W, C)` lat-long at pixel-index coordinates
    (pixel i centred on i): columns wrap (the seam is continuous), rows clamp at the poles."""
    height, width = image.shape[:2]
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0).astype(np.float32)[..., None]
    fy = (y - y0).astype(np.float32)[..., None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    xa, xb = np.mod(x0, width), np.mod(x0 + 1, width)
    ya, yb = np.clip(y0, 0, height - 1), np.clip(y0 + 1, 0, height - 1)
    top = image[ya, xa] * (1.0 - fx) + image[ya, xb] * fx
    bottom = image[yb, xa] * (1.0 - fx) + image[yb, xb] * fx
    return (top * (1.0 - fy) + bottom * fy).astype(np.float32)


def load_equirect(path):
    """Read a lat-long image (EXR/HDR) with OpenImageIO as `(H, W, 3)` float32 scene-linear.

    The file's pixels are returned as stored (no colour conversion); extra channels are dropped
    and a single channel is repeated.
    """
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise OSError(f"cannot read {path}: {buf.geterror()}")
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return np.ascontiguousarray(pixels[:, :, :3])


# --- the Blender camera -----------------------------------------------------------------------


def _rot_x(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def camera_rotation(heading_deg, pitch_deg, roll_deg=0.0):
    """World rotation `(3, 3)` float64 of a Blender camera (columns: its local axes in the world).

    The Blender camera looks down its local -Z with local +Y up. Heading 0 / pitch 0 looks along
    Blender world +Y with a level horizon; positive heading turns left (counter-clockwise seen
    from above, about world +Z); positive pitch looks up; positive roll turns the camera
    counter-clockwise about its viewing axis as seen from behind it (the picture turns clockwise).
    `R = Rz(heading) @ Rx(90 deg + pitch) @ Rz(roll)`; a camera-local direction `v` points along
    `R @ v` in the world, e.g. the forward direction is `R @ (0, 0, -1)`.
    """
    return (
        _rot_z(math.radians(heading_deg))
        @ _rot_x(math.radians(90.0 + pitch_deg))
        @ _rot_z(math.radians(roll_deg))
    )


def euler_xyz_to_matrix(euler_xyz):
    """`(3, 3)` rotation of Blender's Euler 'XYZ' mode (radians): `Rz(z) @ Ry(y) @ Rx(x)`."""
    ex, ey, ez = (float(a) for a in euler_xyz)
    return _rot_z(ez) @ _rot_y(ey) @ _rot_x(ex)


def camera_rotation_euler(heading_deg, pitch_deg, roll_deg=0.0):
    """`camera.rotation_euler` (mode 'XYZ', radians) equal to `camera_rotation(...)`.

    Returns a tuple `(x, y, z)` of floats; with no roll it is `(90 deg + pitch, 0, heading)`.
    """
    if roll_deg == 0.0:
        return (math.radians(90.0 + pitch_deg), 0.0, math.radians(heading_deg))
    r = camera_rotation(heading_deg, pitch_deg, roll_deg)
    # R = Rz(c) Ry(b) Rx(a): R[2, 0] = -sin b, R[2, 1] = cos b sin a, R[1, 0] = sin c cos b.
    cos_b = math.hypot(r[0, 0], r[1, 0])
    b = math.atan2(-r[2, 0], cos_b)
    if cos_b > 1e-9:
        a = math.atan2(r[2, 1], r[2, 2])
        c = math.atan2(r[1, 0], r[0, 0])
    else:  # looking straight up or down: only a + c (or a - c) is defined; put it all in x
        a = math.atan2(-r[1, 2], r[1, 1])
        c = 0.0
    return (a, b, c)


def focal_length_pixels(width, hfov_deg):
    """Pinhole focal length in pixels, `f = (W / 2) / tan(hfov / 2)` (horizontal sensor fit)."""
    return 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)


def lens_mm(hfov_deg, sensor_width_mm=36.0):
    """Blender `camera.data.lens` (mm) giving `hfov_deg` with `sensor_fit = 'HORIZONTAL'`."""
    return 0.5 * sensor_width_mm / math.tan(math.radians(hfov_deg) / 2.0)


def camera_frame_directions(width, height, hfov_deg, subpixel=(0.5, 0.5)):
    """Unit viewing directions `(H, W, 3)` float64 of plate pixels, in the camera frame.

    Camera frame: +Z forward (the plate's centre), +Y up, +X the plate's *left*. Plate pixels
    have their origin at the top-left, y down. With the default `subpixel=(0.5, 0.5)` each entry
    is the direction of the pixel centre `(px + 0.5, py + 0.5)`:
    `normalize(-(px + 0.5 - W/2) / f, -(py + 0.5 - H/2) / f, 1)`, `f = (W/2) / tan(hfov/2)`.
    Other `subpixel` offsets in `[0, 1)` give other points of each pixel (for supersampling).
    """
    f = focal_length_pixels(width, hfov_deg)
    px = np.arange(width, dtype=np.float64) + subpixel[0]
    py = np.arange(height, dtype=np.float64) + subpixel[1]
    x = np.broadcast_to(-(px - 0.5 * width) / f, (height, width))
    y = np.broadcast_to((-(py - 0.5 * height) / f)[:, None], (height, width))
    d = np.stack([x, y, np.ones((height, width))], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def camera_to_blender_world(dirs_cam, rotation):
    """Camera-frame directions `(..., 3)` -> Blender world directions `(..., 3)` float64.

    dirs_cam: camera frame (+Z forward, +Y up, +X the plate's left).
    rotation: `(3, 3)` world rotation of the Blender camera (`camera_rotation`, or the 3x3 part
    of `camera.matrix_world`). The camera frame is first turned 180 degrees about Y into Blender's
    camera-local frame (-Z forward, +X right), then rotated into the world.
    """
    local = np.asarray(dirs_cam, dtype=np.float64) * _CAM_TO_LOCAL
    return local @ np.asarray(rotation, dtype=np.float64).T


def blender_world_to_camera(dirs_world, rotation):
    """Inverse of `camera_to_blender_world`: Blender world `(..., 3)` -> camera frame `(..., 3)`."""
    local = np.asarray(dirs_world, dtype=np.float64) @ np.asarray(rotation, dtype=np.float64)
    return local * _CAM_TO_LOCAL


def _subpixel_offsets(supersample):
    """Stratified n x n sample positions inside a pixel: `((k + 0.5) / n, (l + 0.5) / n)`."""
    n = int(supersample)
    if n < 1:
        raise ValueError(f"supersample must be >= 1, got {supersample}")
    steps = (np.arange(n) + 0.5) / n
    return [(sx, sy) for sy in steps for sx in steps]


def perspective_plate(
    equirect, width, height, hfov_deg, heading_deg, pitch_deg, roll_deg=0.0, supersample=3
):
    """Render a pinhole plate `(height, width, 3)` float32 scene-linear from a world HDRI.

    equirect: `(H, W, 3)` float32 Blender-convention lat-long (the world's Environment Texture).
    The plate is what a Blender perspective camera at the origin with rotation
    `camera_rotation(heading_deg, pitch_deg, roll_deg)`, `sensor_fit = 'HORIZONTAL'` and
    horizontal field of view `hfov_deg` renders of that world: plate pixels with origin top-left,
    y down, pixel centres at `+0.5`.

    Filtering: each pixel is the mean of `supersample x supersample` stratified bilinear samples
    over its square (a box pixel filter). The 1024 x 512 bundled HDRIs are magnified at plate
    resolutions, so bilinear does the reconstruction and the supersampling is the antialiasing;
    with `supersample=1` a pixel is the bilinear sample at its centre. The expectation of
    Cycles with the 'BOX' pixel filter of width 1 px is exactly this box average.
    """
    rotation = camera_rotation(heading_deg, pitch_deg, roll_deg)
    total = np.zeros((height, width, 3), dtype=np.float64)
    offsets = _subpixel_offsets(supersample)
    for subpixel in offsets:  # a few whole-image passes, not a loop over pixels
        dirs = camera_to_blender_world(
            camera_frame_directions(width, height, hfov_deg, subpixel), rotation
        )
        total += sample_equirect(equirect, dirs)[..., :3]
    return (total / len(offsets)).astype(np.float32)


def ground_truth_latlong(equirect, rotation, width, supersample=2):
    """The whole surroundings of the camera as a product lat-long map `(W/2, W, 3)` float32.

    equirect: `(H, W, 3)` float32 scene-linear Blender-convention world lat-long.
    rotation: `(3, 3)` world rotation of the Blender camera (`camera_rotation`).
    width: W of the output (even); its height is W / 2.
    The output is in the camera frame's lat-long convention (docs/conventions.md, `layouts.py`):
    `lat = -pi ((y + 0.5) / H - 0.5)`, `lon = -2pi ((x + 0.5) / W - 0.5)`, direction
    `(sin(lon) cos(lat), sin(lat), cos(lon) cos(lat))`. Its centre column is the camera's
    viewing direction, so the plate appears upright and unmirrored around the centre.
    Each pixel averages `supersample x supersample` stratified bilinear samples.
    """
    total = np.zeros((*map_shape("latlong", width), 3), dtype=np.float64)
    offsets = _subpixel_offsets(supersample)
    for sx, sy in offsets:
        dirs_cam = texel_directions("latlong", width, (sx - 0.5, sy - 0.5))
        dirs = camera_to_blender_world(dirs_cam, rotation)
        total += sample_equirect(equirect, dirs)[..., :3]
    return (total / len(offsets)).astype(np.float32)
