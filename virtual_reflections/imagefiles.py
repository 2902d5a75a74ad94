"""Reading plates and writing maps, with OpenImageIO alone (its EXR writer also writes the
standard `envmap` header attribute, from the spec's ``textureformat``).

Colour spaces are named, never inferred from OIIO's built-in config (whose `scene_linear`
role is ACEScg, not Rec.709):
- 8- and 16-bit integer files are sRGB-encoded ("sRGB" transfer, Rec.709 primaries) and are
  decoded to scene-linear Rec.709;
- half/float files (EXR, HDR, float TIFF) are already scene-linear Rec.709.
Writes are atomic and verified: a temporary file beside the target (`temp_path`, hidden,
named with the writer's process id), read back whole before it is renamed into place
(`commit`), so a full disk or a dying writer never replaces a good file with a partial one.
Some image libraries report no error on a full disk (libpng); the read-back catches that.
Temporary files of writers that died (SIGKILL) are removed by the next write of the same
target (`remove_stale_temps`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import resource
import sys
import tempfile
from dataclasses import dataclass

import numpy as np

from .colour import clean_plate, decode_uint, linear_to_srgb

MAP_EXTENSIONS = (".exr", ".hdr", ".png", ".jpg", ".jpeg", ".tif", ".tiff")
REC709_CHROMATICITIES = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


_MID_RUN = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO}  # not the input's fault
HALF_MAX = 65504.0  # the largest finite half float
EXIT_BAD_INPUT = 2
EXIT_FAILED = 1


class ImageError(ValueError):
    """A plate or map file that cannot be read or written; the message is one line.
    ``exit_code``: 2, bad input (a missing or unreadable plate, a bad output name)."""

    exit_code = EXIT_BAD_INPUT


class WriteError(ImageError):
    """Writing failed mid-run (a full disk, an I/O error): nothing was replaced; exit code 1,
    worth running again."""

    exit_code = EXIT_FAILED


def same_file(a: str, b: str) -> bool:
    """True when paths ``a`` and ``b`` name one file (or would: same absolute path)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.normcase(os.path.realpath(a)) == os.path.normcase(os.path.realpath(b))


# --- temporary files, verified commits ----------------------------------------------------------

_TEMP = re.compile(r"^\.(?P<stem>.+)\.(?P<pid>\d+)\.(?P<tag>tmp|render)(?:\.\w+)?$")


def temp_path(path: str, tag: str = "tmp") -> str:
    """The hidden temporary name beside ``path`` this process writes it under:
    ``.<stem>.<pid>.<tag><ext>``."""
    folder, base = os.path.split(os.path.abspath(path))
    stem, ext = os.path.splitext(base)
    return os.path.join(folder, f".{stem}.{os.getpid()}.{tag}{ext}")


def pid_alive(pid: int) -> bool:
    """True when process ``pid`` exists on this machine (False for this process's own id is
    not implied: the caller decides what to do with its own files)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def remove_stale_temps(folder: str, stems, live_ok: bool = False) -> list[str]:
    """Delete the temporary files of ``stems`` (output file names without extension) in
    ``folder`` that a writer which is no longer running left (SIGKILL, power loss): never
    this process's, never a live process's (unless ``live_ok``: the caller holds the lock of
    these outputs). Returns the paths removed."""
    stems = set(stems)
    removed = []
    try:
        entries = os.listdir(folder)
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP.match(entry)
        if not m or m.group("stem") not in stems:
            continue
        pid = int(m.group("pid"))
        if pid == os.getpid() or (not live_ok and pid_alive(pid)):
            continue
        path = os.path.join(folder, entry)
        try:
            os.remove(path)
            removed.append(path)
        except OSError:
            pass
    return removed


@contextlib.contextmanager
def quiet_stderr():
    """Silence what image libraries print on the process's stderr themselves (libpng's
    "libpng error: ..."), so that a failure is the tool's one line, not two."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@contextlib.contextmanager
