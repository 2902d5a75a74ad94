"""virtual_reflections.movies: the video frames whose bytes are in a movie file, counted from
its container (MP4/MOV, Matroska/WebM, AVI), in small containers built here byte by byte,
whole and cut short. (Movies Blender writes: tests/blender/test_batch_failures.py.)"""

import struct

import pytest

from virtual_reflections.movies import frames_text, whole_frames

FRAMES = [bytes([i]) * (300 + 40 * i) for i in range(5)]  # five frames' data, sizes differ


def box(kind, body):
    return struct.pack(">I4s", 8 + len(body), kind) + body


def mp4(frames):
    """ftyp, moov (one video track; its sample table), then mdat: two chunks of 3 and 2."""

    def moov(mdat_at):
        sizes = struct.pack(">III", 0, 0, len(frames)) + b"".join(
            struct.pack(">I", len(f)) for f in frames
        )
        chunks = [mdat_at + 8, mdat_at + 8 + sum(map(len, frames[:3]))]
        stco = struct.pack(">II", 0, 2) + b"".join(struct.pack(">I", c) for c in chunks)
        stsc = (
            struct.pack(">II", 0, 2) + struct.pack(">III", 1, 3, 1) + struct.pack(">III", 2, 2, 1)
        )
        stbl = box(b"stbl", box(b"stsz", sizes) + box(b"stco", stco) + box(b"stsc", stsc))
        hdlr = box(b"hdlr", b"\0" * 8 + b"vide" + b"\0" * 12)
        mdia = box(b"mdia", hdlr + box(b"minf", stbl))
        return box(b"moov", box(b"trak", mdia))

    ftyp = box(b"ftyp", b"isom\0\0\0\0")
    mdat_at = len(ftyp) + len(moov(0))
    return ftyp + moov(mdat_at) + box(b"mdat", b"".join(frames))


def ebml(ident, body):
    size = len(body) | (1 << 56)  # an 8-byte size
    return ident.to_bytes((ident.bit_length() + 7) // 8, "big") + size.to_bytes(8, "big") + body


def mkv(frames):
    """EBML header, Segment: Tracks (track 1 video, track 2 audio), one Cluster of simple
    blocks (each video frame, an audio block between them)."""
    track = ebml(0xAE, ebml(0xD7, b"\x01") + ebml(0x83, b"\x01"))
    audio = ebml(0xAE, ebml(0xD7, b"\x02") + ebml(0x83, b"\x02"))
    blocks = b"".join(
        ebml(0xA3, b"\x81\0\0\x80" + f) + ebml(0xA3, b"\x82\0\0\x80" + b"a" * 50) for f in frames
    )
    cluster = ebml(0x1F43B675, ebml(0xE7, b"\0") + blocks)
    segment = ebml(0x18538067, ebml(0x1654AE6B, track + audio) + cluster)
    return ebml(0x1A45DFA3, ebml(0x4282, b"matroska")) + segment


def avi(frames):
    def chunk(kind, body):
        return struct.pack("<4sI", kind, len(body)) + body + b"\0" * (len(body) & 1)

    def lst(kind, body):
        return struct.pack("<4sI4s", b"LIST", 4 + len(body), kind) + body

    movi = b"".join(chunk(b"00dc", f) + chunk(b"01wb", b"s" * 31) for f in frames)
    body = b"AVI " + lst(b"hdrl", chunk(b"avih", b"\0" * 56)) + lst(b"movi", movi)
    return struct.pack("<4sI", b"RIFF", len(body)) + body + chunk(b"idx1", b"\0" * 16)


@pytest.mark.parametrize("make", [mp4, mkv, avi])
def test_whole_and_cut_short(tmp_path, make):
    data = make(FRAMES)
    path = tmp_path / "movie"
    path.write_bytes(data)
    assert whole_frames(str(path)) == 5
    # Cut inside frame 4's bytes: frames 1-3 are whole.
    at = data.index(FRAMES[3]) + 10
    path.write_bytes(data[:at])
    assert whole_frames(str(path)) == 3
    path.write_bytes(data[: data.index(FRAMES[0]) + 1])
    assert whole_frames(str(path)) == 0


def test_an_mp4_without_its_index_and_unknown_files(tmp_path):
    path = tmp_path / "movie.mp4"
    data = mp4(FRAMES)
    moov = data.index(b"moov") - 4
    path.write_bytes(data[: moov + 20])  # the index cut inside itself
    assert whole_frames(str(path)) == 0
    path.write_bytes(b"OggS" + b"\0" * 100)
    assert whole_frames(str(path)) is None
    path.write_bytes(b"")
    assert whole_frames(str(path)) == 0


def test_frames_text():
    assert frames_text([5, 6, 7, 9, 10, 12]) == "5-7, 9-10, 12"
