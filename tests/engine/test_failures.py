"""The engine CLI under the failures of issue 14 (docs/failures.md): a full disk, plate ==
output, suns beyond half floats, EXR windows, bad options, memory limits, signals, damaged
plates. Full disk: a file-size limit (RLIMIT_FSIZE) in the child, which makes every write
past it fail as ENOSPC would; memory: an address-space limit (RLIMIT_AS)."""

import os
import resource
import signal
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio
import pytest

from virtual_reflections import cli, imagefiles

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAPER = ("--method", "paper")
BBOX = ("--bbox", 60, 30, 100, 60)


def run(*args, fsize=None, address_space=None, timeout=120):
    def limits():
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a failed write, not a dead process
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
        if address_space is not None:
            resource.setrlimit(resource.RLIMIT_AS, (address_space, address_space))

    return subprocess.run(
        [sys.executable, "-m", "virtual_reflections", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=limits,
    )


def one_line(r):
    lines = r.stderr.strip().splitlines()
    return len(lines) == 1 and "Traceback" not in r.stderr


def write(path, pixels, fmt="uint8", spec=None):
    h, w, c = pixels.shape
    spec = spec or oiio.ImageSpec(w, h, c, fmt)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_image(np.ascontiguousarray(pixels))
    out.close()
    return path


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    """A noisy 160x90 plate (noise: its maps do not compress to nothing)."""
    rng = np.random.default_rng(1)
    path = tmp_path_factory.mktemp("plates") / "plate.png"
    return write(path, rng.integers(0, 256, (90, 160, 3), dtype=np.uint8))


def hidden(folder):
    return [p.name for p in folder.iterdir() if p.name.startswith(".")]


# 1, 14: a full disk never replaces a good file, never passes as success, is one line.
@pytest.mark.parametrize(
    "command,ext",
    [
        ("envmap", "png"),
        ("envmap", "exr"),
        ("envmap", "jpg"),
        ("envmap", "tif"),
        ("segment", "png"),
    ],
)
def test_full_disk_keeps_the_previous_file(plate, tmp_path, command, ext):
    out = tmp_path / f"map.{ext}"
    args = (command, plate, "-o", out, *BBOX, *PAPER, "--width", 1024)[
        : 9 if command == "segment" else 11
    ]
    first = run(*args)
    assert first.returncode == 0, first.stderr
    good = out.read_bytes()
    r = run(*args, fsize=20_000)
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    assert one_line(r), r.stderr
    assert "wrote" not in r.stdout
    assert out.read_bytes() == good
    assert hidden(tmp_path) == []


# 3: the plate is never overwritten by the map.
def test_plate_as_output_is_refused(plate, tmp_path):
    copy = tmp_path / "plate.png"
    copy.write_bytes(plate.read_bytes())
    for command in ("envmap", "segment"):
        r = run(command, copy, "-o", tmp_path / "." / "plate.png", *BBOX, *PAPER)
        assert r.returncode == 2 and one_line(r) and "plate itself" in r.stderr, r.stderr
        assert copy.read_bytes() == plate.read_bytes()


# 7: a sun brighter than half floats can hold stays finite in the default half-float map.
def test_half_float_map_is_finite_for_a_sun(tmp_path):
    pixels = np.full((90, 160, 3), 0.5, np.float32)
    pixels[5:15, 5:15] = 1e6  # a sun, in the outer ring
    plate = write(tmp_path / "sun.exr", pixels, "float")
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *BBOX, *PAPER, "--width", 256)
    assert r.returncode == 0, r.stderr
    assert "clamped" in r.stdout
    env = oiio.ImageBuf(str(tmp_path / "m.exr")).get_pixels(oiio.FLOAT)
    assert np.isfinite(env).all() and env.max() == 65504.0
    r = run("envmap", plate, "-o", tmp_path / "f.exr", *BBOX, *PAPER, "--width", 256, "--float")
    assert oiio.ImageBuf(str(tmp_path / "f.exr")).get_pixels(oiio.FLOAT).max() > 1e5