def held_stderr():
    """Hold what is printed on the process's stderr (fd 2: Blender's and the libraries' own
    lines) while the block runs: replayed when it succeeds, dropped when it raises, so that
    a failure is the tool's one line."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
        held = tempfile.TemporaryFile()
    except (OSError, ValueError, AttributeError):
        yield
        return
    ok = False
    try:
        os.dup2(held.fileno(), 2)
        yield
        ok = True
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        if ok:
            held.seek(0)
            data = held.read()
            if data:
                with contextlib.suppress(OSError):
                    os.write(2, data)
        held.close()


def check_complete(path: str, what: str = "image") -> tuple[int, int]:
    """Read ``path`` whole; ImageError (one line) when it cannot be (truncated, damaged).
    Returns its (width, height): the display window for an EXR."""
    oiio = _oiio()
    with quiet_stderr():
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise ImageError(f"cannot read {what} {path}: {_first_line(oiio.geterror())}")
        try:
            spec = inp.spec()
            pixels = inp.read_image(0, 0, 0, spec.nchannels, "uint8")
            if pixels is None or inp.has_error:
                raise ImageError(f"cannot read {what} {path} whole: {_first_line(inp.geterror())}")
            return _header(spec, path).width, _header(spec, path).height
        finally:
            inp.close()
            oiio.geterror()


def verify_image(path: str, width: int, height: int, what: str | None = None) -> None:
    """Read ``path`` back whole; WriteError (one line, naming ``what`` or ``path``) unless it
    is a complete image of ``width`` x ``height``."""
    name = what or path
    oiio = _oiio()
    with quiet_stderr():
        _verify(oiio, path, width, height, name)


def _verify(oiio, path, width, height, name):
    inp = oiio.ImageInput.open(path)
    if inp is None:
        oiio.geterror()
        raise WriteError(f"cannot write {name}: the file written is unreadable (disk full?)")
    try:
        spec = inp.spec()
        if (spec.width, spec.height) != (width, height):
            raise WriteError(
                f"cannot write {name}: the file written is {spec.width}x{spec.height}, "
                f"not {width}x{height}"
            )
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None or inp.has_error:
            raise WriteError(
                f"cannot write {name}: the file written is incomplete (disk full?): "
                f"{_first_line(inp.geterror())}"
            )
    finally:
        inp.close()
        oiio.geterror()  # drop what the library kept, so it is not printed at exit


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def commit(temp: str, path: str, width: int, height: int) -> None:
    """Verify the image ``temp`` (complete, ``width`` x ``height``), flush it to disk and
    rename it to ``path``. On any failure ``temp`` is removed, ``path`` untouched, and a
    WriteError (one line) raised. The one way every writer puts an image in place."""
    try:
        verify_image(temp, width, height, what=path)
        _fsync(temp)
        os.replace(temp, path)
    except OSError as exc:
        raise WriteError(f"cannot write {path}: {exc.strerror or exc}") from exc
    finally:
        if os.path.exists(temp):
            os.remove(temp)
    try:
        _fsync(os.path.dirname(os.path.abspath(path)) or ".")
    except OSError:
        pass  # some file systems cannot sync a folder; the file itself is on disk


def free_bytes(folder: str) -> int:
    """Bytes this process may still write into ``folder``: the file system's free space,
    and the process's file-size limit (RLIMIT_FSIZE)."""
    try:
        st = os.statvfs(folder)
        free = st.f_bavail * st.f_frsize
    except OSError:
        free = 1 << 62
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return free if soft == resource.RLIM_INFINITY else min(free, soft)


