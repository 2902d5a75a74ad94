"""Reading plates and writing maps, with OpenImageIO alone (its EXR writer also writes the
standard `envmap` header attribute, from the spec's ``textureformat``).

Colour spaces are named, never inferred from OIIO's built-in config (whose `scene_linear`
role is ACEScg, not Rec.709):
- 8- and 16-bit integer files are sRGB-encoded ("sRGB" transfer, Rec.709 primaries) and are
  decoded to scene-linear Rec.709;
- half/float files (EXR, HDR, float TIFF) are already scene-linear Rec.709.
Writes are atomic and verified (atomic_files.py): a temporary file beside the target, read
back whole before it is renamed into place.
"""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass

import numpy as np

from .atomic_files import (
    ImageError,
    WriteError,
    check_space,
    commit,
    first_line,
    openimageio,
    quiet_stderr,
    remove_stale_temps,
    temp_path,
)
from .colour import clean_plate, decode_uint, linear_to_srgb

MAP_EXTENSIONS = (".exr", ".hdr", ".png", ".jpg", ".jpeg", ".tif", ".tiff")


REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


_MID_RUN = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}  # not the input's fault


HALF_MAX = 65504.0  # the largest finite half float


def check_complete(path: str, what: str = "image") -> tuple[int, int]:
    """Read an image file whole, to know it is not truncated or damaged.

    Parameters
    ----------
    path : str
    what : str, optional
        What the file is, for the message ("plate", "map").

    Returns
    -------
    (width, height) : tuple of 2 ints
        For an EXR, its display window.

    Raises
    ------
    ImageError
        One line: the file cannot be read whole.
    """
    oiio = openimageio()
    with quiet_stderr():
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise ImageError(f"cannot read {what} {path}: {first_line(oiio.geterror())}")
        try:
            spec = inp.spec()
            pixels = inp.read_image(0, 0, 0, spec.nchannels, "uint8")
            if pixels is None or inp.has_error:
                raise ImageError(f"cannot read {what} {path} whole: {first_line(inp.geterror())}")
            return _header(spec, path).width, _header(spec, path).height
        finally:
            inp.close()
            oiio.geterror()


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


@dataclass(frozen=True)
class PlateHeader:
    """What a plate file's header says, without reading its pixels.

    Attributes
    ----------
    width, height : int
        The display window: the picture's frame, what the plate is.
    data : (x, y, width, height)
        The pixels stored, relative to the display window.
    channels : tuple of str
        The channel names.
    integer : bool
        8/16-bit (sRGB-encoded) rather than half/float.
    colour : tuple of 3 ints or None
        The indices of the channels read as R, G, B (`colour_channels`); None: the first
        channels (grey or unnamed).
    """

    width: int
    height: int
    data: tuple
    channels: tuple
    integer: bool
    colour: tuple | None = None

    @property
    def bytes_per_copy(self) -> int:
        """Bytes of one float32 RGB copy of the plate."""
        return self.width * self.height * 3 * 4

    @property
    def stored_pixels(self) -> int:
        """Pixels the file stores (its data window), which a read holds before the plate is
        cut to the display window."""
        return self.data[2] * self.data[3]

    @property
    def stored_note(self) -> str:
        """For a message: the data window, when the file stores more pixels than the plate."""
        if self.stored_pixels <= self.width * self.height:
            return ""
        return f" (its data window: {self.data[2]}x{self.data[3]})"

    @property
    def layers(self) -> tuple:
        """The layers of an EXR's channel names (``diffuse`` of ``diffuse.R``), in order."""
        return tuple(dict.fromkeys(n.rpartition(".")[0] for n in self.channels if "." in n))


_COLOUR = {"R", "G", "B", "Y", "r", "g", "b", "y", "red", "green", "blue"}
_RGB = {"r": 0, "red": 0, "g": 1, "green": 1, "b": 2, "blue": 2}


def colour_channels(names, path: str) -> tuple | None:
    """The indices of the R, G, B channels among an EXR's channel ``names``: the one layer
    (``diffuse`` of ``diffuse.R``, or the unnamed layer) that has all three; of several, the
    unnamed one. None when no layer has all three (a grey or unnamed picture: its first
    channels). ImageError (one line) for several named colour layers and no unnamed one."""
    layers = {}
    for i, name in enumerate(names):
        layer, _, channel = name.rpartition(".")
        if channel.lower() in _RGB:
            layers.setdefault(layer, {}).setdefault(_RGB[channel.lower()], i)
    found = {layer: (c[0], c[1], c[2]) for layer, c in layers.items() if len(c) == 3}
    if len(found) > 1 and "" not in found:
        first = next(iter(found.values()))
        raise ImageError(
            f"plate {path} has several colour layers ({', '.join(found)}): save the one to use "
            f"as a plain R, G, B file first (e.g. {plain_rgb_command(path, names, first)})"
        )
    if not found:
        return None
    return found[""] if "" in found else next(iter(found.values()))