# 8: the plate is the display window.
def test_exr_data_window_is_placed_in_the_display_window(tmp_path):
    rng = np.random.default_rng(2)
    full = rng.random((90, 160, 3), dtype=np.float32)
    full[:, :40] = 0.0  # what the data window leaves out is black
    whole = write(tmp_path / "whole.exr", full, "float")
    spec = oiio.ImageSpec(120, 90, 3, "float")
    spec.x, spec.full_x, spec.full_y, spec.full_width, spec.full_height = 40, 0, 0, 160, 90
    windowed = write(tmp_path / "windowed.exr", np.ascontiguousarray(full[:, 40:]), spec=spec)
    a = imagefiles.read_plate(str(whole)).pixels
    b = imagefiles.read_plate(str(windowed)).pixels
    assert b.shape == (90, 160, 3)
    np.testing.assert_array_equal(a, b)


# 11: every option checked up front, one line, exit 2.
@pytest.mark.parametrize(
    "extra",
    [
        ("--width", 0),
        ("--width", 100000),
        ("--width", -8),
        ("--bbox", "nan", 1, 5, 5),
        ("--bbox", 1, 1, "inf", 5),
    ],
)
def test_bad_options_are_one_line(plate, tmp_path, extra):
    bbox = () if extra[0] == "--bbox" else BBOX
    started = time.perf_counter()
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *bbox, *PAPER, *extra)
    assert r.returncode == 2 and one_line(r), r.stderr
    assert time.perf_counter() - started < 20 and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("abbreviation", [("--wid", 64), ("--meth", "paper"), ("--flo",)])
def test_abbreviated_options_are_refused(plate, tmp_path, abbreviation):
    # issue 40, row 30: argparse's prefix matching took `--wid` for `--width`.
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *BBOX, *PAPER, *abbreviation)
    assert r.returncode == 2 and one_line(r), r.stderr
    assert f"unrecognized arguments: {abbreviation[0]}" in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_negative_bbox_in_exponent_notation(plate, tmp_path):
    # 14: "-1e2" is a number, not an unknown option.
    r = run(
        "envmap",
        plate,
        "-o",
        tmp_path / "m.exr",
        "--bbox",
        "-1e2",
        "-1e1",
        100,
        60,
        *PAPER,
        "--width",
        64,
    )
    assert r.returncode == 0, r.stderr


# 12: a job that cannot fit is refused at once; running out anyway is one line, exit 1.
def test_a_job_larger_than_memory_is_refused_up_front(tmp_path):
    # A valid 300-megapixel plate: its display window is 20000x15000, one stored pixel.
    spec = oiio.ImageSpec(1, 1, 3, "half")
    spec.full_width, spec.full_height, spec.x, spec.y = 20000, 15000, 5, 5
    big = write(tmp_path / "big.exr", np.ones((1, 1, 3), np.float16), spec=spec)
    started = time.perf_counter()
    r = run(
        "envmap",
        big,
        "-o",
        tmp_path / "m.exr",
        "--bbox",
        9000,
        7000,
        11000,
        8000,
        *PAPER,
        address_space=3 << 30,
    )
    assert r.returncode == 1 and one_line(r), r.stderr
    assert "memory" in r.stderr and "20000x15000" in r.stderr
    assert time.perf_counter() - started < 20
    assert [p.name for p in tmp_path.iterdir()] == ["big.exr"]


def test_out_of_memory_is_one_line_exit_1(plate, tmp_path, monkeypatch, capsys):
    def no_memory(*_args, **_kwargs):
        raise MemoryError()

    monkeypatch.setattr("virtual_reflections.envmap.apply_table", no_memory)
    code = cli.main(["envmap", str(plate), "-o", str(tmp_path / "m.exr"), *map(str, BBOX), *PAPER])
    err = capsys.readouterr().err
    assert code == 1 and len(err.strip().splitlines()) == 1 and "memory" in err


