"""The batch entry (`python -m render_shot`, bpy module) under the failures of issue 14
(docs/failures.md): full disk, plate == output, two runs on one folder, damaged and
mismatched plate frames, windowed EXR plates, bad options, memory, Ctrl-C/SIGTERM.
Full disk: a file-size limit (RLIMIT_FSIZE) in the child; every write past it fails."""

import json
import os
import pathlib
import resource
import signal
import subprocess
import sys
import time

import bpy
import numpy as np
import OpenImageIO as oiio
import pytest
from sequence_shots import build_scene, write_movie, write_plates
from shots import addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture
def shot(clean_file, tmp_path):
    plates = write_plates(tmp_path)
    build_scene()
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path, plates


def start(*args, fsize=None, address_space=None):
    def limits():
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))

    return subprocess.Popen(
        [sys.executable, "-m", "render_shot", *map(str, args)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=limits,
    )


def run(*args, **limits):
    proc = start(*args, **limits)
    out, err = proc.communicate(timeout=300)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def pattern(plates):
    return str(plates[0]).replace("0001", "####")


def one_line(r):
    lines = r.stderr.strip().splitlines()
    return len(lines) == 1 and lines[0].startswith("render_shot: ") and "Traceback" not in r.stderr


def hidden(folder):
    return sorted(p.name for p in pathlib.Path(folder).iterdir() if p.name.startswith("."))


SMALL = ("--resolution", 256)


# 2: the single-frame outputs are atomic: a full disk keeps the previous good files.
def test_single_frame_full_disk_keeps_previous_outputs(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    args = (blend, "--plate", plates[0], "--out", out, *SMALL, "--scale", 400)
    first = run(*args)
    assert first.returncode == 0, first.stderr[-2000:]
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(before) == {
        "shot_render.exr",
        "shot_composite.png",
        "shot_composite.exr",
        "shot.report.json",
    }
    r = run(*args, fsize=5_000)
    assert r.returncode == 1 and one_line(r), r.stderr[-2000:]
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


# 10: a full disk during a frame range: one line, exit 1, frames written stay whole.
def test_frame_range_full_disk_is_one_line_exit_1(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1-3", *SMALL)
    r = run(*args, "--scale", 400, fsize=20_000)
    assert r.returncode == 1 and one_line(r), r.stderr[-2000:]
    assert "frame " in r.stderr
    assert hidden(out) == []
    for frame in out.glob("shot.*.exr"):
        assert oiio.ImageBuf(str(frame)).get_pixels(oiio.FLOAT) is not None


# 3: the plate is never an output.
def test_plate_as_an_output_is_refused(shot, tmp_path):
    blend, plates = shot
    folder = plates[0].parent
    copy = folder / "shot.0001.png"
    copy.write_bytes(plates[0].read_bytes())
    r = run(blend, "--plate", copy, "--out", folder, "--frames", 1, "--format", "png", *SMALL)
    assert r.returncode == 2 and one_line(r) and "plate" in r.stderr, r.stderr[-2000:]
    assert copy.read_bytes() == plates[0].read_bytes()
    still = folder / "shot_composite.png"
    still.write_bytes(plates[0].read_bytes())
    r = run(blend, "--plate", still, "--out", folder, *SMALL)
    assert r.returncode == 2 and one_line(r) and "plate" in r.stderr, r.stderr[-2000:]
    assert still.read_bytes() == plates[0].read_bytes()


# 4: a second run on the frames a live run is rendering is refused and deletes nothing.
def test_second_run_on_a_live_runs_frames_is_refused(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1-3", *SMALL)
    first = start(*args, "--scale", 800, "--samples", 32)
    try:
        deadline = time.time() + 120
        while not (out.exists() and any(p.name.endswith(".lock") for p in out.iterdir())):
            assert time.time() < deadline and first.poll() is None, first.communicate()
            time.sleep(0.05)
        temp = out / f".shot.0002.{first.pid}.tmp.exr"
        temp.write_bytes(b"in progress")  # as if the first run were writing frame 2
        r = run(*args)
        assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
        assert str(first.pid) in r.stderr and "in use" in r.stderr
        assert temp.exists()
        temp.unlink()
        _, err = first.communicate(timeout=300)
        assert first.returncode == 0, err[-2000:]
    finally:
        if first.poll() is None:
            first.kill()
    # Once it is done the folder is free again (and a dead run's lock never blocks).
    r = run(*args)
    assert r.returncode == 0, r.stderr[-2000:]


# 6: a truncated frame in a sequence fails, named, never renders grey.
def test_truncated_plate_frame_fails_and_is_named(clean_file, tmp_path):
    plates = write_plates(tmp_path)
    build_scene()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    # A noisy frame 2 (so its pixel data is most of the file), cut after three quarters:
    # the header reads, the pixels do not.
    noise = np.random.default_rng(4).integers(0, 256, (32, 64, 3), dtype=np.uint8)
    buf = oiio.ImageBuf(oiio.ImageSpec(64, 32, 3, "uint8"))
    buf.set_pixels(oiio.ROI(), noise)
    assert buf.write(str(plates[1]))
    data = plates[1].read_bytes()
    plates[1].write_bytes(data[: len(data) * 3 // 4])
    out = tmp_path / "out"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1-3", *SMALL)
    assert r.returncode == 1 and one_line(r) and "frame 2" in r.stderr, r.stderr[-2000:]
    report = json.loads((out / "shot.report.json").read_text())
    assert not report["complete"]
    failed = [e for e in report["frames"] if e["status"] == "failed"]
    assert [e["frame"] for e in failed] == [2] and str(plates[1]) in failed[0]["error"]
    assert not (out / "shot.0002.exr").exists()


# 9: a sequence whose frames differ in size is refused up front.
def test_frames_of_different_sizes_are_refused(clean_file, tmp_path):
    plates = write_plates(tmp_path)
    write_plates(tmp_path / "big", size=(96, 48))
    (tmp_path / "big" / "plate.0002.png").replace(plates[1])
    build_scene()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1-3", *SMALL)
    assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
    assert "96x48" in r.stderr and "64x32" in r.stderr
    assert not out.exists()


# 8: an EXR plate whose data window is not its display window is not misread.
def test_windowed_exr_plate_is_refused(shot, tmp_path):
    blend, _ = shot
    spec = oiio.ImageSpec(32, 32, 3, "half")
    spec.x, spec.full_x, spec.full_y, spec.full_width, spec.full_height = 16, 0, 0, 64, 32
    plate = tmp_path / "windowed.exr"
    o = oiio.ImageOutput.create(str(plate))
    o.open(str(plate), spec)
    o.write_image(np.ones((32, 32, 3), np.float16))
    o.close()
    r = run(blend, "--plate", plate, "--out", tmp_path / "out", *SMALL)
    assert r.returncode == 2 and one_line(r) and "data window" in r.stderr, r.stderr[-2000:]


# 11: options whose values would fail later are refused first (more: test_batch_options.py).
def test_render_under_one_pixel_is_refused(shot, tmp_path):
    blend, plates = shot
    r = run(blend, "--plate", plates[0], "--out", tmp_path / "out", "--scale", 1)
    assert r.returncode == 2 and one_line(r) and "pixel" in r.stderr, r.stderr[-2000:]


# 12: memory: refused up front when the plate cannot fit.
def test_plate_larger_than_memory_is_refused(shot, tmp_path):
    blend, _ = shot
    spec = oiio.ImageSpec(1, 1, 3, "half")
    spec.full_width, spec.full_height = 20000, 15000
    plate = tmp_path / "big.exr"
    o = oiio.ImageOutput.create(str(plate))
    o.open(str(plate), spec)
    o.write_image(np.ones((1, 1, 3), np.float16))
    o.close()
    r = run(blend, "--plate", plate, "--out", tmp_path / "out", *SMALL, address_space=6 << 30)
    assert r.returncode == 1 and one_line(r) and "memory" in r.stderr, r.stderr[-2000:]


# 13: Ctrl-C and SIGTERM: one line, 130 / 143, no temporary file left.
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_interrupted_batch_is_one_line(shot, tmp_path, sig, code):
    blend, plates = shot
    out = tmp_path / "out"
    proc = start(
        blend,
        "--plate",
        pattern(plates),
        "--out",
        out,
        "--frames",
        "1-3",
        *SMALL,
        "--scale",
        800,
        "--samples",
        32,
    )
    deadline = time.time() + 120
    while not (out.exists() and any(p.name.endswith(".lock") for p in out.iterdir())):
        assert time.time() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    time.sleep(0.3)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err[-2000:]
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err[-2000:]
    assert [n for n in hidden(out) if not n.endswith(".lock")] == []


# 5 (bpy module): an exception nothing expects is one line and a non-zero code.
def test_unexpected_exception_exits_non_zero(shot, tmp_path, monkeypatch, capsys):
    sys.path.insert(0, str(ROOT))
    try:
        import render_shot
    finally:
        sys.path.remove(str(ROOT))

    def broken(*_args):
        raise TypeError("something nobody expected")

    monkeypatch.setattr(render_shot, "run", broken)
    blend, plates = shot
    code = render_shot.main([str(blend), "--plate", str(plates[0]), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 1
    assert err.strip().splitlines() == [
        "render_shot: error: internal error: TypeError: something nobody expected"
    ]


def test_an_interrupt_in_a_callback_from_c_is_held_for_the_next_step():
    """A signal whose Interrupted is raised inside a callback from C (Python cannot pass it
    on there and would print it: the compiled back end's kernel cache calls back through
    ctypes) prints nothing; the next step raises it, and other unraisable errors still print."""
    signals = addon_part("operators.batch.signals")
    seen = []
    previous = sys.unraisablehook
    sys.unraisablehook = seen.append
    try:
        with signals.stop_on_signals():
            with pytest.raises(signals.Interrupted):  # the handler raises and records it
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(5)
            for error in (signals.Interrupted(signal.SIGTERM), RuntimeError("other")):
                sys.unraisablehook(
                    type("Info", (), {"exc_value": error, "exc_type": type(error)})()
                )
            with pytest.raises(signals.Interrupted) as raised:
                signals.raise_if_signalled()
            assert raised.value.exit_code == 143
        assert [type(i.exc_value) for i in seen] == [RuntimeError]
        assert sys.unraisablehook == seen.append  # restored on the way out
        signals.raise_if_signalled()  # and the signal is the block's alone: nothing raised
    finally:
        sys.unraisablehook = previous


# Issue 40 (docs/failures.md, rows 20-40): nobody in, nothing lost.


def _report_targets(tmp_path, blend, plates):
    """--report paths that are inputs or outputs of a run of frames 1-2 into tmp_path/out."""
    out = tmp_path / "out"
    return {
        "the shot": blend,
        "a plate frame outside --frames": plates[2],
        "a plate frame inside --frames": plates[0],
        "the run's own composite": out / "shot.0001.exr",
        "a composite of another frame": out / "shot.0007.exr",
        "a CG element": out / "shot_render.0042.exr",
        "a one-frame output": out / "shot_composite.png",
        "the lock": out / ".shot.lock",
    }


# 20: --report never replaces an input, an output or a file that is not a report.
def test_a_report_path_that_is_an_input_or_an_output_is_refused(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    targets = _report_targets(tmp_path, blend, plates)
    before = {p: p.read_bytes() for p in (blend, *plates)}
    for what, target in targets.items():
        args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1-2", *SMALL)
        r = run(*args, "--report", target)
        assert r.returncode == 2 and one_line(r), (what, r.stderr[-2000:])
        assert "--report" in r.stderr, (what, r.stderr)
        assert not out.exists(), what
    assert {p: p.read_bytes() for p in before} == before
    # An existing file that is not one of the tool's reports: kept, refused.
    notes = tmp_path / "notes.json"
    for text in ('{"frames": [1, 2]}\n', "my notes\n", ""):
        notes.write_text(text)
        r = run(blend, "--plate", pattern(plates), "--out", out, "--frames", 1, "--report", notes)
        assert r.returncode == 2 and one_line(r) and "not a report" in r.stderr, r.stderr[-2000:]
        assert notes.read_text() == text and not out.exists()
    # One frame: the same rules.
    r = run(blend, "--plate", plates[0], "--out", out, "--report", plates[1], *SMALL)
    assert r.returncode == 2 and one_line(r) and "--report" in r.stderr, r.stderr[-2000:]
    r = run(blend, "--plate", plates[0], "--out", out, "--report", blend, *SMALL)
    assert r.returncode == 2 and one_line(r) and "--report" in r.stderr, r.stderr[-2000:]
    assert {p: p.read_bytes() for p in before} == before and not out.exists()


# 27: a --name that another name's outputs could have (a_render: run a's CG elements).
def test_a_name_ending_in_an_output_suffix_is_refused(clean_file, tmp_path):
    plates = write_plates(tmp_path)
    build_scene()
    out = tmp_path / "out"
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    for name in ("shot_render", "shot_Composite"):
        r = run(blend, "--plate", pattern(plates), "--out", out, "--name", name, "--frames", 1)
        assert r.returncode == 2 and one_line(r) and "--name" in r.stderr, r.stderr[-2000:]
    # The shot's own name is the default --name: the same rule.
    named = tmp_path / "a_render.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(named))
    r = run(named, "--plate", pattern(plates), "--out", out, "--frames", 1)
    assert r.returncode == 2 and one_line(r) and "--name" in r.stderr, r.stderr[-2000:]
    assert not out.exists()


# 28: frames outside Blender's range are refused, not clamped to its last frame.
def test_frames_beyond_blenders_range_are_refused(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    limit = bpy.types.Scene.bl_rna.properties["frame_current"].hard_max
    for frames in (f"{limit + 1}", f"{limit - 1}-{limit + 2}", f"{-limit - 1}"):
        r = run(blend, "--plate", plates[0], "--out", out, "--frames", frames, *SMALL)
        assert r.returncode == 2 and one_line(r) and str(limit) in r.stderr, r.stderr[-2000:]
    r = run(blend, "--plate", plates[0], "--out", out, "--frame", limit + 1, *SMALL)
    assert r.returncode == 2 and one_line(r) and str(limit) in r.stderr, r.stderr[-2000:]
    assert not out.exists()


# 32: a full disk while writing the report: exit 1, the report named, no temporary left.
def test_full_disk_writing_the_report_is_exit_1(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1-2", *SMALL)
    first = run(*args)
    assert first.returncode == 0, first.stderr[-2000:]
    report = out / "shot.report.json"
    before = report.read_bytes()
    r = run(*args, fsize=len(before) // 4)  # every frame is skipped: only the report is written
    assert r.returncode == 1 and one_line(r), r.stderr[-2000:]
    assert str(report) in r.stderr, r.stderr
    assert [p for p in hidden(out) if not p.endswith(".vr.json")] == []
    assert report.read_bytes() == before


# 33: --combine WORLD with --passes: refused before the first frame, in both modes alike.
def test_world_with_passes_is_refused_up_front(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    opts = ("--combine", "WORLD", "--passes", 2, *SMALL)
    ranged = run(blend, "--plate", pattern(plates), "--out", out, "--frames", "1-2", *opts)
    assert ranged.returncode == 2 and one_line(ranged), ranged.stderr[-2000:]
    single = run(blend, "--plate", plates[0], "--out", out, *opts)
    assert single.returncode == 2 and one_line(single), single.stderr[-2000:]
    assert ranged.stderr == single.stderr and "World (--combine)" in ranged.stderr
    assert not out.exists()


# 39: a still plate whose name has a # or a %d is the still it names.
@pytest.mark.parametrize("name", ["take#3.png", "x_100%d.png"])
def test_an_existing_still_with_pattern_characters_is_a_still(shot, tmp_path, name):
    blend, plates = shot
    still = tmp_path / name
    still.write_bytes(plates[0].read_bytes())
    source = addon_part("operators.batch.ranges").PlateSource(str(still))
    assert source.kind == "still" and source.file(7) == str(still)
    if name.startswith("take"):
        out = tmp_path / "out"
        r = run(blend, "--plate", still, "--out", out, *SMALL)
        assert r.returncode == 0, r.stderr[-2000:]
        assert (out / "shot_composite.png").exists()


# 40: a folder as the plate of a frame range is named as a folder.
def test_a_folder_as_plate_of_a_frame_range_is_named(shot, tmp_path):
    blend, _ = shot
    folder = tmp_path / "plates.png"
    folder.mkdir()
    out = tmp_path / "out"
    r = run(blend, "--plate", folder, "--out", out, "--frames", "1-2", *SMALL)
    assert r.returncode == 2 and one_line(r) and "is a folder" in r.stderr, r.stderr[-2000:]
    assert not out.exists()


# Issue 42, 5: one frame writes the report --report names (as a frame range does).
def test_one_frame_writes_its_report(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    path = tmp_path / "reports" / "one.json"
    path.parent.mkdir()
    r = run(blend, "--plate", plates[0], "--out", out, "--report", path, *SMALL)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads(path.read_text())
    assert report["complete"] and report["plate"] == str(plates[0])
    [entry] = report["frames"]
    assert entry["status"] == "rendered" and entry["frame"] == 1
    assert sorted(entry["outputs"]) == sorted(
        str(out / n) for n in ("shot_render.exr", "shot_composite.png", "shot_composite.exr")
    )
    assert sorted(p.name for p in out.iterdir()) == [
        "shot_composite.exr",
        "shot_composite.png",
        "shot_render.exr",
    ]
    # Without --report it goes where the help says: OUT/<name>.report.json; run again, the
    # tool's own report is replaced.
    for _ in range(2):
        r = run(blend, "--plate", plates[0], "--out", out, *SMALL)
        assert r.returncode == 0, r.stderr[-2000:]
        assert json.loads((out / "shot.report.json").read_text())["complete"]


# 34: damaged still plates in frame-range mode: stderr is exactly the tool's one line.
@pytest.mark.parametrize("damage", ["corrupt-exr", "truncated-jpeg", "truncated-exr"])
def test_a_damaged_still_plate_in_a_frame_range_is_one_line(shot, tmp_path, damage):
    blend, _ = shot
    rng = np.random.default_rng(7)
    noise = rng.random((32, 64, 3), dtype=np.float32)
    kind, ext = damage.split("-")
    plate = tmp_path / f"damaged.{ext}"
    buf = oiio.ImageBuf(oiio.ImageSpec(64, 32, 3, "half" if ext == "exr" else "uint8"))
    buf.set_pixels(oiio.ROI(), noise if ext == "exr" else (noise * 255).astype(np.uint8))
    assert buf.write(str(plate))
    data = plate.read_bytes()
    if kind == "corrupt":  # the header whole, the pixels' bytes overwritten
        cut = len(data) // 3
        plate.write_bytes(data[:cut] + bytes(rng.integers(0, 256, len(data) - cut, np.uint8)))
    else:
        plate.write_bytes(data[: len(data) * 2 // 3])
    out = tmp_path / "out"
    r = run(blend, "--plate", plate, "--out", out, "--frames", "1-2", *SMALL)
    assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
    assert str(plate) in r.stderr
    assert not out.exists()


# 31: a render too large for the memory left is refused up front, one line (it aborted,
# exit 134, stderr empty).
def test_a_render_larger_than_memory_is_refused_up_front(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1", *SMALL)
    r = run(*args, "--scale", 10000, "--samples", 1, address_space=3 << 30)
    assert r.returncode == 1 and one_line(r), (r.returncode, r.stderr[-2000:])
    assert "6400x3200 render" in r.stderr and "memory" in r.stderr
    assert not list(out.glob("shot*"))


# 31: a render that dies (an abort under a memory limit) still shows Blender's last lines:
# the lines held back during a render are replayed when the process dies in it.
def test_a_render_that_dies_still_shows_its_last_lines(shot, tmp_path):
    blend, plates = shot
    out = tmp_path / "out"
    script = (
        "import os, sys, bpy\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        "import render_shot\n"
        "@bpy.app.handlers.persistent\n"
        "def die(*_):\n"
        "    os.write(2, b'Error: out of memory in the renderer, its last words\\n')\n"
        "    os.abort()\n"
        "bpy.app.handlers.render_pre.append(die)\n"
        "sys.exit(render_shot.main(sys.argv[1:]))\n"
    )
    args = (blend, "--plate", pattern(plates), "--out", out, "--frames", "1", *SMALL)
    r = subprocess.run(
        [sys.executable, "-c", script, *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == -signal.SIGABRT, (r.returncode, r.stderr[-2000:])
    assert "out of memory in the renderer, its last words" in r.stderr, r.stderr[-2000:]


# 31: held lines are still dropped when the block fails (the tool's one line says it) and
# replayed when it succeeds.
def test_held_stderr_replays_on_success_and_drops_on_failure(capfd):
    atomic_files = addon_part("virtual_reflections.atomic_files")
    with atomic_files.held_stderr():
        os.write(2, b"kept\n")
    with pytest.raises(RuntimeError), atomic_files.held_stderr():
        os.write(2, b"dropped\n")
        raise RuntimeError
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "kept\nafter\n"


# 25, 37 (issue 40): plates Blender would not read as a picture are refused up front, naming why.
def test_layered_exr_plate_is_refused_naming_its_layers(shot, tmp_path):
    # Blender reads an EXR with layered channel names as render passes: no picture.
    blend, _ = shot
    spec = oiio.ImageSpec(64, 32, 4, "half")
    spec.channelnames = ("depth.Z", "diffuse.R", "diffuse.G", "diffuse.B")
    plate = tmp_path / "layers.exr"
    o = oiio.ImageOutput.create(str(plate))
    o.open(str(plate), spec)
    o.write_image(np.ones((32, 64, 4), np.float16))
    o.close()
    out = tmp_path / "out"
    r = run(blend, "--plate", plate, "--out", out, *SMALL)
    assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
    assert "depth, diffuse" in r.stderr and "--ch R=diffuse.R" in r.stderr, r.stderr
    assert not out.exists() or not [p for p in out.iterdir() if not p.name.startswith(".")]


def test_deep_exr_plate_is_refused(shot, tmp_path):
    blend, _ = shot
    spec = oiio.ImageSpec(64, 32, 5, "float")
    spec.channelnames = ("R", "G", "B", "A", "Z")
    spec.deep = True
    deep = oiio.DeepData()
    deep.init(spec)
    for pixel in range(64 * 32):
        deep.set_samples(pixel, 1)
        for c in range(5):
            deep.set_deep_value(pixel, c, 0, 0.5)
    plate = tmp_path / "deep.exr"
    o = oiio.ImageOutput.create(str(plate))
    assert o.open(str(plate), spec) and o.write_deep_image(deep)
    o.close()
    out = tmp_path / "out"
    r = run(blend, "--plate", plate, "--out", out, *SMALL)
    assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
    assert "deep image" in r.stderr and "--flatten" in r.stderr, r.stderr
    assert not out.exists() or not [p for p in out.iterdir() if not p.name.startswith(".")]


# 23: a movie cut short is refused up front for the frames it no longer holds (Blender showed
# its last whole frame for every frame after it, exit 0, complete).
def test_a_movie_cut_short_is_refused_for_the_frames_it_lost(clean_file, tmp_path):
    colours = [((i + 1) / 10, 1 - (i + 1) / 10, (i % 3) / 2) for i in range(10)]
    movie = write_movie(tmp_path, write_plates(tmp_path, colours=colours))
    assert movie is not None, "this Blender cannot write movies"
    data = movie.read_bytes()
    movie.write_bytes(data[: len(data) // 2])  # frames 1-4 whole, the header still says 10
    build_scene()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    r = run(blend, "--plate", movie, "--out", out, "--frames", "1-10", *SMALL)
    assert r.returncode == 2 and one_line(r), r.stderr[-2000:]
    assert str(movie) in r.stderr and "frames 5-10" in r.stderr, r.stderr
    assert "has frames 1-4 whole" in r.stderr and "10" in r.stderr, r.stderr
    assert not out.exists() or not [p for p in out.iterdir() if not p.name.startswith(".")]
    # The frames it holds render.
    r = run(blend, "--plate", movie, "--out", out, "--frames", "3-4", *SMALL)
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads((out / "shot.report.json").read_text())["complete"]


# 23: a movie frame that cannot be read once the run has started fails that frame (exit 1,
# the report says failed) instead of showing another frame.
def test_a_movie_frame_lost_during_the_run_fails_that_frame(clean_file, tmp_path):
    movie = write_movie(tmp_path, write_plates(tmp_path))
    assert movie is not None, "this Blender cannot write movies"
    build_scene()
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    cut = tmp_path / "cut.mkv"
    script = (
        "import os, sys, bpy\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        "import render_shot\n"
        "@bpy.app.handlers.persistent\n"
        "def cut(scene, *_):\n"
        "    if scene.frame_current == 1:  # after frame 1: a copy cut short replaces it\n"
        f"        data = open({str(movie)!r}, 'rb').read()\n"
        f"        open({str(cut)!r}, 'wb').write(data[: len(data) * 3 // 4])\n"
        f"        os.replace({str(cut)!r}, {str(movie)!r})\n"
        "bpy.app.handlers.render_post.append(cut)\n"
        "code = render_shot.main(sys.argv[1:])\n"
        "bpy.app.handlers.render_post.remove(cut)  # the bpy module hangs at exit with it\n"
        "sys.exit(code)\n"
    )
    args = (blend, "--plate", movie, "--out", out, "--frames", "1-3", *SMALL)
    r = subprocess.run(
        [sys.executable, "-c", script, *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 1 and one_line(r), r.stderr[-2000:]
    assert "frame 3" in r.stderr and str(movie) in r.stderr, r.stderr
    report = json.loads((out / "shot.report.json").read_text())
    assert not report["complete"]
    assert [e["status"] for e in report["frames"]] == ["rendered", "rendered", "failed"]