def plain_rgb_command(path: str, names, colour) -> str:
    """The oiiotool command that saves some channels of a file as a plain R, G, B file.

    Parameters
    ----------
    path : str
    names : sequence of str
        The file's channel names.
    colour : sequence of 3 ints or None
        Indices into `names` of R, G and B; None: a LAYER for the user to name.

    Returns
    -------
    str
    """
    r, g, b = ("LAYER.R", "LAYER.G", "LAYER.B") if colour is None else (names[i] for i in colour)
    return f"oiiotool {path} --ch R={r},G={g},B={b} -o OUT.exr"


def read_header(path: str) -> PlateHeader:
    """The header of a plate file.

    Parameters
    ----------
    path : str

    Returns
    -------
    PlateHeader

    Raises
    ------
    ImageError
        One line: a missing, unreadable, empty, deep or colourless (depth-only) file, or one
        with several colour layers.
    """
    oiio = openimageio()
    if os.path.isdir(path):
        raise ImageError(f"plate is a folder, not an image file: {path}")
    if not os.path.isfile(path):
        raise ImageError(f"plate not found: {path}")
    with quiet_stderr():
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise ImageError(f"cannot read plate {path}: {first_line(oiio.geterror())}")
        try:
            return _header(inp.spec(), path)
        finally:
            inp.close()


def _header(spec, path) -> PlateHeader:
    full = (spec.full_width, spec.full_height)
    if full[0] < 1 or full[1] < 1:
        full = (spec.width, spec.height)
    if spec.width < 1 or spec.height < 1 or spec.nchannels < 1 or min(full) < 1:
        raise ImageError(f"plate {path} is empty ({spec.width}x{spec.height})")
    if spec.deep:
        raise ImageError(
            f"plate {path} is a deep image (samples at many depths per pixel), not supported: "
            f"flatten it first (e.g. oiiotool {path} --flatten -o OUT.exr)"
        )
    names = tuple(spec.channelnames)
    integer = str(spec.format) in ("uint8", "int8", "uint16", "int16")
    if not integer and names and not any(n.split(".")[-1] in _COLOUR for n in names):
        raise ImageError(
            f"plate {path} has no colour channels (only {', '.join(names)}): not a picture"
        )
    data = (spec.x - spec.full_x, spec.y - spec.full_y, spec.width, spec.height)
    return PlateHeader(full[0], full[1], data, names, integer, colour_channels(names, path))


def read_plate(path: str) -> Plate:
    """Read an image file as a plate (see the module docstring for colour handling).

    The plate is the display window: an EXR whose data window is smaller or larger is placed
    in it (black where no pixels are stored, cropped where they reach outside). A file that
    cannot be read whole (truncated, damaged) is an ImageError, never a partly grey plate."""
    oiio = openimageio()
    with quiet_stderr():
        header = read_header(path)
        config = oiio.ImageSpec()
        config.attribute("oiio:UnassociatedAlpha", 1)  # alpha is ignored: keep colour as stored
        inp = oiio.ImageInput.open(path, config)
        if inp is None:
            raise ImageError(f"cannot read plate {path}: {first_line(oiio.geterror())}")
        try:
            spec = inp.spec()
            integer = header.integer
            fmt = "uint8" if str(spec.format) == "uint8" else "uint16" if integer else "float"
            first, last = _channel_span(header)
            pixels = inp.read_image(0, 0, first, last, fmt)
            if pixels is None or inp.has_error:
                raise ImageError(f"cannot read plate {path} whole: {first_line(inp.geterror())}")
        finally:
            inp.close()
            oiio.geterror()
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, -1)
    if header.colour is not None:
        pixels = pixels[..., [i - first for i in header.colour]]
    if integer:
        linear, encoding = decode_uint(pixels[..., :3]), "sRGB"
    else:
        linear, encoding = pixels.astype(np.float32, copy=False), "linear"
    linear = _display_window(linear, header)
    clean = clean_plate(linear)
    return Plate(clean.pixels, encoding, clean.nonfinite, path)


