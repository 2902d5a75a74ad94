"""The render-farm driver (pipeline/farm.py): frame chunks, and a real Dask cluster on loopback.

The driver's own behaviour (fan-out, merged report, retries, a lost worker, bad input) is tested
against a stand-in batch entry that writes text frames in milliseconds; one integration test
renders a tiny shot through the real render_shot on the cluster and compares it pixel for pixel
with the same frames rendered on one machine.
"""

import importlib.util
import json
import pathlib
import subprocess
import sys
import textwrap
import time

import pytest

from pipeline import farm

ROOT = pathlib.Path(__file__).resolve().parents[2]
PLATE = ROOT / "sample_scenes/plates/courtyard.jpg"  # 1280x720: --scale 5 renders 64x36


# -- frames and chunks (no cluster) -----------------------------------------------------------


@pytest.mark.parametrize(
    "spec, frames",
    [
        ("1-4", [1, 2, 3, 4]),
        ("1-10x2", [1, 3, 5, 7, 9]),
        ("5", [5]),
        ("1,3,7-9", [1, 3, 7, 8, 9]),
        ("7-9,1,3,3", [1, 3, 7, 8, 9]),
        ("-2-1", [-2, -1, 0, 1]),
        (" 1 - 3 ", [1, 2, 3]),
    ],
)
def test_parse_frames(spec, frames):
    assert farm.parse_frames(spec) == frames


@pytest.mark.parametrize(
    "spec", ["", "a", "3-1", "1-10x0", "1-", "1,,2", "1-5x-1", "1.5", "1-9999999"]
)
def test_parse_frames_refuses(spec):
    with pytest.raises(ValueError, match="frame"):
        farm.parse_frames(spec)


@pytest.mark.parametrize(
    "frames, chunk, chunks",
    [
        ("1-240", 10, [f"{a}-{a + 9}" for a in range(1, 241, 10)]),
        ("1-10", 4, ["1-4", "5-8", "9-10"]),
        ("1-10", 100, ["1-10"]),
        ("1-10x2", 2, ["1,3", "5,7", "9"]),
        ("1-20x2", 4, ["1-7x2", "9-15x2", "17,19"]),
        ("5", 10, ["5"]),
        ("1,3,7-9", 2, ["1,3", "7-8", "9"]),
        ("1,3,7-9", 3, ["1,3,7", "8-9"]),
        ([4, 2, 3, 1], 2, ["1-2", "3-4"]),
    ],
)
def test_plan_chunks(frames, chunk, chunks):
    assert farm.plan_chunks(frames, chunk) == chunks


@pytest.mark.parametrize("spec", ["1-240", "1-100x3", "1,3,7-9,20-30x5,31", "-5-5"])
@pytest.mark.parametrize("chunk", [1, 2, 7, 1000])
def test_plan_chunks_covers_every_frame_once_in_order(spec, chunk):
    chunks = farm.plan_chunks(spec, chunk)
    frames = [f for c in chunks for f in farm.parse_frames(c)]
    assert frames == farm.parse_frames(spec)
    assert all(len(farm.parse_frames(c)) <= chunk for c in chunks)


@pytest.mark.parametrize("chunk", [0, -1, 2.5, True, "10"])
def test_plan_chunks_refuses_bad_chunk_size(chunk):
    with pytest.raises(ValueError, match="chunk size"):
        farm.plan_chunks("1-10", chunk)


def test_merge_reports_sorts_frames_and_keeps_the_first_header():
    merged = farm.merge_reports(
        [
            {"shot": "a", "frames": [{"frame": 3}, {"frame": 4}]},
            {"shot": "b", "frames": [{"frame": 1}, {"frame": 2, "status": "x"}]},
        ]
    )
    assert merged["shot"] == "a"
    assert [e["frame"] for e in merged["frames"]] == [1, 2, 3, 4]


def test_batch_commands():
    prefix, cwd = farm.batch_command("/s/shot.blend", blender="/opt/blender/blender")
    assert prefix == [
        "/opt/blender/blender",
        "-b",
        "/s/shot.blend",
        "--python-exit-code",  # issue 14, case 5: a Python error is never exit code 0
        "1",
        "--python",
        str(ROOT / "render_shot.py"),
        "--",
    ]
    prefix, cwd = farm.batch_command("/s/shot.blend")
    assert prefix == [farm.WORKER_PYTHON, "-m", "render_shot"] and cwd == str(ROOT)


