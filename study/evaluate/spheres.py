"""Probe spheres rendered from a lat-long map: mirror, matte silver and diffuse (pure NumPy).

These are the renders the lighting-estimation literature compares (DiffusionLight, StyleLight):
a perfect mirror, a glossy "matte silver" sphere and a white Lambertian sphere, each lit only by
the distant environment in the map (no self-shadowing, no inter-reflection).

Frames (docs/conventions.md):

- Maps are lat-long in the **camera frame** (+Z the viewing direction, +Y up, +X the plate's
  left): pixel centre `(x + 0.5, y + 0.5)` of a W x H map (W = 2H) has
  `lat = -pi ((y + 0.5) / H - 0.5)`, `lon = -2pi ((x + 0.5) / W - 0.5)`, direction
  `(sin lon cos lat, sin lat, cos lon cos lat)`.
- A sphere image is S x S, origin top-left, y down. It is seen by an orthographic camera looking
  along the sphere frame's +Z; the image point `(u, v)` (u = +1 at the image's *left* edge, as
  +X is the plate's left; v = +1 at the top) has the normal `n = (u, v, -sqrt(1 - u^2 - v^2))`
  (facing the camera), and a mirror there reflects the view direction `(0, 0, 1)` into
  `r = d - 2 (d.n) n`. So the sphere's centre reflects what is behind the camera and its rim
  what is behind the sphere; what is left in the map shows on the sphere's left.
- `view`: a `(3, 3)` rotation whose columns are the sphere frame's axes in the camera frame
  (`object_view` builds it for an object seen in a given direction); `None` is the identity,
  the sphere at the plate's centre.

Colour: every map and render here is scene-linear Rec.709 float32; background pixels are 0.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..panorama import bilinear_wrap

SPHERE_SIZE = 128
GLOSSY_EXPONENT = 32.0  # Phong lobe cos^32 (about 10 deg wide): GGX roughness ~0.5, "matte silver"
PREFILTER_WIDTH = 128  # lat-long grid (128 x 64, 2.8 deg) on which lobes are convolved;
# 256 changes a matte-silver render by < 0.7 % (54 dB)

# Ramamoorthi & Hanrahan (2001): the cosine lobe's SH coefficients per band, A_0..A_2.
_SH_BAND = np.array([math.pi] + [2.0 * math.pi / 3.0] * 3 + [math.pi / 4.0] * 5)


# --- lat-long geometry and sampling --------------------------------------------------------------


def latlong_directions(width: int) -> np.ndarray:
    """Unit camera-frame directions `(W/2, W, 3)` float64 of a W-wide lat-long's texel centres."""
    height = width // 2
    lat = -math.pi * ((np.arange(height) + 0.5) / height - 0.5)
    lon = -2.0 * math.pi * ((np.arange(width) + 0.5) / width - 0.5)
    c = np.cos(lat)[:, None]
    return np.stack(
        [
            np.sin(lon)[None, :] * c,
            np.broadcast_to(np.sin(lat)[:, None], (height, width)),
            np.cos(lon)[None, :] * c,
        ],
        axis=-1,
    )


def row_solid_angles(height: int) -> np.ndarray:
    """Exact solid angle `(H,)` float64 of one texel in each row of an H-row lat-long map
    (its width is 2H): `(2 pi / W) (sin(lat_top) - sin(lat_bottom))`; they sum to 4 pi."""
    edges = math.pi * (0.5 - np.arange(height + 1) / height)  # latitude of row boundaries
    return (math.pi / height) * (np.sin(edges[:-1]) - np.sin(edges[1:]))


