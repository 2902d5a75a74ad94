"""The command line's contract: options, exit codes, outputs, no partial files."""

import argparse
import os
import subprocess
import sys

import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


PAPER = ("--method", "paper")


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "virtual_reflections", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    path = tmp_path_factory.mktemp("plates") / "plate.png"
    y, x = np.mgrid[0:90, 0:160]
    pixels = np.stack([x * 255 // 160, y * 255 // 90, np.full_like(x, 90)], -1).astype(np.uint8)
    buf = oiio.ImageBuf(oiio.ImageSpec(160, 90, 3, "uint8"))
    buf.set_pixels(oiio.ROI(), pixels)
    buf.write(str(path))
    return path


def test_envmap_writes_each_format(plate, tmp_path):
    for name, layout, shape in (
        ("m.exr", "latlong", (64, 128)),
        ("c.exr", "cube", (96, 16)),
        ("m.hdr", "latlong", (64, 128)),
        ("m.png", "latlong", (64, 128)),
        ("m.jpg", "latlong", (64, 128)),
        ("m.tif", "cube", (96, 16)),
    ):
        width = 128 if layout == "latlong" else 16
        r = run(
            "envmap",
            plate,
            "-o",
            tmp_path / name,
            "--bbox",
            60,
            30,
            100,
            60,
            "--layout",
            layout,
            "--width",
            width,
            "--triangles",
            32,
            "--enlarge",
            0.05,
            "--border",
            0.1,
            "--method",
            "paper",
        )
        assert r.returncode == 0, r.stderr
        spec = oiio.ImageInput.open(str(tmp_path / name)).spec()
        assert (spec.height, spec.width) == shape, name
    header = OpenEXR.File(str(tmp_path / "c.exr"), header_only=True).header()
    assert header["envmap"] == OpenEXR.ENVMAP_CUBE


def test_segment_writes_an_overlay(plate, tmp_path):
    r = run(
        "segment", plate, "-o", tmp_path / "seg.png", "--bbox", 60, 30, 100, 60, "--triangles", 16
    )
    assert r.returncode == 0, r.stderr
    assert oiio.ImageInput.open(str(tmp_path / "seg.png")).spec().width == 160


@pytest.mark.parametrize(
    "args",
    [
        ("envmap", "{missing}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--hfov", 60),
        ("envmap", "{corrupt}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--hfov", 60),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 50, 1, 40, 5, "--hfov", 60),  # X0 >= X1
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 50, 1, 50, 5, "--method", "paper"),
        ("envmap", "{plate}", "-o", "{tmp}/m.webpx", "--bbox", 1, 1, 5, 5, "--hfov", 60),
        ("envmap", "{plate}", "-o", "{tmp}/nowhere/m.exr", "--bbox", 1, 1, 5, 5, "--hfov", 60),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--triangles", 6, *PAPER),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, "--hfov", 60),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--width", 7, *PAPER),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--hfov", 200),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--method", "mirror"),
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5),  # camera without --hfov
        ("envmap", "{plate}", "-o", "{out}", "--bbox", 1, 1, 5, 5, "--method", "frustum"),
        ("segment", "{missing}", "-o", "{tmp}/s.png", "--bbox", 1, 1, 5, 5),
        ("frobnicate",),
    ],
)
def test_bad_input_is_one_line_exit_2_and_no_file(plate, tmp_path, args):
    corrupt = tmp_path / "corrupt.jpg"
    corrupt.write_bytes(b"\xff\xd8\xff\xe0 not really a jpeg")
    subs = dict(
        missing=tmp_path / "missing.png",
        corrupt=corrupt,
        plate=plate,
        out=tmp_path / "out.exr",
        tmp=tmp_path,
    )
    r = run(*(str(a).format(**{k: str(v) for k, v in subs.items()}) for a in args))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corrupt.jpg"]


def test_unwritable_output_leaves_nothing(plate, tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    # Root may write anywhere it has permission bits for; /proc refuses new files to all.
    target = locked if not os.access(locked, os.W_OK) else "/proc"
    try:
        r = run("envmap", plate, "-o", f"{target}/m.exr", "--bbox", 1, 1, 5, 5, "--hfov", 60)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not os.path.exists(f"{target}/m.exr") and list(locked.iterdir()) == []
    finally:
        locked.chmod(0o700)


def read_map(path):
    return oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)


