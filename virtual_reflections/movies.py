"""How many frames of a movie file are really in it: its video frames whose bytes are all in
the file, counted from the container (no decoding).

A movie cut short (a copy that stopped, a render killed while writing) keeps the frame count
its header was written with; a reader that trusts it (Blender does) shows the last frame
that is there for every frame after it. `whole_frames` counts the video frames whose bytes
are all in the file: ISO base media (.mp4, .mov, .m4v: the sample table), Matroska and WebM
(.mkv, .webm: the blocks of the video track) and AVI (the video chunks of its ``movi``
list). Other containers (and fragmented MP4) are None: not known. A frame that needs a later
frame to decode (B-frames) may still be counted; the tools' own writers make none.
"""

from __future__ import annotations

import mmap
import os
import struct


def whole_frames(path: str) -> int | None:
    """Count the video frames of a movie whose bytes are all in the file.

    Parameters
    ----------
    path : str
        The movie file (.mp4, .mov, .m4v, .mkv, .webm, .avi).

    Returns
    -------
    int or None
        The whole frames (0 when its index is missing), or None when its container is not one
        this module reads.

    Raises
    ------
    OSError
        When the file cannot be read.
    """
    with open(path, "rb") as f:
        if os.fstat(f.fileno()).st_size < 12:
            return 0
        with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:  # never read whole
            return _count(data)


def _count(data):
    head = data[:12]
    try:
        if head[4:8] in (b"ftyp", b"moov", b"mdat", b"wide", b"free", b"skip"):
            return _iso_frames(data)
        if head[:4] == b"\x1a\x45\xdf\xa3":
            return _matroska_frames(data)
        if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
            return _avi_frames(data)
    except (struct.error, IndexError, ValueError):
        return 0  # an index cut inside itself: nothing can be trusted
    return None


# --- ISO base media (.mp4, .mov) ----------------------------------------------------------------


def _boxes(data, start, end):
    """(type, body start, body end) of the boxes in data[start:end]; a box running past the
    data ends the walk (its body end is where the data ends)."""
    at = start
    while at + 8 <= end:
        size, kind = struct.unpack(">I4s", data[at : at + 8])
        body = at + 8
        if size == 1:
            size = struct.unpack(">Q", data[at + 8 : at + 16])[0]
            body = at + 16
        elif size == 0:
            size = end - at
        if size < body - at:
            return
        yield kind, body, min(at + size, end), at + size <= end
        at += size


def _child(data, start, end, kind):
    for k, body, stop, whole in _boxes(data, start, end):
        if k == kind:
            return body, stop, whole
    return None


def _iso_frames(data):
    moov = next((b for b in _boxes(data, 0, len(data)) if b[0] == b"moov"), None)
    if moov is None or not moov[3]:
        return 0  # no index, or one cut short: no frame can be found
    if any(k == b"moof" for k, *_ in _boxes(data, 0, len(data))):
        return None  # fragmented: the samples are indexed per fragment
    for kind, body, stop, _ in _boxes(data, moov[1], moov[2]):
        if kind != b"trak":
            continue
        mdia = _child(data, body, stop, b"mdia")
        hdlr = mdia and _child(data, mdia[0], mdia[1], b"hdlr")
        if not hdlr or data[hdlr[0] + 8 : hdlr[0] + 12] != b"vide":
            continue
        minf = _child(data, mdia[0], mdia[1], b"minf")
        stbl = minf and _child(data, minf[0], minf[1], b"stbl")
        if not stbl:
            return 0
        return _iso_whole_samples(data, stbl[0], stbl[1])
    return 0


def _iso_whole_samples(data, start, end):
    boxes = {k: (b, s) for k, b, s, _ in _boxes(data, start, end)}
    b = boxes[b"stsz"][0]
    fixed, count = struct.unpack(">II", data[b + 4 : b + 12])
    sizes = (
        [fixed] * count if fixed else struct.unpack(f">{count}I", data[b + 12 : b + 12 + 4 * count])
    )
    if b"co64" in boxes:
        b = boxes[b"co64"][0]
        n = struct.unpack(">I", data[b + 4 : b + 8])[0]
        chunks = struct.unpack(f">{n}Q", data[b + 8 : b + 8 + 8 * n])
    else:
        b = boxes[b"stco"][0]
        n = struct.unpack(">I", data[b + 4 : b + 8])[0]
        chunks = struct.unpack(f">{n}I", data[b + 8 : b + 8 + 4 * n])
    b = boxes[b"stsc"][0]
    n = struct.unpack(">I", data[b + 4 : b + 8])[0]
    runs = [struct.unpack(">III", data[b + 8 + 12 * i : b + 20 + 12 * i])[:2] for i in range(n)]
    sample = 0
    for i, offset in enumerate(chunks, 1):
        per_chunk = next((per for first, per in reversed(runs) if first <= i), 0)
        for _ in range(per_chunk):
            if sample >= count:
                return count
            offset += sizes[sample]
            if offset > len(data):
                return sample
            sample += 1
    return sample


