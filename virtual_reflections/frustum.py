"""The "frustum" method: use the plate camera's field of view (which Blender knows).

The paper (§3.1) ignores the camera: it stretches region X over the whole back face, so what
lies behind the object lands roughly, not where it really is. With the horizontal field of
view the plate is a pinhole image (CONVENTIONS.md):

    f = (W / 2) / tan(hfov / 2);  direction d (z > 0) is seen at
    px = W/2 - f d.x / d.z,  py = H/2 - f d.y / d.z      (continuous plate coordinates)

so every direction the plate sees is placed exactly. Directions it does not see (more than
90 % of a mirror sphere's) are extended from the plate's nearest edge: the direction is
clamped, in azimuth and elevation, onto the frustum, and the plate is read there through a
blur that grows with the angle between the direction and its clamped twin — sky continues
from the top band, ground from the bottom band, the sides and the back from the side bands,
fading toward their local average instead of repeating misplaced detail. The blur is capped
at a share of the plate height so the sky stays sky and the ground stays ground.
"""

from __future__ import annotations

import math

import numpy as np


def intrinsics_from_hfov(width: int, height: int, hfov_deg: float):
    """(fx, fy, cx, cy) in plate pixels of a centred pinhole with square pixels."""
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return f, f, width / 2.0, height / 2.0


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
    log2 of `blur` x (angle to the frustum in radians) x fx pixels, at most
    log2(max_blur x height)). Inside the frustum the blur level is 0.
    """
    fx, fy, cx, cy = intrinsics or intrinsics_from_hfov(width, height, hfov_deg)
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
    # Angle between the direction and its clamped twin.
    cos_e = np.cos(e)
    clamped = np.stack((np.sin(a) * cos_e, np.sin(e), cos_a * cos_e), axis=-1)
    cosine = np.clip((d * clamped).sum(-1) / norm, -1.0, 1.0)
    pixels = blur * np.arccos(cosine) * fx
    cap = math.log2(max(max_blur * height, 1.0))
    lod = np.minimum(np.log2(np.maximum(pixels, 1.0)), cap)
    return position.astype(np.float32), lod.astype(np.float32)