def test_the_default_method_is_camera(plate, tmp_path):
    common = ("-o", "--bbox", 60, 30, 100, 60, "--width", 64, "--hfov", 60, "--float")
    maps = {}
    for name, extra in (("default", ()), ("camera", ("--method", "camera")), ("paper", PAPER)):
        out = tmp_path / f"{name}.exr"
        r = run("envmap", plate, common[0], out, *common[1:], *extra)
        assert r.returncode == 0, r.stderr
        maps[name] = read_map(out)
    np.testing.assert_array_equal(maps["default"], maps["camera"])
    assert np.abs(maps["default"] - maps["paper"]).max() > 0.05


def test_frustum_is_an_alias_of_camera(plate, tmp_path):
    maps = {}
    for method in ("camera", "frustum"):
        out = tmp_path / f"{method}.exr"
        r = run(
            "envmap", plate, "-o", out, "--bbox", 60, 30, 100, 60, "--width", 64,
            "--hfov", 55, "--method", method, "--float",
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        maps[method] = read_map(out)
    np.testing.assert_array_equal(maps["camera"], maps["frustum"])


@pytest.mark.parametrize("method", [(), ("--method", "camera"), ("--method", "frustum")])
def test_camera_without_hfov_is_one_line_exit_2(plate, tmp_path, method):
    r = run("envmap", plate, "-o", tmp_path / "m.exr", "--bbox", 60, 30, 100, 60, *method)
    assert r.returncode == 2
    (line,) = r.stderr.strip().splitlines()
    assert "--method camera needs --hfov" in line and "--method paper" in line, line
    assert list(tmp_path.iterdir()) == []


def test_segment_needs_no_hfov(plate, tmp_path):
    """segment draws the paper's regions, so the camera default asks for nothing more."""
    r = run("segment", plate, "-o", tmp_path / "s.png", "--bbox", 60, 30, 100, 60)
    assert r.returncode == 0, r.stderr


def test_every_option_says_what_it_does():
    from virtual_reflections.cli import build_parser

    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in commands.choices.items():
        silent = [a.dest for a in sub._actions if a.dest != "help" and not (a.help or "").strip()]
        assert not silent, (name, silent)
    assert set(commands.choices) == {"envmap", "segment"}


def test_a_one_shot_map_runs_on_numpy_without_loading_numba(tmp_path):
    """Issue 42: one map per process is faster on NumPy than after loading Numba's kernels
    (benchmarks/cli_backend_bench.py): the command line does not import Numba unless
    VR_GATHER asks for it."""
    pytest.importorskip("numba")  # requirements/blender45.txt installs it: CI runs this
    plate = tmp_path / "plate.png"
    from virtual_reflections.imagefiles import write_rgba

    write_rgba(str(plate), np.full((24, 32, 4), 0.5, np.float32))
    script = (
        "import sys; from virtual_reflections import cli;"
        "code = cli.main(sys.argv[1:]); print('numba' in sys.modules); sys.exit(code)"
    )
    args = ["envmap", str(plate), "-o", str(tmp_path / "m.exr"), "--bbox", "8", "6", "20", "18"]
    args += ["--hfov", "50", "--width", "64"]
    for gather, loaded in (("", "False"), ("numba", "True")):
        env = {k: v for k, v in os.environ.items() if k != "VR_GATHER"}
        if gather:
            env["VR_GATHER"] = gather
        r = subprocess.run([sys.executable, "-c", script, *args], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        assert r.stdout.split()[-1] == loaded, (gather, r.stdout)


def test_the_command_lines_preference_ends_with_the_call(tmp_path):
    """Called in a process that goes on (a test, a script): the NumPy preference is the
    call's own; the process's back end afterwards is what it was."""
    from virtual_reflections import backends, cli
    from virtual_reflections.imagefiles import write_rgba

    plate = tmp_path / "plate.png"
    write_rgba(str(plate), np.full((24, 32, 4), 0.5, np.float32))
    before = backends.backend()
    args = ["envmap", str(plate), "-o", str(tmp_path / "m.exr"), "--bbox", "8", "6", "20", "18"]
    assert cli.main([*args, "--hfov", "50", "--width", "64"]) == 0
    assert backends.backend() == before