def sample_latlong(latlong: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear samples `(..., C)` float32 of a camera-frame lat-long along `(..., 3)` directions.

    Horizontal wrap (the seam behind the camera is continuous); rows clamp at the poles.
    """
    latlong = np.asarray(latlong, dtype=np.float32)
    height, width = latlong.shape[:2]
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    lat = np.arcsin(np.clip(d[..., 1], -1.0, 1.0))
    lon = np.arctan2(d[..., 0], d[..., 2])
    x = (0.5 - lon / (2.0 * math.pi)) * width - 0.5  # texel-index units: texel i centred on i
    y = (0.5 - lat / math.pi) * height - 0.5
    return bilinear_wrap(latlong, x, y)


def resample_latlong(latlong: np.ndarray, width: int) -> np.ndarray:
    """A lat-long `(h, w, C)` brought to width `width` `(width/2, width, C)` float32.

    Down by an integer factor: each texel is the solid-angle-weighted mean of the texels it
    covers (no aliasing); otherwise (up, or a fractional factor): bilinear samples at the new
    texel centres.
    """
    latlong = np.asarray(latlong, dtype=np.float32)
    h, w = latlong.shape[:2]
    if w == width:
        return latlong
    k = w // width
    if w > width and w == k * width and h == k * (width // 2):
        weight = row_solid_angles(h).astype(np.float32)
        blocks = (latlong * weight[:, None, None]).reshape(width // 2, k, width, k, -1)
        total = blocks.sum(axis=(1, 3))
        norm = weight.reshape(width // 2, k).sum(axis=1) * k
        return (total / norm[:, None, None]).astype(np.float32)
    return sample_latlong(latlong, latlong_directions(width))


# --- spherical harmonics (Ramamoorthi & Hanrahan 2001) -------------------------------------------


def sh9_basis(directions: np.ndarray) -> np.ndarray:
    """The nine real SH basis functions (bands 0-2) `(..., 9)` float64 at unit directions.

    Order: Y00; Y1-1 (y), Y10 (z), Y11 (x); Y2-2 (xy), Y2-1 (yz), Y20 (3z^2 - 1), Y21 (xz),
    Y22 (x^2 - y^2). Any orthonormal frame works (irradiance is rotation-covariant); we use the
    camera frame.
    """
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack(
        [
            np.full_like(x, 0.282095),
            0.488603 * y,
            0.488603 * z,
            0.488603 * x,
            1.092548 * x * y,
            1.092548 * y * z,
            0.315392 * (3.0 * z * z - 1.0),
            1.092548 * x * z,
            0.546274 * (x * x - y * y),
        ],
        axis=-1,
    )


@functools.lru_cache(maxsize=8)
def _sh9_weights(width: int) -> np.ndarray:
    """`(W/2 * W, 9)` float64: basis times texel solid angle, for projecting a W-wide map."""
    height = width // 2
    basis = sh9_basis(latlong_directions(width))
    return (basis * row_solid_angles(height)[:, None, None]).reshape(height * width, 9)


def sh9_coefficients(latlong: np.ndarray) -> np.ndarray:
    """Project a lat-long `(H, W, 3)` radiance map onto 9 SH coefficients `(9, 3)` float64
    (exact texel solid angles)."""
    latlong = np.asarray(latlong, dtype=np.float64)
    height, width = latlong.shape[:2]
    return _sh9_weights(width).T @ latlong.reshape(height * width, -1)


def sh9_irradiance(coefficients: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance `(..., 3)` at unit normals from 9 radiance SH coefficients `(9, 3)`:
    `E(n) = sum_lm A_l L_lm Y_lm(n)` (Ramamoorthi & Hanrahan 2001). A white Lambertian
    surface then has radiance `E / pi`."""
    return sh9_basis(normals) @ (np.asarray(coefficients) * _SH_BAND[:, None])


# --- pre-filtered maps: a rotationally symmetric lobe, convolved along longitude by FFT -----------


@functools.lru_cache(maxsize=8)
def _lobe_spectrum(width: int, exponent: float) -> np.ndarray:
    """`(W/2 + 1, H, H)` float64: per longitude frequency, the lobe's kernel from input row j to
    output row i, already weighted by the input texels' solid angles and normalised so a
    constant map stays constant. The lobe is `max(0, cos g)^exponent` of the angle g between the
    output direction and the incoming one; on a lat-long it depends only on the two rows and the
    longitude difference, so it is a circular convolution along each row."""
    height = width // 2
    lat = math.pi * (0.5 - (np.arange(height) + 0.5) / height)
    dlon = 2.0 * math.pi * np.arange(width) / width
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    cos_g = (
        sin_lat[:, None, None] * sin_lat[None, :, None]
        + cos_lat[:, None, None] * cos_lat[None, :, None] * np.cos(dlon)[None, None, :]
    )
    kernel = np.maximum(cos_g, 0.0) ** exponent * row_solid_angles(height)[None, :, None]
    kernel /= kernel.sum(axis=(1, 2), keepdims=True)
    # The kernel is real and even in the longitude difference, so its spectrum is real.
    return np.ascontiguousarray(np.fft.rfft(kernel, axis=2).real.transpose(2, 0, 1))


def prefilter(latlong: np.ndarray, exponent: float, width: int = PREFILTER_WIDTH) -> np.ndarray:
    """Pre-filtered map `(width/2, width, 3)` float32: each texel the normalised integral of the
    input radiance times the lobe `max(0, cos g)^exponent` around the texel's direction.

    exponent = 1 gives `E / pi`, the radiance of a white Lambertian surface with that normal
    (the exact irradiance, not its SH9 approximation); a large exponent a Phong glossy lobe
    around the mirror direction. The input is first brought to `width` (see `resample_latlong`).
    """
    grid = resample_latlong(latlong, width).astype(np.float64)
    spectrum = np.fft.rfft(grid, axis=1)  # (H, W/2 + 1, 3)
    kernel = _lobe_spectrum(width, float(exponent))  # (W/2 + 1, H, H)
    out = np.empty_like(spectrum)
    # per frequency m: out[:, m] = K_m @ in[:, m]; one batched matmul for real and imaginary parts
    per_m = spectrum.transpose(1, 0, 2)  # (M, H, 3)
    out_m = np.matmul(kernel, per_m.real) + 1j * np.matmul(kernel, per_m.imag)
    out = out_m.transpose(1, 0, 2)
    return np.fft.irfft(out, n=width, axis=1).astype(np.float32)


# --- sphere geometry -------------------------------------------------------------------------


def object_view(direction) -> np.ndarray:
    """The sphere frame `(3, 3)` for an object seen along camera-frame `direction`: columns are
    the frame's left (+X), up (+Y) and forward (+Z) axes; forward is `direction`, up is the
    camera's +Y made orthogonal to it. The identity for the plate's centre."""
    f = np.asarray(direction, dtype=np.float64)
    f = f / np.linalg.norm(f)
    up = np.array([0.0, 1.0, 0.0]) - f[1] * f
    up /= np.linalg.norm(up)
    left = np.cross(up, f)
    return np.stack([left, up, f], axis=1)


@functools.lru_cache(maxsize=16)
def _sphere_geometry(size: int, supersample: int):
    """Normals `(size, size, s*s, 3)` in the sphere frame and a coverage mask of the samples."""
    steps = (np.arange(supersample) + 0.5) / supersample
    p = (np.arange(size)[:, None] + steps[None, :]).reshape(-1)  # sample positions along an axis
    u = -(p - 0.5 * size) / (0.5 * size)  # +1 at the image's left: +X is the plate's left
    v = -(p - 0.5 * size) / (0.5 * size)  # +1 at the top
    uu, vv = np.meshgrid(u, v)  # (S*s, S*s): rows follow v, columns u
    r2 = uu * uu + vv * vv
    inside = r2 < 1.0
    nz = -np.sqrt(np.maximum(1.0 - r2, 0.0))
    normals = np.stack([uu, vv, nz], axis=-1)
    n = supersample
    normals = (
        normals.reshape(size, n, size, n, 3).transpose(0, 2, 1, 3, 4).reshape(size, size, n * n, 3)
    )
    inside = inside.reshape(size, n, size, n).transpose(0, 2, 1, 3).reshape(size, size, n * n)
    return normals, inside


def sphere_mask(size: int = SPHERE_SIZE) -> np.ndarray:
    """`(size, size)` bool: pixels whose centre lies on the sphere (where metrics are taken)."""
    normals, inside = _sphere_geometry(size, 1)
    return inside[..., 0]


def sphere_normals(size: int = SPHERE_SIZE, view=None) -> np.ndarray:
    """Camera-frame normals `(size, size, 3)` float64 at pixel centres (zero off the sphere)."""
    normals, inside = _sphere_geometry(size, 1)
    n = normals[..., 0, :]
    if view is not None:
        n = n @ np.asarray(view, dtype=np.float64).T
    return np.where(inside[..., 0, None], n, 0.0)


def reflect_view(normals: np.ndarray) -> np.ndarray:
    """Mirror directions `(..., 3)` of the sphere frame's view direction (0, 0, 1) about normals
    in that frame: `r = d - 2 (d.n) n`."""
    d = np.array([0.0, 0.0, 1.0])
    return d - 2.0 * normals[..., 2:3] * normals


def _shade(fn, size, supersample, view, reflect):
    """Average `fn(camera-frame directions)` over each pixel's samples on the sphere."""
    normals, inside = _sphere_geometry(size, supersample)
    dirs = reflect_view(normals) if reflect else normals
    if view is not None:
        dirs = dirs @ np.asarray(view, dtype=np.float64).T
    values = fn(dirs[inside])
    out = np.zeros(inside.shape + (values.shape[-1],), np.float32)
    out[inside] = values
    count = inside.sum(axis=-1)
    return (out.sum(axis=2) / np.maximum(count, 1)[..., None]).astype(np.float32)


# --- the three spheres -----------------------------------------------------------------------


def bilinear_taps(directions: np.ndarray, width: int):
    """The bilinear lookup of `sample_latlong` for a W-wide lat-long, precomputed: flat texel
    indices `(..., 4)` int64 and weights `(..., 4)` float32, so sampling many maps of the same
    size along the same directions is one gather."""
    height = width // 2
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    lat = np.arcsin(np.clip(d[..., 1], -1.0, 1.0))
    lon = np.arctan2(d[..., 0], d[..., 2])
    x = (0.5 - lon / (2.0 * math.pi)) * width - 0.5
    y = (0.5 - lat / math.pi) * height - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb = np.mod(x0, width), np.mod(x0 + 1, width)
    ya, yb = np.clip(y0, 0, height - 1), np.clip(y0 + 1, 0, height - 1)
    index = np.stack([ya * width + xa, ya * width + xb, yb * width + xa, yb * width + xb], -1)
    weight = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], -1)
    return index, weight.astype(np.float32)