def cli(*args, timeout=120):
    return subprocess.run(
        [sys.executable, "-m", "pipeline.farm", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.parametrize(
    "args, message",
    [
        (("--frames", "1-x"), "bad frame range"),
        (("--frames", "1-4", "--chunk", "0"), "chunk size"),
        (("--frames", "1-4", "--", "--frames", "2"), "--frames is set by the farm"),
        (("--frames", "1-4", "--", "--out=elsewhere"), "--out is set by the farm"),
        # issue 40, row 30: abbreviations of the farm's options (argparse took `--ou` for `--out`)
        (("--frames", "1-4", "--", "--ou", "elsewhere"), "--ou is an abbreviation of --out"),
        (("--frames", "1-4", "--", "--pla=p2"), "--pla is an abbreviation of --plate"),
        (("--frames", "1-4", "--", "--rep", "r.json"), "--rep is an abbreviation of --report"),
        (("--frames", "1-4", "--", "--fr", "2"), "--fr is an abbreviation of --frame"),
        (("--frames", "1-4", "--ou", "elsewhere"), "unrecognized arguments: --ou elsewhere"),
        (("--frames", "1-4", "--chu", "2"), "unrecognized arguments: --chu 2"),
        (("--frames", "1-4", "--blender", "b", "--bpy"), "not allowed with"),
        (("--frames", "1-4", "--extension", "/nowhere"), "no render_shot.py"),
        (("--frames", "1-4"), "shot not found: "),
    ],
)
def test_cli_bad_input_is_one_line_and_exit_2(tmp_path, args, message):
    r = cli("--scheduler", "tcp://127.0.0.1:9", "s.blend", "--plate", "p", "--out", tmp_path, *args)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("farm: error: "), r.stderr
    assert message in lines[0], r.stderr


# -- on a Dask cluster (loopback) -------------------------------------------------------------


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip(
        "distributed",
        reason="Dask distributed is not installed: pip install -r requirements/farm.txt",
    )
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        yield cluster


@pytest.fixture
def client(cluster):
    from distributed import Client

    with Client(cluster) as client:
        yield client


# A stand-in for render_shot.py with its farm contract and none of Blender: text "frames",
# written atomically and skipped when complete, a JSON report at --report, exit 2 and one
# stderr line for a missing plate; a marker file in $FAKE_CRASH_ONCE makes it crash once, one
# in $FAKE_KILL_WORKER_ONCE makes it kill the Dask worker that runs it, once.
FAKE = textwrap.dedent(
    """
    import argparse, json, os, signal, sys, time
    sys.path.insert(0, {root!r})
    from pipeline.farm import parse_frames

    def once(variable):
        marker = os.environ.get(variable)
        try:
            os.close(os.open(marker, os.O_CREAT | os.O_EXCL)) if marker else None
        except FileExistsError:
            return False
        return bool(marker)

    p = argparse.ArgumentParser(allow_abbrev=False)
    for option in ("--plate", "--out", "--frames", "--report", "--name"):
        p.add_argument(option)
    p.add_argument("blend")
    args = p.parse_args()
    if not os.path.isfile(args.plate):
        sys.exit(print("render_shot: error: plate not found: " + args.plate, file=sys.stderr) or 2)
    if once("FAKE_CRASH_ONCE"):
        sys.exit(print("Segmentation fault", file=sys.stderr) or 139)
    if once("FAKE_KILL_WORKER_ONCE"):
        os.kill(os.getppid(), signal.SIGKILL)
        sys.exit(1)
    name = args.name or os.path.splitext(os.path.basename(args.blend))[0]
    entries = []
    for frame in parse_frames(args.frames):
        path = os.path.join(args.out, f"{{name}}.{{frame:04d}}.txt")
        status = "skipped"
        if not os.path.exists(path):
            time.sleep(0.05)
            with open(path + ".tmp", "w") as f:
                f.write(f"{{frame}} by {{os.getpid()}}")
            os.replace(path + ".tmp", path)
            status = "rendered"
        entries.append({{"frame": frame, "status": status, "outputs": [path]}})
    with open(args.report + ".tmp", "w") as f:
        json.dump({{"shot": args.blend, "plate": args.plate, "frames": entries}}, f)
    os.replace(args.report + ".tmp", args.report)
    """
).format(root=str(ROOT))


@pytest.fixture
def fake(tmp_path):
    """(command prefix, shot, plate) for the stand-in batch entry."""
    script = tmp_path / "fake_render_shot.py"
    script.write_text(FAKE)
    shot, plate = tmp_path / "fake.blend", tmp_path / "plate.jpg"
    shot.write_bytes(b"")
    plate.write_bytes(b"")
    return [sys.executable, str(script)], shot, plate


def test_run_farm_fans_out_and_merges_one_report(client, fake, tmp_path):
    prefix, shot, plate = fake
    out, lines = tmp_path / "out", []
    report = farm.run_farm(
        client, shot, plate, out, "1-20x2", 3, command_prefix=prefix, log=lines.append
    )
    frames = list(range(1, 20, 2))
    assert [e["frame"] for e in report["frames"]] == frames
    assert {e["status"] for e in report["frames"]} == {"rendered"}
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["fake.report.json", *(f"fake.{f:04d}.txt" for f in frames)]
    )
    assert json.loads((out / "fake.report.json").read_text()) == report
    assert report["shot"] == str(shot)
    chunks = report["farm"]["chunks"]
    assert [c["frames"] for c in chunks] == ["1-5x2", "7-11x2", "13-17x2", "19"]
    assert len({c["worker"] for c in chunks}) == 2  # both workers took chunks
    assert len([x for x in lines if "frames" in x and " on " in x]) == 4

    # Resumable: a second run renders nothing and reports every frame as skipped.
    again = farm.run_farm(client, shot, plate, out, "1-20x2", 3, command_prefix=prefix, log=None)
    assert {e["status"] for e in again["frames"]} == {"skipped"}


def test_run_farm_retries_a_crashed_chunk(client, fake, tmp_path):
    prefix, shot, plate = fake
    # The workers were started before this test: the marker goes through the command.
    prefix = ["env", f"FAKE_CRASH_ONCE={tmp_path / 'crashed'}", *prefix]
    report = farm.run_farm(client, shot, plate, tmp_path / "out", "1-4", 2, command_prefix=prefix)
    assert [e["frame"] for e in report["frames"]] == [1, 2, 3, 4]
    assert (tmp_path / "crashed").exists()

    prefix = ["env", f"FAKE_CRASH_ONCE={tmp_path / 'crashed2'}", *fake[0]]
    with pytest.raises(farm.FarmError, match="Segmentation fault") as info:
        farm.run_farm(
            client, shot, plate, tmp_path / "out2", "1-4", 4, command_prefix=prefix, retries=0
        )
    assert not info.value.bad_input


def test_run_farm_survives_a_lost_worker(client, fake, tmp_path):
    prefix, shot, plate = fake
    prefix = ["env", f"FAKE_KILL_WORKER_ONCE={tmp_path / 'killed'}", *prefix]
    out = tmp_path / "out"
    report = farm.run_farm(client, shot, plate, out, "1-6", 2, command_prefix=prefix)
    assert (tmp_path / "killed").exists()
    assert [e["frame"] for e in report["frames"]] == [1, 2, 3, 4, 5, 6]
    assert len(list(out.glob("fake.*.txt"))) == 6
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it for the next tests


def test_run_farm_bad_input_fails_fast_without_retries(client, fake, tmp_path):
    prefix, shot, _ = fake
    started = time.perf_counter()
    with pytest.raises(farm.FarmError, match="render_shot: error: plate not found") as info:
        farm.run_farm(
            client,
            shot,
            tmp_path / "missing.exr",
            tmp_path / "out",
            "1-40",
            2,
            command_prefix=prefix,
            retries=5,
        )
    assert info.value.bad_input
    assert time.perf_counter() - started < 20
    report = json.loads((tmp_path / "out/fake.report.json").read_text())
    assert report["farm"]["failed"]["error"].startswith("render_shot: error: plate not found")


def test_run_farm_refuses_options_it_owns(client, fake, tmp_path):
    prefix, shot, plate = fake
    with pytest.raises(ValueError, match="--report is set by the farm"):
        farm.run_farm(
            client,
            shot,
            plate,
            tmp_path,
            "1",
            1,
            command_prefix=prefix,
            extra_args=["--report", "x"],
        )
    with pytest.raises(ValueError, match="--rep is an abbreviation of --report"):
        farm.run_farm(
            client, shot, plate, tmp_path, "1", 1, command_prefix=prefix, extra_args=["--rep", "x"]
        )


# -- the real batch entry on the cluster ------------------------------------------------------

SHOT = textwrap.dedent(
    """
    import math, sys
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -6.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    sphere = bpy.context.active_object
    for frame, x in ((1, -1.0), (4, 1.0)):  # it moves: every frame differs
        sphere.location.x = x
        sphere.keyframe_insert("location", index=0, frame=frame)
    scene.frame_start, scene.frame_end = 1, 4
    scene.render.engine = "CYCLES"
    # Deterministic: a fixed seed, no denoiser, one thread.
    scene.cycles.samples = 2
    scene.cycles.seed = 0
    scene.cycles.use_animated_seed = False
    scene.cycles.use_denoising = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 1
    scene.view_settings.view_transform = "Standard"
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
    """
)
RENDER_ARGS = ("--scale", 5, "--resolution", 256, "--format", "exr")


def read_pixels(path):
    import OpenImageIO as oiio

    pixels = oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)
    assert pixels is not None and pixels.size, path
    return pixels


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    if importlib.util.find_spec("bpy") is None:
        pytest.skip("the bpy module is not installed in this environment")
    path = tmp_path_factory.mktemp("shot") / "shot.blend"
    r = subprocess.run(
        [sys.executable, "-c", SHOT, str(path)], capture_output=True, text=True, timeout=120
    )
    assert r.returncode == 0 and path.exists(), r.stdout[-2000:] + r.stderr[-2000:]
    return path