def _channel_span(header: PlateHeader) -> tuple[int, int]:
    """The channels a plate read needs, first and one past the last: the colour layer's, or
    the first four (grey, grey and alpha, RGB, RGBA)."""
    if header.colour is None:
        return 0, min(len(header.channels), 4)
    return min(header.colour), max(header.colour) + 1


def _display_window(pixels: np.ndarray, header: PlateHeader) -> np.ndarray:
    """The data window's ``pixels`` placed in the display window (black outside)."""
    x, y, w, h = header.data
    if (x, y, w, h) == (0, 0, header.width, header.height):
        return pixels
    canvas = np.zeros((header.height, header.width, pixels.shape[2]), np.float32)
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + w, header.width), min(y + h, header.height)
    if x0 < x1 and y0 < y1:
        canvas[y0:y1, x0:x1] = pixels[y0 - y : y1 - y, x0 - x : x1 - x]
    return canvas


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


def write_map(path: str, pixels: np.ndarray, layout: str | None = None, half: bool = True) -> int:
    """Write a map (or any picture) atomically, verified.

    .exr: half (or float), Rec.709 chromaticities, and for maps the standard `envmap` attribute;
    half floats are clamped to +-65504 (a sun brighter would become Inf). .hdr: RGBE. .png/.jpg:
    sRGB-encoded 8-bit; .tif: sRGB-encoded 16-bit. A previous file stays unless the new is whole.

    Parameters
    ----------
    path : str
        The file; its extension picks the format.
    pixels : (H, W, 3) float32 ndarray
        Scene-linear Rec.709.
    layout : {"latlong", "cube"} or None, optional
        Written as the EXR's `envmap` attribute (LATLONG or CUBE); None for a picture.
    half : bool, optional
        An EXR in half floats (else float).

    Returns
    -------
    int
        How many values were clamped to fit half floats (0 for other formats).

    Raises
    ------
    ImageError
        A bad file name (exit 2).
    WriteError
        The write failed (exit 1).
    """
    ext = check_writable(path)
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    h, w = pixels.shape[:2]
    clamped = 0
    if ext == ".exr" and half:
        over = ~(np.abs(pixels) <= HALF_MAX)
        clamped = int(np.count_nonzero(over))
        if clamped:
            pixels = np.nan_to_num(np.clip(pixels, -HALF_MAX, HALF_MAX), nan=0.0)
    folder = os.path.dirname(os.path.abspath(path))
    stem = os.path.splitext(os.path.basename(path))[0]
    remove_stale_temps(folder, [stem])
    if ext in (".jpg", ".jpeg"):
        # libjpeg ends the process on a write error (full disk) before anything can be done:
        # make sure the worst case fits first.
        check_space(path, w * h * pixels.shape[2] + 65536)
    tmp = temp_path(path)
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)  # the usual umask
        os.close(fd)
    except OSError as exc:
        kind = WriteError if exc.errno in _MID_RUN else ImageError
        raise kind(f"cannot write in {folder}: {exc.strerror}") from exc
    try:
        try:
            if ext == ".exr":
                _write_exr(tmp, pixels, layout, half)
            else:
                _write_oiio(tmp, pixels, ext)
        except ImageError as exc:
            raise WriteError(str(exc).replace(tmp, path)) from exc
        except OSError as exc:
            raise WriteError(f"cannot write {path}: {exc.strerror}") from exc
        commit(tmp, path, w, h)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return clamped


ENVMAP_TEXTUREFORMAT = {"latlong": "LatLong Environment", "cube": "CubeFace Environment"}


LINEAR_TAG = "lin_rec709_scene"  # OIIO/OCIO's interop name of scene-linear Rec.709


def exr_spec(width: int, height: int, channels: int, fmt: str, layout: str | None = None):
    """The OIIO ImageSpec of every EXR the engine writes: ZIP-compressed, Rec.709
    chromaticities, tagged scene-linear Rec.709 (OIIO 3.1+ writes it as the header's
    ``colorInteropID``), and for a map the standard ``envmap`` attribute (LATLONG or CUBE:
    OIIO's EXR writer sets it from ``textureformat``; no OpenEXR package needed)."""
    oiio = openimageio()
    spec = oiio.ImageSpec(width, height, channels, fmt)
    spec.attribute("compression", "zip")
    spec.attribute("chromaticities", "float[8]", REC709_CHROMATICITIES)
    spec.attribute("oiio:ColorSpace", LINEAR_TAG)
    if layout is not None:
        spec.attribute("textureformat", ENVMAP_TEXTUREFORMAT[layout])
    return spec