# 13: SIGTERM and SIGKILL leave nothing behind.
@pytest.mark.parametrize(
    "sig,code,word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")]
)
def test_a_signal_is_one_line_and_leaves_no_temp(
    plate, tmp_path, monkeypatch, capsys, sig, code, word
):
    """SIGTERM or Ctrl-C arrives while the map is being written (the writer signals its own
    process)."""
    write_oiio = imagefiles._write_oiio  # noqa: SLF001 - the test wraps the writer

    def write_then_terminated(path, *args):
        write_oiio(path, *args)
        assert os.path.exists(path)  # the temporary file, half the job done
        os.kill(os.getpid(), sig)
        time.sleep(5)  # the handler raises here

    monkeypatch.setattr(imagefiles, "_write_oiio", write_then_terminated)
    result = cli.main(
        [
            "envmap",
            str(plate),
            "-o",
            str(tmp_path / "m.png"),
            *map(str, BBOX),
            *PAPER,
            "--width",
            "64",
        ]
    )
    assert result == code
    assert capsys.readouterr().err.strip() == f"virtual_reflections: {word}"
    assert list(tmp_path.iterdir()) == []


def test_a_killed_writers_temp_file_is_removed_by_the_next_write(plate, tmp_path):
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    ).stdout.strip()
    stale = tmp_path / f".m.{dead}.tmp.png"
    stale.write_bytes(b"half a png")
    r = run("envmap", plate, "-o", tmp_path / "m.png", *BBOX, *PAPER, "--width", 64)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png"]