def test_farm_frames_match_one_machine(cluster, shot, tmp_path):
    pytest.importorskip("OpenImageIO", reason="OpenImageIO reads the frames back")
    on_farm, alone = tmp_path / "farm", tmp_path / "alone"
    t = time.perf_counter()
    r = cli(
        "--scheduler",
        cluster.scheduler_address,
        shot,
        "--plate",
        PLATE,
        "--out",
        on_farm,
        "--frames",
        "1-4",
        "--chunk",
        2,
        "--bpy",
        "--timeout",
        300,
        "--",
        *RENDER_ARGS,
        timeout=400,
    )
    farm_seconds = time.perf_counter() - t
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    t = time.perf_counter()
    single = subprocess.run(
        [
            sys.executable,
            "-m",
            "render_shot",
            shot,
            "--plate",
            PLATE,
            "--out",
            alone,
            "--frames",
            "1-4",
            *map(str, RENDER_ARGS),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=400,
    )
    alone_seconds = time.perf_counter() - t
    assert single.returncode == 0, single.stdout[-3000:] + single.stderr[-3000:]
    print(f"farm (2 workers, 2 chunks) {farm_seconds:.1f} s, one machine {alone_seconds:.1f} s")

    frames = sorted(p.name for p in on_farm.glob("shot.????.*"))
    assert frames == sorted(p.name for p in alone.glob("shot.????.*"))
    assert {n.split(".")[1] for n in frames} == {"0001", "0002", "0003", "0004"}
    for name in frames:
        a, b = read_pixels(on_farm / name), read_pixels(alone / name)
        assert a.shape == b.shape and (a == b).all(), f"{name} differs between farm and one machine"
    first, last = (read_pixels(on_farm / n) for n in (frames[0], frames[-1]))
    assert not (first == last).all()  # the frames are really frames 1 and 4

    report = json.loads((on_farm / "shot.report.json").read_text())
    assert [e["frame"] for e in report["frames"]] == [1, 2, 3, 4]
    assert [c["frames"] for c in report["farm"]["chunks"]] == ["1-2", "3-4"]
    assert not list(on_farm.glob(".*.tmp")) and not list(on_farm.glob("*.tmp"))


def test_farm_bad_plate_is_one_clear_line(cluster, shot, tmp_path):
    r = cli(
        "--scheduler",
        cluster.scheduler_address,
        shot,
        "--plate",
        tmp_path / "nope.exr",
        "--out",
        tmp_path / "out",
        "--frames",
        "1-4",
        "--chunk",
        2,
        "--bpy",
        "--",
        *RENDER_ARGS,
        timeout=300,
    )
    assert r.returncode == 2, r.stdout[-3000:] + r.stderr[-3000:]
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("farm: error: frames ") and "render_shot: error" in lines[0]
    assert "nope.exr" in lines[0]


def find_blender():
    """(command, why): a Blender binary the way tests/e2e finds one, or None and the reason."""
    folder = ROOT / "tests/e2e"
    spec = importlib.util.spec_from_file_location("vr_e2e_conftest", folder / "conftest.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(folder))  # its own helpers (gl_libraries) beside it
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(folder))
    return module.find_blender()


@pytest.mark.e2e
def test_farm_with_a_blender_binary(client, shot, tmp_path):
    command, why = find_blender()
    if command is None:
        pytest.skip(why)
    prefix = [*command, "-b", str(shot), "--python", str(ROOT / "render_shot.py"), "--"]
    report = farm.run_farm(
        client,
        shot,
        PLATE,
        tmp_path,
        "1-2",
        1,
        command_prefix=prefix,
        cwd=ROOT,
        extra_args=RENDER_ARGS,
        timeout=300,
    )
    assert [e["frame"] for e in report["frames"]] == [1, 2]
    assert report["complete"] and report["blender"] != ""
    assert sorted(p.name for p in tmp_path.glob("shot.*.exr")) == ["shot.0001.exr", "shot.0002.exr"]
