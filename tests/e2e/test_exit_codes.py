"""Issue 14, case 5: under a real Blender binary (`blender -b --python render_shot.py`) a
failure is never exit code 0. Blender itself returns 0 after a script's uncaught exception;
the entry catches everything and leaves Blender with its own code (sys.exit), and
`--python-exit-code 1` covers what happens before the entry runs."""

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import ROOT

pytestmark = pytest.mark.e2e


def entry(plate, out, *extra):
    return [
        "-b",
        "--factory-startup",
        "--python-exit-code",
        "1",
        "--python",
        ROOT / "render_shot.py",
        "--",
        "--plate",
        plate,
        "--out",
        out,
        "--engine",
        "CYCLES",
        "--samples",
        1,
        "--scale",
        10,
        "--resolution",
        256,
        "--objects",
        "Cube",
        *extra,
    ]


@pytest.fixture
def plate(tmp_path):
    path = tmp_path / "plate.png"
    buf = oiio.ImageBuf(oiio.ImageSpec(192, 108, 3, "uint8"))
    buf.set_pixels(oiio.ROI(), np.full((108, 192, 3), 120, np.uint8))
    assert buf.write(str(path))
    return path


def errors(r):
    return [line for line in r.stderr.splitlines() if line.startswith("render_shot:")]


def test_exit_codes_under_the_blender_binary(blender, plate, tmp_path):
    out = tmp_path / "out"
    r = blender(*entry(tmp_path / "missing.png", out))
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    assert len(errors(r)) == 1 and "Traceback" not in r.stderr

    r = blender(*entry(plate, out))
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert len(names) == 4 and "shot.report.json" in names, names  # 3 images and the report

    # The on-set HDRI asked for by name, in a shot whose world has none: one line, code 2.
    r = blender(*entry(plate, tmp_path / "out2", "--method", "ground", "--surroundings", "world"))
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    assert errors(r) == [
        "render_shot: error: --surroundings world: world 'World' has no Environment Texture "
        "with an image"
    ], r.stderr[-2000:]

    # A failure after writing began (a full disk, under the bpy module:
    # tests/blender/test_batch_failures.py) is exit code 1 the same way: the entry's sys.exit.
    # A script Blender cannot run at all: --python-exit-code makes that 1 too.
    r = blender(
        "-b",
        "--factory-startup",
        "--python-exit-code",
        "1",
        "--python",
        tmp_path / "no_such_script.py",
    )
    assert r.returncode == 1