class Probe:
    """The three spheres of one view, precomputed so each new map costs a gather or two.

    size: the image's side S in pixels; view: the sphere frame (see `object_view`), or None.
    `render(latlong)` -> (mirror, glossy, diffuse), each `(S, S, 3)` float32 linear, identical to
    `mirror_sphere`, `glossy_sphere` and `diffuse_sphere` (up to float rounding).
    """

    def __init__(self, size: int = SPHERE_SIZE, view=None, mirror_samples: int = 3):
        self.size = size
        self.view = None if view is None else np.asarray(view, dtype=np.float64)
        self.mask = sphere_mask(size)
        self._taps = {}  # (kind, map width) -> (index, weight) per pixel
        self._mirror_samples = mirror_samples
        normals, inside = _sphere_geometry(size, 2)
        n = self._to_camera(normals)
        count = np.maximum(inside.sum(axis=-1, keepdims=True), 1)
        basis = sh9_basis(n) * (inside / count)[..., None]  # mean basis over a pixel's samples
        self._diffuse = basis.sum(axis=2).reshape(size * size, 9) * (_SH_BAND / math.pi)

    def _to_camera(self, dirs):
        return dirs if self.view is None else dirs @ self.view.T

    def _lookup(self, kind: str, width: int):
        key = (kind, width)
        if key not in self._taps:
            samples = self._mirror_samples if kind == "mirror" else 2
            normals, inside = _sphere_geometry(self.size, samples)
            index, weight = bilinear_taps(self._to_camera(reflect_view(normals)), width)
            count = np.maximum(inside.sum(axis=-1, keepdims=True), 1)
            weight = weight * (inside / count)[..., None].astype(np.float32)
            s = self.size
            self._taps[key] = (index.reshape(s * s, -1), weight.reshape(s * s, -1))
        return self._taps[key]

    def _gather(self, kind, latlong):
        latlong = np.asarray(latlong, dtype=np.float32)
        index, weight = self._lookup(kind, latlong.shape[1])
        planes = np.ascontiguousarray(np.moveaxis(latlong, 2, 0)).reshape(latlong.shape[2], -1)
        out = np.stack([(np.take(plane, index) * weight).sum(axis=1) for plane in planes], -1)
        return out.reshape(self.size, self.size, -1)

    def mirror(self, latlong):
        return self._gather("mirror", latlong)

    def glossy(self, latlong=None, prefiltered=None):
        if prefiltered is None:
            prefiltered = prefilter(latlong, GLOSSY_EXPONENT)
        return self._gather("glossy", prefiltered)

    def diffuse(self, latlong=None, coefficients=None):
        sh = sh9_coefficients(latlong) if coefficients is None else coefficients
        out = (self._diffuse @ sh).astype(np.float32)
        return out.reshape(self.size, self.size, -1)

    def render(self, latlong):
        return self.mirror(latlong), self.glossy(latlong), self.diffuse(latlong)