def check_space(path: str, nbytes: int) -> None:
    """WriteError (one line) when fewer than ``nbytes`` can be written beside ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    free = free_bytes(folder)
    if free < nbytes:
        raise WriteError(
            f"cannot write {path}: not enough space in {folder} "
            f"(needs up to {nbytes / 1e6:.1f} MB, {free / 1e6:.1f} MB free)"
        )


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


@dataclass(frozen=True)
class PlateHeader:
    """What a plate file's header says, without reading its pixels.

    width, height: the display window (the picture's frame: what the plate is);
    data: (x, y, width, height) of the pixels stored, relative to the display window;
    channels: the channel names; integer: 8/16-bit (sRGB-encoded) rather than half/float."""

    width: int
    height: int
    data: tuple
    channels: tuple
    integer: bool

    @property
    def bytes_per_copy(self) -> int:
        """Bytes of one float32 RGB copy of the plate."""
        return self.width * self.height * 3 * 4


_COLOUR = {"R", "G", "B", "Y", "r", "g", "b", "y", "red", "green", "blue"}


def read_header(path: str) -> PlateHeader:
    """The header of a plate file; ImageError (one line) for a missing, unreadable, empty or
    colourless (depth-only) file."""
    oiio = _oiio()
    if os.path.isdir(path):
        raise ImageError(f"plate is a folder, not an image file: {path}")
    if not os.path.isfile(path):
        raise ImageError(f"plate not found: {path}")
    with quiet_stderr():
        inp = oiio.ImageInput.open(path)
        if inp is None:
            raise ImageError(f"cannot read plate {path}: {_first_line(oiio.geterror())}")
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
    names = tuple(spec.channelnames)
    integer = str(spec.format) in ("uint8", "int8", "uint16", "int16")
    if not integer and names and not any(n.split(".")[-1] in _COLOUR for n in names):
        raise ImageError(
            f"plate {path} has no colour channels (only {', '.join(names)}): not a picture"
        )
    data = (spec.x - spec.full_x, spec.y - spec.full_y, spec.width, spec.height)
    return PlateHeader(full[0], full[1], data, names, integer)


def read_plate(path: str) -> Plate:
    """Read an image file as a plate (see the module docstring for colour handling).

    The plate is the display window: an EXR whose data window is smaller or larger is placed
    in it (black where no pixels are stored, cropped where they reach outside). A file that
    cannot be read whole (truncated, damaged) is an ImageError, never a partly grey plate."""
    oiio = _oiio()
    with quiet_stderr():
        header = read_header(path)
        config = oiio.ImageSpec()
        config.attribute("oiio:UnassociatedAlpha", 1)  # alpha is ignored: keep colour as stored
        inp = oiio.ImageInput.open(path, config)
        if inp is None:
            raise ImageError(f"cannot read plate {path}: {_first_line(oiio.geterror())}")
        try:
            spec = inp.spec()
            integer = header.integer
            fmt = "uint8" if str(spec.format) == "uint8" else "uint16" if integer else "float"
            pixels = inp.read_image(0, 0, 0, min(spec.nchannels, 4), fmt)
            if pixels is None or inp.has_error:
                raise ImageError(f"cannot read plate {path} whole: {_first_line(inp.geterror())}")
        finally:
            inp.close()
            oiio.geterror()
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, -1)
    if integer:
        linear, encoding = decode_uint(pixels[..., :3]), "sRGB"
    else:
        linear, encoding = pixels.astype(np.float32, copy=False), "linear"
    linear = _display_window(linear, header)
    clean = clean_plate(linear)
    return Plate(clean.pixels, encoding, clean.nonfinite, path)


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


def write_map(path: str, pixels: np.ndarray, layout: str | None = None, half: bool = True) -> int:
    """Write a (H, W, 3) float32 scene-linear map (or any picture) atomically, verified.

    .exr: scene-linear half (or float), Rec.709 chromaticities, and for maps the standard
          `envmap` attribute (LATLONG or CUBE); half floats are clamped to +-65504 (a sun
          brighter than that would become Inf);
    .hdr: scene-linear RGBE;
    .png/.jpg: sRGB-encoded 8-bit; .tif: sRGB-encoded 16-bit.
    Returns how many values were clamped to fit half floats (0 for other formats).
    Raises ImageError (bad name, exit 2) or WriteError (the write failed: exit 1); the
    previous file at ``path`` stays as it was unless the new one is complete.
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
    oiio = _oiio()
    spec = oiio.ImageSpec(width, height, channels, fmt)
    spec.attribute("compression", "zip")
    spec.attribute("chromaticities", "float[8]", REC709_CHROMATICITIES)
    spec.attribute("oiio:ColorSpace", LINEAR_TAG)
    if layout is not None:
        spec.attribute("textureformat", ENVMAP_TEXTUREFORMAT[layout])
    return spec


def _write_exr(path: str, pixels: np.ndarray, layout: str | None, half: bool) -> None:
    oiio = _oiio()
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise ImageError(f"cannot write {path}: {_first_line(oiio.geterror())}")
    spec = exr_spec(w, h, c, "half" if half else "float", layout)
    ok = out.open(path, spec) and out.write_image(np.ascontiguousarray(pixels, np.float32))
    ok = out.close() and ok
    if not ok:
        raise ImageError(f"cannot write {path}: {_first_line(out.geterror())}")


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
    with quiet_stderr():  # a damaged file: the library's own lines, then ours
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
    """Write an (H, W, 4) float32 premultiplied render as a scene-linear float RGBA EXR (ZIP),
    atomically and verified as `write_map` (WriteError, exit 1, if the write fails)."""
    oiio = _oiio()
    h, w = rgba.shape[:2]
    tmp = temp_path(path)
    try:
        out = oiio.ImageOutput.create(path)
        if out is None:
            raise ImageError(f"cannot write {path}: {_first_line(oiio.geterror())}")
        spec = exr_spec(w, h, 4, "float")
        ok = out.open(tmp, spec) and out.write_image(np.ascontiguousarray(rgba, np.float32))
        ok = out.close() and ok
        if not ok:
            raise WriteError(f"cannot write {path}: {_first_line(out.geterror())}")
        commit(tmp, path, w, h)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
