"""Uncompressed OpenEXR files read with NumPy alone (no OpenImageIO).

The inter-reflection passes render into a multilayer EXR written without compression
(operators/interreflect.py), so reading it needs no image library: Blender's packages on
some distributions come without OpenImageIO. Scanline files, single- or multi-part (Blender
5.x writes one part per pass), compression NONE, channels half, float or uint; anything else
raises ImageError (one line) naming what it is.

OpenEXR's layout (openexr.com, "OpenEXR File Layout"): magic and version, the header(s) as
(name, type, size, value) attributes ending with an empty name, the chunk offset table(s),
then the chunks: [part number,] y, size, and the block's lines, each line holding every
channel (in the header's order, which is alphabetical) for the data window's width.
"""

from __future__ import annotations

import os
import struct

import numpy as np

from .atomic_files import ImageError

MAGIC = 20000630
TILED, LONG_NAMES, DEEP, MULTIPART = 0x200, 0x400, 0x800, 0x1000
DTYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def read_channels(path: str) -> dict:
    """Every channel of an uncompressed EXR by name, every part included.

    Parameters
    ----------
    path : str

    Returns
    -------
    dict of str to (H, W) float32 ndarray
        Over the display window (zero where no data), top row first, values as stored.

    Raises
    ------
    ImageError
        One line: the file is missing, damaged or compressed.
    """
    if not os.path.isfile(path):
        raise ImageError(f"image not found: {path}")
    with open(path, "rb") as f:
        data = f.read()
    try:
        return _channels(data, path)
    except (struct.error, IndexError, ValueError) as exc:
        if isinstance(exc, ImageError):
            raise
        raise ImageError(f"cannot read {path}: damaged EXR ({exc})") from exc


def _channels(data: bytes, path: str) -> dict:
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != MAGIC:
        raise ImageError(f"cannot read {path}: not an OpenEXR file")
    if version & (TILED | DEEP):
        raise ImageError(f"cannot read {path}: tiled or deep EXR (write scanlines)")
    multipart = bool(version & MULTIPART)
    pos, headers = 8, []
    while True:
        header, pos = _header(data, pos)
        headers.append(header)
        if not multipart:
            break
        if data[pos] == 0:  # an empty header ends the list
            pos += 1
            break
    out = {}
    tables = []
    for header in headers:
        count = _chunk_count(header)
        tables.append(struct.unpack_from(f"<{count}Q", data, pos))
        pos += 8 * count
    for part, (header, offsets) in enumerate(zip(headers, tables, strict=True)):
        out.update(_read_part(data, header, offsets, part if multipart else None, path))
    return out


def _header(data: bytes, pos: int) -> tuple[dict, int]:
    header = {}
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        pos = end + 1
        if not name:
            return header, pos
        end = data.index(b"\0", pos)
        kind = data[pos:end].decode()
        (size,) = struct.unpack_from("<i", data, end + 1)
        value = data[end + 5 : end + 5 + size]
        pos = end + 5 + size
        header[name] = _value(kind, value)


def _value(kind: str, raw: bytes):
    if kind == "chlist":
        channels, pos = [], 0
        while raw[pos] != 0:
            end = raw.index(b"\0", pos)
            name = raw[pos:end].decode()
            pixel_type, _, _, xs, ys = struct.unpack_from("<iB3sii", raw, end + 1)
            channels.append((name, pixel_type, xs, ys))
            pos = end + 1 + 16
        return channels
    if kind == "box2i":
        return struct.unpack("<4i", raw)
    if kind == "compression":
        return raw[0]
    if kind == "int":
        return struct.unpack("<i", raw)[0]
    if kind == "string":
        return raw.decode(errors="replace")
    return raw


def _chunk_count(header: dict) -> int:
    if "chunkCount" in header:
        return header["chunkCount"]
    x0, y0, x1, y1 = header["dataWindow"]
    return y1 - y0 + 1  # compression NONE: one line per chunk


def _read_part(data, header, offsets, part, path) -> dict:
    if header.get("compression", 0) != 0:
        raise ImageError(f"cannot read {path}: compressed EXR (this reader needs compression NONE)")
    if header.get("type", "scanlineimage") != "scanlineimage":
        raise ImageError(f"cannot read {path}: {header['type']} part (scanlines only)")
    channels = header["channels"]
    if any(xs != 1 or ys != 1 or t not in DTYPES for _, t, xs, ys in channels):
        raise ImageError(f"cannot read {path}: subsampled or unknown channel type")
    x0, y0, x1, y1 = header["dataWindow"]
    dx0, dy0, dx1, dy1 = header.get("displayWindow", header["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    line = np.dtype([(str(i), DTYPES[t], (w,)) for i, (_, t, _, _) in enumerate(channels)])
    rows = np.zeros(h, dtype=line)
    for offset in offsets:
        pos = offset
        if part is not None:
            pos += 4  # the part number
        y, size = struct.unpack_from("<ii", data, pos)
        block = np.frombuffer(data, dtype=line, count=size // line.itemsize, offset=pos + 8)
        rows[y - y0 : y - y0 + len(block)] = block
    out = {}
    full = (dy1 - dy0 + 1, dx1 - dx0 + 1)
    for i, (name, _, _, _) in enumerate(channels):
        plane = np.zeros(full, np.float32)
        # The data window inside the display window (cut to it).
        ys, xs = slice(max(y0, dy0), min(y1, dy1) + 1), slice(max(x0, dx0), min(x1, dx1) + 1)
        values = rows[str(i)].astype(np.float32)
        plane[ys.start - dy0 : ys.stop - dy0, xs.start - dx0 : xs.stop - dx0] = values[
            ys.start - y0 : ys.stop - y0, xs.start - x0 : xs.stop - x0
        ]
        out[name] = plane
    return out
