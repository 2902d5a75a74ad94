"""Frame ranges through the batch entry (`python -m render_shot ... --frames`), bpy module."""

import json
import pathlib
import subprocess
import sys
import time

import bpy
import numpy as np
import pytest
from sequence_shots import COLOURS, build_scene, read, write_movie, write_plates
from shots import addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture
def shot(clean_file, tmp_path):
    """shot.blend (a sphere before the camera, deterministic tiny Cycles) and three plates."""
    plates = write_plates(tmp_path)
    build_scene()
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path, plates


def command(*args):
    return [sys.executable, "-m", "render_shot", *map(str, args)]


def run(*args):
    return subprocess.run(command(*args), cwd=ROOT, capture_output=True, text=True, timeout=300)


def pattern(plates):
    return str(plates[0]).replace("0001", "####")


def on_sphere(pixels):
    """Mean colour of the middle of the frame (the sphere), (3,)."""
    h, w = pixels.shape[:2]
    return pixels[h // 3 : 2 * h // 3, w // 3 : 2 * w // 3, :3].reshape(-1, 3).mean(0)


def test_frames_write_composites_and_report(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1-3", "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    progress = [line for line in r.stdout.splitlines() if line.startswith("frame ")]
    assert [p.split()[1] for p in progress] == ["1/3", "2/3", "3/3"]
    assert all(p.endswith(" s") for p in progress)
    files = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    composites = [f"shot.{f:04d}.exr" for f in (1, 2, 3)]
    elements = [f"shot_render.{f:04d}.exr" for f in (1, 2, 3)]
    assert files == sorted([*composites, *elements, "shot.report.json"])
    hidden = sorted(p.name for p in out.iterdir() if p.name.startswith("."))
    assert hidden == [f".{c}.vr.json" for c in composites]  # what made each frame
    frames = [read(out / f"shot.{f:04d}.exr") for f in (1, 2, 3)]
    for frame, pixels in enumerate(frames, 1):
        assert pixels.shape == (32, 64, 4)
        # The CG element: the render alone, transparent around the sphere.
        element = read(out / f"shot_render.{frame:04d}.exr")
        assert element.shape == (32, 64, 4) and element[0, 0, 3] == 0.0
        assert on_sphere(element)[np.argmax(COLOURS[frame - 1])] > 0
        # Plate and sphere show that frame's colour: the sphere reflects that frame's plate.
        assert np.argmax(on_sphere(pixels)) == np.argmax(COLOURS[frame - 1])
    report = json.loads((out / "shot.report.json").read_text())
    assert report["complete"] and report["plate_kind"] == "sequence"
    # the engine back end that made the maps (this process runs with the same environment)
    backends = addon_part("virtual_reflections.backends")
    assert report["reflections"]["back_end"] == backends.backend()
    assert [e["frame"] for e in report["frames"]] == [1, 2, 3]
    first = report["frames"][0]
    assert first["status"] == "rendered" and first["plate"] == str(plates[0])
    assert first["outputs"] == [str(out / "shot.0001.exr"), str(out / "shot_render.0001.exr")]
    assert first["passes"] == 1
    assert {"plate", "bounds", "table", "gather", "render", "write", "total"} <= set(first["times"])
    assert first["changes"]["maps_updated"] == ["VR Map Sphere"]
    # The sphere does not move: its table is built once, then reused for every later frame.
    assert [e["changes"]["tables_reused"] for e in report["frames"]] == [0, 1, 1]
    assert report["totals"]["rendered"] == 3 and report["totals"]["skipped"] == 0


def test_killed_batch_resumes(shot, tmp_path):
    """Kill a run once its first frame is written; the next run skips that frame and its
    frames equal those of an uninterrupted run, pixel for pixel."""
    blend, plates = shot
    args = ["--plate", pattern(plates), "--frames", "1-3", "--resolution", 256]
    slow = ["--scale", 400, "--samples", 24]  # ~0.5 s a frame: time to kill it mid-run
    whole = run(blend, *args, *slow, "--out", tmp_path / "whole")
    assert whole.returncode == 0, whole.stderr[-2000:]

    out = tmp_path / "resumed"
    proc = subprocess.Popen(
        command(blend, *args, *slow, "--out", out), cwd=ROOT, stdout=subprocess.PIPE, text=True
    )
    first = out / ".shot.0001.exr.vr.json"  # a frame's last file: the record of what made it
    deadline = time.monotonic() + 120
    while not first.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.kill()
    proc.communicate()
    assert first.exists()
    written = [f for f in (1, 2, 3) if (out / f"shot.{f:04d}.exr").exists()]
    assert written[0] == 1 and len(written) < 3, "the run finished before it could be killed"
    # Whatever was written is complete: only hidden temporary files may be half-written.
    for f in written:
        assert read(out / f"shot.{f:04d}.exr").shape == (128, 256, 4)

    again = run(blend, *args, *slow, "--out", out)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "[1] skipped" in again.stdout
    assert sorted(p.name for p in out.iterdir()) == sorted(
        p.name for p in (tmp_path / "whole").iterdir()
    )  # no temporary file left
    for f in (1, 2, 3):
        a = read(out / f"shot.{f:04d}.exr")
        b = read(tmp_path / "whole" / f"shot.{f:04d}.exr")
        assert np.array_equal(a, b), f
    report = json.loads((out / "shot.report.json").read_text())
    assert report["complete"]
    assert [e["status"] for e in report["frames"]][0] == "skipped"


def test_bad_range(shot, tmp_path):
    """(Every bad form of --frames: test_sequence.py's test_parse_frames.)"""
    blend, plates = shot
    out = tmp_path / "out"
    message = "bad frame range '3-1'"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "3-1")
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("render_shot: error") and message in lines[0]
    assert not out.exists()


def test_missing_sequence_frame(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1-4")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    missing = str(plates[0]).replace("0001", "0004")
    assert len(lines) == 1 and "plate frame 4 is missing" in lines[0] and missing in lines[0]
    assert not out.exists()


def test_unwritable_output(shot, tmp_path):
    blend, plates = shot
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    r = run(blend, "--plate", pattern(plates), "--out", blocker / "out", "--frames", "1")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "output folder not writable" in lines[0]


def test_movie_plate_and_png(clean_file, tmp_path):
    plates = write_plates(tmp_path)
    movie = write_movie(tmp_path, plates)
    if movie is None:
        pytest.skip("this Blender cannot write movies")
    build_scene()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    r = run(blend, "--plate", movie, "--out", out, "--format", "png", "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]  # the scene's range: 1-3
    for frame in (1, 2, 3):
        pixels = read(out / f"shot.{frame:04d}.png")
        assert np.argmax(on_sphere(pixels)) == np.argmax(COLOURS[frame - 1])
    r = run(blend, "--plate", movie, "--out", out, "--frames", "2-4")
    assert r.returncode == 2 and "has frames 1-3" in r.stderr


def test_passes_flow_through(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1", "--passes", "2")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "shot.report.json").read_text())
    assert report["reflections"]["passes_requested"] == 2
    has_passes = (ROOT / "operators" / "interreflect.py").exists()
    if has_passes:
        assert report["frames"][0]["passes"] == 2
        assert len(report["frames"][0]["pass_reports"]) == 2
    else:
        assert report["frames"][0]["passes"] == 1
        assert any("interreflect" in w for w in report["warnings"])