def mirror_sphere(latlong, size: int = SPHERE_SIZE, supersample: int = 3, view=None):
    """A perfect mirror sphere `(size, size, 3)` float32, each pixel the mean of
    `supersample^2` reflected samples (bilinear on the map) over its part of the sphere."""
    return _shade(lambda d: sample_latlong(latlong, d), size, supersample, view, reflect=True)


def glossy_sphere(
    latlong, size: int = SPHERE_SIZE, exponent: float = GLOSSY_EXPONENT, view=None, prefiltered=None
):
    """A matte-silver sphere `(size, size, 3)` float32: the map pre-filtered with a normalised
    Phong lobe `cos^exponent` (see `prefilter`), looked up in the mirror direction (Fresnel and
    the cosine term left out, as in pre-filtered environment lighting). `prefiltered` may pass a
    map already filtered with this lobe."""
    glossy = prefilter(latlong, exponent) if prefiltered is None else prefiltered
    return _shade(lambda d: sample_latlong(glossy, d), size, 2, view, reflect=True)


def diffuse_sphere(latlong=None, size: int = SPHERE_SIZE, view=None, coefficients=None):
    """A white Lambertian sphere `(size, size, 3)` float32 lit by 9 SH coefficients of the map
    (Ramamoorthi & Hanrahan): radiance `E(n) / pi`. `coefficients` `(9, 3)` may replace the map."""
    sh = sh9_coefficients(latlong) if coefficients is None else coefficients
    return _shade(lambda n: sh9_irradiance(sh, n) / math.pi, size, 2, view, reflect=False)


def diffuse_sphere_exact(latlong, size: int = SPHERE_SIZE, view=None, irradiance=None):
    """A white Lambertian sphere from the exact cosine convolution of the map (no SH);
    `irradiance` may pass `prefilter(latlong, 1.0)` already computed."""
    irradiance = prefilter(latlong, 1.0) if irradiance is None else irradiance
    return _shade(lambda n: sample_latlong(irradiance, n), size, 2, view, reflect=False)