# 14: damaged and odd plates are refused with one line.
def test_truncated_plate_is_refused(plate, tmp_path):
    rng = np.random.default_rng(3)
    jpeg = write(tmp_path / "p.jpg", rng.integers(0, 256, (90, 160, 3), dtype=np.uint8))
    data = jpeg.read_bytes()
    jpeg.write_bytes(data[: len(data) // 2])
    png = tmp_path / "p.png"
    png.write_bytes(plate.read_bytes()[: plate.stat().st_size // 2])
    for damaged in (jpeg, png):
        r = run("envmap", damaged, "-o", tmp_path / "m.exr", *BBOX, *PAPER)
        assert r.returncode == 2 and one_line(r), r.stderr
        assert not (tmp_path / "m.exr").exists()


def test_folder_and_depth_only_plates_are_named(tmp_path):
    r = run("envmap", tmp_path, "-o", tmp_path / "m.exr", *BBOX, *PAPER)
    assert r.returncode == 2 and one_line(r) and "is a folder" in r.stderr, r.stderr
    spec = oiio.ImageSpec(160, 90, 1, "float")
    spec.channelnames = ("Z",)
    depth = write(tmp_path / "depth.exr", np.ones((90, 160, 1), np.float32), spec=spec)
    r = run("envmap", depth, "-o", tmp_path / "m.exr", *BBOX, *PAPER)
    assert r.returncode == 2 and one_line(r) and "no colour channels" in r.stderr, r.stderr


def test_sigterm_inside_a_callback_from_c_still_ends_the_run(plate, tmp_path, monkeypatch, capsys):
    """A SIGTERM whose exception is raised inside a callback from C (the optional compiled back
    end caches a kernel through one; Python cannot pass the exception on there and would print
    it and go on) is held and raised when the work returns: one line, exit code 143; and as
    the process ends, what the interrupted work left half made prints nothing."""
    from virtual_reflections import interrupts

    def envmap_then_callback(args):
        # What Python does with an exception raised in a callback from C.
        sys.unraisablehook(type("Info", (), {"exc_value": cli.Terminated()})())

    monkeypatch.setattr(cli, "run_envmap", envmap_then_callback)
    previous = sys.unraisablehook
    try:
        code = cli.main(["envmap", str(plate), "-o", str(tmp_path / "m.exr"), *map(str, BBOX)])
        err = capsys.readouterr().err
        assert code == 143 and err.strip() == "virtual_reflections: terminated", err
        assert sys.unraisablehook is interrupts.silent  # the way out prints nothing more
    finally:
        sys.unraisablehook = previous
    seen = []
    hook = interrupts.hold_interrupts(seen.append, held := [])
    hook(type("Info", (), {"exc_value": RuntimeError("not an interrupt")})())
    assert not held and len(seen) == 1  # other unraisable errors are still printed


# Issue 40: plates and options that passed the checks and failed later.
def write_channels(path, names, values, fmt="half"):
    """A 160x90 EXR whose channels `names` hold the constants `values`."""
    spec = oiio.ImageSpec(160, 90, len(names), fmt)
    spec.channelnames = tuple(names)
    pixels = np.empty((90, 160, len(names)), np.float32)
    pixels[...] = values
    return write(path, pixels.astype(np.float16 if fmt == "half" else np.float32), spec=spec)


def test_layered_exr_plate_reads_its_colour_layer(tmp_path):
    # 25: depth.Z, diffuse.R/G/B: the colour layer is the plate, not depth as red.
    plate = write_channels(
        tmp_path / "layers.exr", ("depth.Z", "diffuse.R", "diffuse.G", "diffuse.B"), (9, 1, 2, 3)
    )
    np.testing.assert_allclose(imagefiles.read_plate(str(plate)).pixels[0, 0], (1, 2, 3))
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *BBOX, *PAPER, "--width", 64)
    assert r.returncode == 0, r.stderr
    env = oiio.ImageBuf(str(tmp_path / "m.exr")).get_pixels(oiio.FLOAT)
    np.testing.assert_allclose(env.reshape(-1, 3).mean(0), (1, 2, 3), rtol=1e-3)
    # An unnamed R, G, B beside other layers is the picture.
    names = ("R", "G", "B", "depth.Z", "spec.R", "spec.G", "spec.B")
    plate = write_channels(tmp_path / "main.exr", names, (4, 5, 6, 9, 7, 7, 7))
    np.testing.assert_allclose(imagefiles.read_plate(str(plate)).pixels[0, 0], (4, 5, 6))


def test_several_colour_layers_are_refused_by_name(tmp_path):
    # 25: which of two colour layers is the plate is the artist's choice, not the reader's.
    names = ("diffuse.R", "diffuse.G", "diffuse.B", "spec.R", "spec.G", "spec.B")
    plate = write_channels(tmp_path / "two.exr", names, (1, 2, 3, 4, 5, 6))
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *BBOX, *PAPER)
    assert r.returncode == 2 and one_line(r), r.stderr
    assert "diffuse" in r.stderr and "spec" in r.stderr
    assert list(tmp_path.iterdir()) == [plate]


def test_width_beyond_the_compact_form_is_refused_up_front(plate, tmp_path):
    # 35: a --width whose table the compact form cannot hold is refused before any work (under
    # a 2 GiB address space, which that work would need many times over).
    for layout, width in (("latlong", 16384), ("cube", 8192)):
        r = run(
            "envmap",
            plate,
            "-o",
            tmp_path / "m.exr",
            *BBOX,
            *PAPER,
            "--layout",
            layout,
            "--width",
            width,
            address_space=2 << 30,
        )
        assert r.returncode == 2 and one_line(r), r.stderr
        assert "--width" in r.stderr and str(width) in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_largest_width_fits_the_compact_form():
    # 35: the largest --width's table fits the compact form, the next size does not.
    from virtual_reflections import layouts, table, trilinear

    for layout, step in (("latlong", 2), ("cube", 1)):
        largest = cli.WIDTH_RANGE[layout][1]
        assert largest == table.max_size(layout)
        h, w = layouts.map_shape(layout, largest)
        assert h * w <= trilinear.MAX_TEXELS
        h, w = layouts.map_shape(layout, largest + step)
        assert h * w > trilinear.MAX_TEXELS


def test_data_window_larger_than_memory_is_refused_up_front(tmp_path):
    # 36: an 8x8 picture whose data window is 16000x16000: the stored pixels count too.
    spec = oiio.ImageSpec(16000, 16000, 3, "half")
    spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, 8, 8
    spec.attribute("compression", "rle")  # zeros: a 24 MB file
    path = tmp_path / "wide.exr"
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    rows = np.zeros((500, 16000, 3), np.float16)
    for y in range(0, 16000, 500):
        assert out.write_scanlines(y, y + 500, 0, rows)
    out.close()
    r = run(
        "envmap",
        path,
        "-o",
        tmp_path / "m.exr",
        "--bbox",
        2,
        2,
        6,
        6,
        *PAPER,
        address_space=3 << 30,
    )
    assert r.returncode == 1 and one_line(r), r.stderr
    assert "memory" in r.stderr and "16000x16000" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wide.exr"]


def write_deep(path):
    """A 16x8 deep EXR, one sample a pixel."""
    spec = oiio.ImageSpec(16, 8, 5, "float")
    spec.channelnames = ("R", "G", "B", "A", "Z")
    spec.deep = True
    deep = oiio.DeepData()
    deep.init(spec)
    for pixel in range(16 * 8):
        deep.set_samples(pixel, 1)
        for c in range(5):
            deep.set_deep_value(pixel, c, 0, 0.5)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec) and out.write_deep_image(deep)
    out.close()
    return path


def test_deep_exr_plate_is_refused(tmp_path):
    # 37: a deep EXR is named as one, not "read_native_scanlines without an open file".
    plate = write_deep(tmp_path / "deep.exr")
    for command in ("envmap", "segment"):
        r = run(command, plate, "-o", tmp_path / "m.png", "--bbox", 2, 2, 6, 6, *PAPER)
        assert r.returncode == 2 and one_line(r), r.stderr
        assert "deep" in r.stderr and "flatten" in r.stderr
    assert list(tmp_path.iterdir()) == [plate]


def test_ground_method_is_refused_up_front(plate, tmp_path):
    # 40: the ground method needs the object's place in a scene, which the command line
    # cannot give: --method offers the methods it can run.
    r = run("envmap", plate, "-o", tmp_path / "m.exr", *BBOX, "--method", "ground", "--hfov", 50)
    assert r.returncode == 2 and one_line(r), r.stderr
    assert "--method" in r.stderr and "camera" in r.stderr and "paper" in r.stderr
    assert "up" not in r.stderr.split()  # no internal parameter named
    assert list(tmp_path.iterdir()) == []


def test_kernel_cache_is_kept_in_the_users_cache_folder(tmp_path):
    # 41: compiled kernels are cached in the user's cache folder (or NUMBA_CACHE_DIR), never
    # in the package folder, which an installed extension may not write and an update replaces.
    pytest.importorskip("numba")  # requirements/*.txt install it: CI runs this
    import shutil

    package = tmp_path / "copy" / "virtual_reflections"
    shutil.copytree(
        os.path.join(ROOT, "virtual_reflections"),
        package,
        ignore=shutil.ignore_patterns("__pycache__"),
    )
    script = (
        "import sys; import numpy as np; sys.path.insert(0, sys.argv[1]);"
        "from virtual_reflections import backends; k = backends.kernels();"
        "backends.run(k.halve, np.ones((8, 8, 3), np.float32), np.zeros((4, 4, 3), np.float32))"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    cases = (
        dict(env, XDG_CACHE_HOME=str(tmp_path / "xdg")),  # the default
        dict(env, XDG_CACHE_HOME=str(tmp_path / "xdg2"), NUMBA_CACHE_DIR=str(tmp_path / "nb")),
    )
    for environ in cases:
        proc = subprocess.run(
            [sys.executable, "-c", script, str(package.parent)],
            capture_output=True,
            text=True,
            env=environ,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
    assert not [p.name for p in package.rglob("*.nb[ic]")]
    assert list((tmp_path / "xdg" / "virtual-reflections" / "numba").rglob("*.nbi"))
    assert list((tmp_path / "nb").rglob("*.nbi"))
    assert not (tmp_path / "xdg2").exists()
