"""The methods compared: baselines, the paper's method at several n, and the engine's own.

Every method has one signature, the one `study.methods.METHODS` uses:

    method(plate_linear, bbox, hfov_deg, width) -> (width/2, width, 3) float32 lat-long

`plate_linear` is `(H, W, 3)` float32 scene-linear Rec.709; `bbox` = (x0, y0, x1, y1) in plate
pixels (origin top-left, y down, x1/y1 exclusive); the map is in the camera frame
(docs/conventions.md: +Z the plate's centre, +Y up, +X the plate's left).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from virtual_reflections.envmap import environment_map
from virtual_reflections.layouts import texel_directions
from virtual_reflections.params import Params

from .. import methods as engine_configurations
from ..panorama import focal_length_pixels
from .spheres import prefilter, resample_latlong

MIDDLE_GREY = 0.18  # scene-linear
AGUSANTO_EXPONENT = 8.0  # Phong cos^8, about 20 deg wide: a heavily blurred, pre-filtered map
PAPER_TRIANGLES = (4, 8, 32, 128, 256, 0)  # 0 = the continuous limit


@dataclass(frozen=True)
class Method:
    """A map builder under test.

    name:   the label in tables and charts (unique).
    family: "baseline", "paper", "engine" (registered in `study.methods`) or
            "reference" (not a product candidate: shows what a target needs).
    fn:     `fn(plate_linear, bbox, hfov_deg, width) -> (width/2, width, 3)` float32.
    """

    name: str
    family: str
    fn: Callable


def constant_grey(plate, bbox, hfov_deg, width):
    """Middle grey (0.18 linear) everywhere: what a material with no environment sees."""
    return np.full((width // 2, width, 3), MIDDLE_GREY, np.float32)


def plate_mean(plate, bbox, hfov_deg, width):
    """The plate's mean colour everywhere (a flat, correctly exposed, correctly tinted map)."""
    mean = np.asarray(plate, np.float64).reshape(-1, 3).mean(axis=0)
    return np.broadcast_to(mean.astype(np.float32), (width // 2, width, 3)).copy()


def stretched_plate(plate, bbox, hfov_deg, width):
    """The plate resized to the whole lat-long, as if it were an HDRI (what artists do today):
    its centre on the view direction, its top row on the zenith, its left and right edges meeting
    behind the camera. Resized with OpenImageIO's default filter (area-correct)."""
    import OpenImageIO as oiio

    src = oiio.ImageBuf(np.ascontiguousarray(plate, dtype=np.float32))
    out = oiio.ImageBufAlgo.resize(src, roi=oiio.ROI(0, width, 0, width // 2, 0, 1, 0, 3))
    return np.asarray(out.get_pixels(oiio.FLOAT), np.float32).reshape(width // 2, width, 3)


def paper(triangles: int) -> Callable:
    """The paper's method (Ropinski et al. 2004) with n = `triangles` (0: continuous limit)."""

    def build(plate, bbox, hfov_deg, width):
        return environment_map(plate, bbox, Params(triangles=triangles), "latlong", width)

    return build


def agusanto(plate, bbox, hfov_deg, width):
    """A blurred pre-filtered map in the manner of Agusanto et al. 2003: the paper's
    (continuous) map convolved with a wide Phong lobe `cos^8`, as a glossy pre-filtered map."""
    sharp = environment_map(plate, bbox, Params(), "latlong", width)
    return resample_latlong(prefilter(sharp, AGUSANTO_EXPONENT, min(width, 128)), width)


REFERENCE_SAMPLES = 4  # n x n plate samples per texel: a box filter over the texel's footprint


@functools.lru_cache(maxsize=8)
def _plate_taps(plate_w: int, plate_h: int, hfov_deg: float, width: int):
    """For the texels of a W-wide lat-long the plate sees (their centre projects inside it):
    the flat texel indices and, per texel, n x n plate positions over its footprint."""
    f = focal_length_pixels(plate_w, hfov_deg)
    n = REFERENCE_SAMPLES
    centre = texel_directions("latlong", width)
    z = centre[..., 2]
    zs = np.where(z > 1e-6, z, 1.0)
    px = 0.5 * plate_w - f * centre[..., 0] / zs
    py = 0.5 * plate_h - f * centre[..., 1] / zs
    seen = (z > 1e-6) & (px >= 0) & (px <= plate_w) & (py >= 0) & (py <= plate_h)
    index = np.flatnonzero(seen)
    xs, ys = [], []
    for sy in range(n):
        for sx in range(n):
            d = texel_directions("latlong", width, ((sx + 0.5) / n - 0.5, (sy + 0.5) / n - 0.5))
            d = d.reshape(-1, 3)[index]
            xs.append(0.5 * plate_w - f * d[:, 0] / d[:, 2])
            ys.append(0.5 * plate_h - f * d[:, 1] / d[:, 2])
    return index, np.stack(xs, -1), np.stack(ys, -1)


def _bilinear(plate, x, y):
    """Bilinear samples of `(H, W, 3)` at continuous pixel positions (centres at +0.5), edges
    clamped."""
    h, w = plate.shape[:2]
    x, y = np.clip(x - 0.5, 0, w - 1), np.clip(y - 0.5, 0, h - 1)
    x0, y0 = (
        np.minimum(np.floor(x).astype(np.int64), w - 2),
        np.minimum(np.floor(y).astype(np.int64), h - 2),
    )
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = plate[y0, x0] * (1 - fx) + plate[y0, x0 + 1] * fx
    bottom = plate[y0 + 1, x0] * (1 - fx) + plate[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bottom * fy


def exact_plate_mean_elsewhere(plate, bbox, hfov_deg, width):
    """A reference, not a candidate: every texel the plate sees is the box-filtered plate over
    the texel's footprint (n x n samples, exact pinhole placement by the field of view); every
    other texel is the plate's mean colour. It shows that the 40 dB target where the plate sees
    is reachable, and what a flat fill scores outside."""
    plate = np.asarray(plate, np.float32)
    out = plate_mean(plate, bbox, hfov_deg, width).reshape(-1, 3)
    index, xs, ys = _plate_taps(plate.shape[1], plate.shape[0], float(hfov_deg), width)
    out[index] = _bilinear(plate, xs, ys).mean(axis=1)
    return out.reshape(width // 2, width, 3)


def paper_name(triangles: int) -> str:
    return "paper n=inf" if triangles == 0 else f"paper n={triangles}"


BASELINES = (
    Method("grey", "baseline", constant_grey),
    Method("plate mean", "baseline", plate_mean),
    Method("stretched plate", "baseline", stretched_plate),
    Method("agusanto blur", "baseline", agusanto),
)
REFERENCES = (Method("exact plate + mean (reference)", "reference", exact_plate_mean_elsewhere),)


def engine_methods():
    """`(methods, default_name)`: the engine's configurations registered in `study.methods`
    (its `METHODS` dict, name -> callable with the signature above, each labelled
    "engine <name>") and the label of the product's default (`DEFAULT`, or None when that names
    no registered method)."""
    registered = dict(engine_configurations.METHODS)
    methods = [Method(f"engine {name}", "engine", fn) for name, fn in registered.items()]
    default = engine_configurations.DEFAULT
    return methods, (f"engine {default}" if default in registered else None)


def all_methods(triangles=PAPER_TRIANGLES):
    """`(methods, default_name)`: baselines, the paper at each n, then the engine's own."""
    engine, default = engine_methods()
    papers = tuple(Method(paper_name(n), "paper", paper(n)) for n in triangles)
    return list(BASELINES) + list(REFERENCES) + list(papers) + engine, default
