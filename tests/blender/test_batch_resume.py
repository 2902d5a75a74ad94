"""Resume never ships a stale frame (issue 12): each frame keeps a record of what made it; a
run with other inputs renders complete frames again and says why, the same inputs skip."""

import json
import os
import pathlib
import struct
import subprocess
import sys
import zlib

import bpy
import numpy as np
import pytest
from sequence_shots import COLOURS, build_scene, read, write_plates
from shots import addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture
def shot(clean_file, tmp_path):
    """shot.blend and two plate sequences: a/ in COLOURS, b/ in the reverse order."""
    a = write_plates(tmp_path / "a")
    b = write_plates(tmp_path / "b", colours=COLOURS[::-1])
    build_scene()
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path, str(a[0]).replace("0001", "####"), str(b[0]).replace("0001", "####")


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "render_shot", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def sphere_colour(path):
    pixels = read(path)
    h, w = pixels.shape[:2]
    return int(np.argmax(pixels[h // 3 : 2 * h // 3, w // 3 : 2 * w // 3, :3].mean((0, 1))))


def statuses(out):
    report = json.loads((out / "shot.report.json").read_text())
    return [(e["status"], e.get("rendered_again")) for e in report["frames"]]


def test_other_inputs_render_again_same_inputs_skip(shot, tmp_path):
    blend, plate_a, plate_b = shot
    out = tmp_path / "out"
    common = [blend, "--out", out, "--frames", "1-2", "--resolution", 256]
    first = run(*common, "--plate", plate_a)
    assert first.returncode == 0, first.stderr[-2000:]
    assert sphere_colour(out / "shot.0001.exr") == 0  # red: plate a's frame 1

    # The same inputs: both frames skipped.
    same = run(*common, "--plate", plate_a)
    assert same.returncode == 0, same.stderr[-2000:]
    assert statuses(out) == [("skipped", None), ("skipped", None)]

    # Another plate: rendered again, the report and the log say why; the frames are b's.
    other = run(*common, "--plate", plate_b)
    assert other.returncode == 0, other.stderr[-2000:]
    assert statuses(out) == [("rendered", "made with another plate")] * 2
    assert "[1] rendered again: made with another plate" in other.stdout
    assert sphere_colour(out / "shot.0001.exr") == 2  # blue: plate b's frame 1

    # Another combine (and passes): rendered again, naming what changed.
    mixed = run(*common, "--plate", plate_b, "--combine", "MIX")
    assert mixed.returncode == 0, mixed.stderr[-2000:]
    assert statuses(out) == [("rendered", "made with another reflections")] * 2
    report = json.loads((out / "shot.report.json").read_text())
    record = json.loads((out / ".shot.0001.exr.vr.json").read_text())
    assert record["inputs"]["reflections"]["combine"] == "MIX"
    assert record["fingerprint"] == report["frames"][0]["fingerprint"]

    # The artist's own sky (Surroundings Custom): rendered again; its brightness is recorded
    # only under Custom, where it shapes the maps.
    custom = run(*common, "--plate", plate_b, "--combine", "MIX", "--sky-brightness", 2.5)
    assert custom.returncode == 0, custom.stderr[-2000:]
    assert statuses(out) == [("rendered", "made with another reflections")] * 2
    record = json.loads((out / ".shot.0001.exr.vr.json").read_text())
    assert record["inputs"]["reflections"]["surroundings"] == "CUSTOM"
    assert record["inputs"]["reflections"]["sky_brightness"] == 2.5
    # The Sky Texture: rendered again at another share; recorded when on (the default, 0.75), and
    # off (0) the records are those made before it had one (a flat sky).
    textured = run(*common, "--plate", plate_b, "--combine", "MIX", "--sky-texture", 0.5)
    assert textured.returncode == 0, textured.stderr[-2000:]
    assert statuses(out) == [("rendered", "made with another reflections")] * 2
    record = json.loads((out / ".shot.0001.exr.vr.json").read_text())
    assert record["inputs"]["reflections"]["sky_texture"] == 0.5
    named = run(*common, "--plate", plate_b, "--combine", "MIX", "--surroundings", "auto")
    assert named.returncode == 0, named.stderr[-2000:]
    record = json.loads((out / ".shot.0001.exr.vr.json").read_text())
    assert "sky_brightness" not in record["inputs"]["reflections"]
    assert record["inputs"]["reflections"]["sky_texture"] == 0.75  # the default
    flat = run(*common, "--plate", plate_b, "--combine", "MIX", "--surroundings", "auto",
               "--sky-texture", 0)  # fmt: skip
    assert flat.returncode == 0, flat.stderr[-2000:]
    record = json.loads((out / ".shot.0001.exr.vr.json").read_text())
    assert "sky_texture" not in record["inputs"]["reflections"]
    again = run(*common, "--plate", plate_b, "--combine", "MIX", "--surroundings", "auto")
    assert again.returncode == 0, again.stderr[-2000:]  # the default's records, for what follows

    # The plate file changed in place (same name, new pixels): rendered again.
    plate_file = pathlib.Path(plate_b.replace("####", "0002"))
    plate_file.write_bytes(pathlib.Path(plate_a.replace("####", "0002")).read_bytes())
    touched = run(*common, "--plate", plate_b, "--combine", "MIX")
    assert touched.returncode == 0, touched.stderr[-2000:]
    assert statuses(out) == [("skipped", None), ("rendered", "made with another plate")]

    # Frames without a record (an older version's output) are rendered again, never skipped.
    (out / ".shot.0001.exr.vr.json").unlink()
    older = run(*common, "--plate", plate_b, "--combine", "MIX")
    assert older.returncode == 0, older.stderr[-2000:]
    assert statuses(out) == [("rendered", "no record of what made it"), ("skipped", None)]
    assert not [p for p in out.iterdir() if ".tmp" in p.name]


def _other_density(png):
    """``png`` with another pixel density in its pHYs chunk (its CRC made again): a valid
    file of the same size whose bytes differ."""
    at = png.index(b"pHYs") - 4
    (length,) = struct.unpack(">I", png[at : at + 4])
    body = bytearray(png[at + 4 : at + 8 + length])
    body[4 + 3] ^= 0x01  # pixels per unit along x
    crc = struct.pack(">I", zlib.crc32(bytes(body)) & 0xFFFFFFFF)
    return png[: at + 4] + bytes(body) + crc + png[at + 12 + length :]


def test_a_plate_replaced_with_its_size_and_time_kept_renders_again(shot, tmp_path):
    """Resume compares the plate's bytes (a hash), not its size and time alone: a plate
    replaced by other bytes of the same size, its time put back, is not skipped."""
    blend, plate_a, _ = shot
    out = tmp_path / "out"
    common = [blend, "--out", out, "--frames", "1-2", "--resolution", 256, "--plate", plate_a]
    first = run(*common)
    assert first.returncode == 0, first.stderr[-2000:]
    plate_file = pathlib.Path(plate_a.replace("####", "0002"))
    data = plate_file.read_bytes()
    st = plate_file.stat()
    plate_file.write_bytes(_other_density(data))  # other bytes, the same size and pixels
    os.utime(plate_file, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert plate_file.stat().st_size == st.st_size
    assert plate_file.stat().st_mtime_ns == st.st_mtime_ns
    again = run(*common)
    assert again.returncode == 0, again.stderr[-2000:]
    assert statuses(out) == [("skipped", None), ("rendered", "made with another plate")]
    record = json.loads((out / ".shot.0002.exr.vr.json").read_text())
    assert record["inputs"]["plate"]["blake2b"]


def test_frames_made_with_another_blender_render_again(shot, tmp_path):
    """The record holds the Blender that made the frame: another one renders it again."""
    blend, plate_a, _ = shot
    out = tmp_path / "out"
    common = [blend, "--out", out, "--frames", "1-2", "--resolution", 256, "--plate", plate_a]
    first = run(*common)
    assert first.returncode == 0, first.stderr[-2000:]
    path = out / ".shot.0001.exr.vr.json"
    record = json.loads(path.read_text())
    assert record["inputs"]["blender"]["version"] == bpy.app.version_string
    # As if Blender 4.2 had made frame 1: its record stays whole (fingerprint of its inputs).
    batch_record = addon_part("operators.batch.record")
    record["inputs"]["blender"] = {"version": "4.2.0", "build_hash": "0123456789ab"}
    record["fingerprint"] = batch_record.digest(record["inputs"])
    path.write_text(json.dumps(record))
    again = run(*common)
    assert again.returncode == 0, again.stderr[-2000:]
    assert statuses(out) == [("rendered", "made with Blender 4.2.0"), ("skipped", None)]
    assert "[1] rendered again: made with Blender 4.2.0" in again.stdout