# --- Matroska, WebM (.mkv, .webm) --------------------------------------------------------------

_SEGMENT, _CLUSTER, _TRACKS, _TRACK = 0x18538067, 0x1F43B675, 0x1654AE6B, 0xAE
_LEVEL1 = {
    0x114D9B74,
    0x1549A966,
    _TRACKS,
    _CLUSTER,
    0x1C53BB6B,
    0x1043A770,
    0x1941A469,
    0x1254C367,
}


def _vint(data, at, keep_marker):
    first = data[at]
    length = 9 - first.bit_length()
    if not 1 <= length <= 8:
        raise ValueError("not an EBML number")
    value = int.from_bytes(data[at : at + length], "big")
    if not keep_marker:
        value &= (1 << (7 * length)) - 1
        if value == (1 << (7 * length)) - 1:
            value = None  # unknown size
    return value, at + length


def _elements(data, start, end):
    """(id, body start, body end, whole) in data[start:end]; an unknown size runs to ``end``."""
    at = start
    while at < end:
        ident, at2 = _vint(data, at, True)
        size, body = _vint(data, at2, False)
        stop = end if size is None else body + size
        yield ident, body, min(stop, len(data)), stop <= len(data), size is None
        if size is None and ident in (_SEGMENT, _CLUSTER):
            return  # its children follow; the caller walks them
        at = stop


def _matroska_frames(data):
    segment = None
    for ident, body, stop, _, _ in _elements(data, 0, len(data)):
        if ident == _SEGMENT:
            segment = (body, len(data) if stop < body else stop)
            break
    if segment is None:
        return 0
    video, count = None, 0
    items = list(_level1(data, *segment))
    for ident, body, stop, whole in items:
        if ident == _TRACKS and whole:
            video = _matroska_video_track(data, body, stop)
    if video is None:
        return 0
    for ident, body, stop, _ in items:
        if ident != _CLUSTER:
            continue
        for child, cbody, cstop, cwhole, _ in _elements(data, body, stop):
            block = cbody
            if child == 0xA0:  # BlockGroup: its Block
                inner = next((e for e in _elements(data, cbody, cstop) if e[0] == 0xA1), None)
                if inner is None:
                    continue
                block = inner[1]
            elif child != 0xA3:  # not a SimpleBlock
                continue
            if not cwhole:
                return count
            if _vint(data, block, False)[0] == video:
                count += 1
    return count


def _level1(data, start, end):
    """The Segment's children, a Cluster of unknown size ending where the next one starts."""
    at = start
    while at < min(end, len(data)):
        ident, at2 = _vint(data, at, True)
        size, body = _vint(data, at2, False)
        if size is None:  # runs until the next element of the Segment's own level
            stop = body
            while stop < len(data):
                child, c2 = _vint(data, stop, True)
                if child in _LEVEL1:
                    break
                csize, cbody = _vint(data, c2, False)
                stop = len(data) if csize is None else cbody + csize
            yield ident, body, min(stop, len(data)), stop <= len(data)
            at = stop
            continue
        yield ident, body, min(body + size, len(data)), body + size <= len(data)
        at = body + size


def _matroska_video_track(data, start, end):
    for ident, body, stop, _, _ in _elements(data, start, end):
        if ident != _TRACK:
            continue
        fields = {i: data[b:s] for i, b, s, _, _ in _elements(data, body, stop)}
        if int.from_bytes(fields.get(0x83, b""), "big") == 1:  # TrackType video
            return int.from_bytes(fields.get(0xD7, b"\0"), "big")
    return None


# --- AVI ---------------------------------------------------------------------------------------


def _avi_frames(data):
    """The video chunks (``00dc``, ``00db``: stream 0 is the video Blender writes first) of
    the ``movi`` list that are whole."""
    at, count = 12, 0
    while at + 12 <= len(data):
        kind, size = struct.unpack("<4sI", data[at : at + 8])
        if kind == b"LIST" and data[at + 8 : at + 12] == b"movi":
            inner, end = at + 12, min(at + 8 + size, len(data))
            while inner + 8 <= end:
                ckind, csize = struct.unpack("<4sI", data[inner : inner + 8])
                if inner + 8 + csize > len(data):
                    return count
                if ckind[2:] in (b"dc", b"db"):
                    count += 1
                inner += 8 + csize + (csize & 1)
            return count
        at += 8 + size + (size & 1)
    return 0


def frames_text(frames) -> str:
    """Frame numbers as short ranges: [5, 6, 7, 9] -> "5-7, 9".

    Parameters
    ----------
    frames : iterable of int
        Frame numbers, in any order.

    Returns
    -------
    str
        Runs of consecutive frames as "a-b", single frames as "a", joined by ", ".
    """
    runs = []
    for f in sorted(frames):
        if runs and f == runs[-1][1] + 1:
            runs[-1][1] = f
        else:
            runs.append([f, f])
    return ", ".join(f"{a}-{b}" if a != b else f"{a}" for a, b in runs)
