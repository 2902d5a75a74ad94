"""Reading plates and writing maps, with OpenImageIO (and the OpenEXR package for the
standard `envmap` header attribute, which OIIO's Python API cannot write).

Colour spaces are named, never inferred from OIIO's built-in config (whose `scene_linear`
role is ACEScg, not Rec.709):
- 8- and 16-bit integer files are sRGB-encoded ("sRGB" transfer, Rec.709 primaries) and are
  decoded to scene-linear Rec.709;
- half/float files (EXR, HDR, float TIFF) are already scene-linear Rec.709.
Writes are atomic: a temporary file beside the target, renamed into place when complete,
so a failure never leaves a partial output file.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass

import numpy as np

from .colour import clean_plate, decode_uint, linear_to_srgb

MAP_EXTENSIONS = (".exr", ".hdr", ".png", ".jpg", ".jpeg", ".tif", ".tiff")
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


class ImageError(ValueError):
    """A plate or map file that cannot be read or written; the message is one line."""


@dataclass(frozen=True)
class Plate:
    """A plate ready for the engine.

    pixels:    (H, W, 3) float32 scene-linear Rec.709.
    encoding:  "sRGB" (8/16-bit file, decoded) or "linear" (half/float file).
    nonfinite: how many NaN/Inf values were replaced.
    """

    pixels: np.ndarray
    encoding: str
    nonfinite: int
    path: str = ""


def _oiio():
    try:
        import OpenImageIO
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImageError("OpenImageIO is not installed (pip install OpenImageIO)") from exc
    return OpenImageIO


def read_plate(path: str) -> Plate:
    """Read an image file as a plate (see the module docstring for colour handling)."""
    oiio = _oiio()
    if not os.path.isfile(path):
        raise ImageError(f"plate not found: {path}")
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)  # alpha is ignored: keep colour as stored
    inp = oiio.ImageInput.open(path, config)
    if inp is None:
        raise ImageError(f"cannot read plate {path}: {_first_line(oiio.geterror())}")
    try:
        spec = inp.spec()
        if spec.width < 1 or spec.height < 1 or spec.nchannels < 1:
            raise ImageError(f"plate {path} is empty ({spec.width}x{spec.height})")
        integer = str(spec.format) in ("uint8", "int8", "uint16", "int16")
        fmt = "uint8" if str(spec.format) == "uint8" else "uint16" if integer else "float"
        pixels = inp.read_image(0, 0, 0, min(spec.nchannels, 4), fmt)
        if pixels is None or inp.has_error:
            raise ImageError(f"cannot read plate {path}: {_first_line(inp.geterror())}")
    finally:
        inp.close()
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, -1)
    if integer:
        linear, encoding = decode_uint(pixels[..., :3]), "sRGB"
    else:
        linear, encoding = pixels.astype(np.float32, copy=False), "linear"
    clean = clean_plate(linear)
    return Plate(clean.pixels, encoding, clean.nonfinite, path)


def _first_line(message: str) -> str:
    lines = [line for line in (message or "").splitlines() if line.strip()]
    return lines[0] if lines else "unknown error"


def check_writable(path: str) -> str:
    """Raise ImageError unless `path` has a known extension and its folder is writable."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in MAP_EXTENSIONS:
        raise ImageError(
            f"unknown output extension {ext or '(none)'!r}; use one of {', '.join(MAP_EXTENSIONS)}"
        )
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise ImageError(f"output folder does not exist: {folder}")
    if not os.access(folder, os.W_OK):
        raise ImageError(f"output folder is not writable: {folder}")
    if os.path.isdir(path):
        raise ImageError(f"output path is a folder: {path}")
    return ext


def write_map(path: str, pixels: np.ndarray, layout: str | None = None, half: bool = True) -> None:
    """Write a (H, W, 3) float32 scene-linear map (or any picture) atomically.

    .exr: scene-linear half (or float), Rec.709 chromaticities, and for maps the standard
          `envmap` attribute (LATLONG or CUBE);
    .hdr: scene-linear RGBE;
    .png/.jpg: sRGB-encoded 8-bit; .tif: sRGB-encoded 16-bit.
    """
    ext = check_writable(path)
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=".vr-", suffix=ext, dir=folder)
    except OSError as exc:
        raise ImageError(f"cannot write in {folder}: {exc.strerror}") from exc
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs get the usual permissions
        if ext == ".exr":
            _write_exr(tmp, pixels, layout, half)
        else:
            _write_oiio(tmp, pixels, ext)
        os.replace(tmp, path)
    except OSError as exc:
        os.unlink(tmp)
        raise ImageError(f"cannot write {path}: {exc.strerror}") from exc
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _write_exr(path: str, pixels: np.ndarray, layout: str | None, half: bool) -> None:
    import OpenEXR

    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        "chromaticities": REC709_CHROMATICITIES,
    }
    if layout is not None:
        header["envmap"] = {"latlong": OpenEXR.ENVMAP_LATLONG, "cube": OpenEXR.ENVMAP_CUBE}[layout]
    data = pixels.astype(np.float16) if half else pixels
    try:
        OpenEXR.File(header, {"RGB": data}).write(path)
    except Exception as exc:
        raise ImageError(f"cannot write {path}: {_first_line(str(exc))}") from exc