def _write_exr(path: str, pixels: np.ndarray, layout: str | None, half: bool) -> None:
    oiio = openimageio()
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise ImageError(f"cannot write {path}: {first_line(oiio.geterror())}")
    spec = exr_spec(w, h, c, "half" if half else "float", layout)
    ok = out.open(path, spec) and out.write_image(np.ascontiguousarray(pixels, np.float32))
    ok = out.close() and ok
    if not ok:
        raise ImageError(f"cannot write {path}: {first_line(out.geterror())}")


def _write_oiio(path: str, pixels: np.ndarray, ext: str) -> None:
    oiio = openimageio()
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
        raise ImageError(f"cannot write {path}: {first_line(oiio.geterror())}")
    spec = oiio.ImageSpec(w, h, pixels.shape[2], fmt)
    spec.attribute("oiio:ColorSpace", space)
    if ext in (".jpg", ".jpeg"):
        spec.attribute("Compression", "jpeg:92")
    ok = out.open(path, spec) and out.write_image(np.ascontiguousarray(data))
    ok = out.close() and ok
    if not ok:
        raise ImageError(f"cannot write {path}: {first_line(out.geterror())}")


def read_channels(path: str) -> dict:
    """Every channel of an image file by name, every part of a multi-part EXR included.

    Parameters
    ----------
    path : str

    Returns
    -------
    dict of str to (H, W) float32 ndarray
        Top row first, values as stored (renders: scene-linear).

    Raises
    ------
    ImageError
        One line: the file is missing or unreadable.
    """
    oiio = openimageio()
    if not os.path.isfile(path):
        raise ImageError(f"image not found: {path}")
    image = oiio.ImageInput.open(path)
    if image is None:
        raise ImageError(f"cannot read {path}: {first_line(oiio.geterror())}")
    channels = {}
    try:
        part = 0
        while image.seek_subimage(part, 0):  # Blender 5.x writes one part per pass
            spec = image.spec()
            pixels = image.read_image(part, 0, 0, spec.nchannels, "float")
            if pixels is None or image.has_error:
                raise ImageError(f"cannot read {path}: {first_line(image.geterror())}")
            pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
            for c, name in enumerate(spec.channelnames):
                channels[name] = pixels[..., c]
            part += 1
    finally:
        image.close()
    return channels


def read_rgba(path: str) -> np.ndarray:
    """The RGBA pixels of an image file, values as stored.

    Parameters
    ----------
    path : str

    Returns
    -------
    (H, W, 4) float32 ndarray
        Top row first: an 8-bit file's sRGB codes / 255, an EXR's scene-linear values; alpha 1
        where the file has none.

    Raises
    ------
    ImageError
        One line: the file is missing or unreadable.
    """
    oiio = openimageio()
    if not os.path.isfile(path):
        raise ImageError(f"image not found: {path}")
    with quiet_stderr():  # a damaged file: the library's own lines, then ours
        image = oiio.ImageInput.open(path)
        if image is None:
            raise ImageError(f"cannot read {path}: {first_line(oiio.geterror())}")
        try:
            spec = image.spec()
            pixels = image.read_image(0, 0, 0, min(spec.nchannels, 4), "float")
            if pixels is None or image.has_error:
                raise ImageError(f"cannot read {path}: {first_line(image.geterror())}")
        finally:
            image.close()
            oiio.geterror()
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
    """Write a premultiplied render as a scene-linear float RGBA EXR (ZIP), atomically and verified.

    Parameters
    ----------
    path : str
    rgba : (H, W, 4) float32 ndarray
        Premultiplied, scene-linear.

    Raises
    ------
    ImageError
        The file cannot be opened for writing (exit 2).
    WriteError
        The write failed, as `write_map` (exit 1).
    """
    oiio = openimageio()
    h, w = rgba.shape[:2]
    tmp = temp_path(path)
    try:
        out = oiio.ImageOutput.create(path)
        if out is None:
            raise ImageError(f"cannot write {path}: {first_line(oiio.geterror())}")
        spec = exr_spec(w, h, 4, "float")
        ok = out.open(tmp, spec) and out.write_image(np.ascontiguousarray(rgba, np.float32))
        ok = out.close() and ok
        if not ok:
            raise WriteError(f"cannot write {path}: {first_line(out.geterror())}")
        commit(tmp, path, w, h)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