def _write_oiio(path: str, pixels: np.ndarray, ext: str) -> None:
    oiio = _oiio()
    h, w = pixels.shape[:2]
    if ext == ".hdr":
        data, fmt, space = pixels, "float", "lin_rec709_scene"
    else:
        encoded = linear_to_srgb(pixels)
        if ext in (".tif", ".tiff"):
            data, fmt = np.round(encoded * 65535.0).astype(np.uint16), "uint16"
        else:
            data, fmt = np.round(encoded * 255.0).astype(np.uint8), "uint8"
        space = "srgb_rec709_scene"
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise ImageError(f"cannot write {path}: {_first_line(oiio.geterror())}")
    spec = oiio.ImageSpec(w, h, pixels.shape[2], fmt)
    spec.attribute("oiio:ColorSpace", space)
    if ext in (".jpg", ".jpeg"):
        spec.attribute("Compression", "jpeg:92")
    ok = out.open(path, spec) and out.write_image(np.ascontiguousarray(data))
    ok = out.close() and ok
    if not ok:
        raise ImageError(f"cannot write {path}: {_first_line(out.geterror())}")


def read_channels(path: str) -> dict:
    """Every channel of an image file by name, every part of a multi-part EXR included:
    {name: (H, W) float32}, top row first, values as stored (renders: scene-linear)."""
    oiio = _oiio()
    if not os.path.isfile(path):
        raise ImageError(f"image not found: {path}")
    image = oiio.ImageInput.open(path)
    if image is None:
        raise ImageError(f"cannot read {path}: {_first_line(oiio.geterror())}")
    channels = {}
    try:
        part = 0
        while image.seek_subimage(part, 0):  # Blender 5.x writes one part per pass
            spec = image.spec()
            pixels = image.read_image(part, 0, 0, spec.nchannels, "float")
            if pixels is None or image.has_error:
                raise ImageError(f"cannot read {path}: {_first_line(image.geterror())}")
            pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
            for c, name in enumerate(spec.channelnames):
                channels[name] = pixels[..., c]
            part += 1
    finally:
        image.close()
    return channels


def read_rgba(path: str) -> np.ndarray:
    """(H, W, 4) float32 pixels of an image file, top row first, values as stored (an 8-bit
    file's sRGB codes / 255, an EXR's scene-linear values); alpha 1 where the file has none."""
    oiio = _oiio()
    if not os.path.isfile(path):
        raise ImageError(f"image not found: {path}")
    image = oiio.ImageInput.open(path)
    if image is None:
        raise ImageError(f"cannot read {path}: {_first_line(oiio.geterror())}")
    try:
        spec = image.spec()
        pixels = image.read_image(0, 0, 0, min(spec.nchannels, 4), "float")
        if pixels is None or image.has_error:
            raise ImageError(f"cannot read {path}: {_first_line(image.geterror())}")
    finally:
        image.close()
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, -1)
    rgba = np.ones((spec.height, spec.width, 4), np.float32)
    if pixels.shape[2] < 3:  # grey (and alpha)
        rgba[..., :3] = pixels[..., :1]
        if pixels.shape[2] == 2:
            rgba[..., 3] = pixels[..., 1]
    else:
        rgba[..., : pixels.shape[2]] = pixels
    return rgba


def write_rgba(path: str, rgba: np.ndarray) -> None:
    """Write an (H, W, 4) float32 premultiplied render as a scene-linear float RGBA EXR (ZIP)."""
    oiio = _oiio()
    h, w = rgba.shape[:2]
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise ImageError(f"cannot write {path}: {_first_line(oiio.geterror())}")
    spec = oiio.ImageSpec(w, h, 4, "float")
    spec.attribute("compression", "zip")
    ok = out.open(path, spec) and out.write_image(np.ascontiguousarray(rgba, np.float32))
    ok = out.close() and ok
    if not ok:
        raise ImageError(f"cannot write {path}: {_first_line(out.geterror())}")
