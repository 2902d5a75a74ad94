"""The batch and a shot whose maps are saved as files (issue 40): the batch writes nothing
outside --out, never the shot's own maps, even where the shot's folder is read-only (a farm)."""

import json
import os
import pathlib
import shutil
import stat
import subprocess
import sys

import bpy
import pytest
from sequence_shots import build_scene, write_plates

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture
def saved_maps_shot(addon, tmp_path):
    """shot/shot.blend with its maps saved as files beside it (shot/vr_maps/), and plates."""
    plates = write_plates(tmp_path / "plates")
    sphere = build_scene()
    scene = bpy.context.scene
    settings = scene.virtual_reflections
    settings.plate_image = bpy.data.images.load(str(plates[0]))
    settings.map_storage = "FILES"
    settings.resolution = "256"
    folder = tmp_path / "shot"
    folder.mkdir()
    blend = folder / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    bpy.ops.object.select_all(action="DESELECT")
    sphere.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}, settings.last_report
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    assert list((folder / "vr_maps").glob("*.exr")), "the shot's maps were not saved beside it"
    return blend, plates


def snapshot(folder):
    """Every file under ``folder``: relative path -> (bytes, inode, mtime)."""
    found = {}
    for path in sorted(pathlib.Path(folder).rglob("*")):
        if path.is_file():
            info = path.stat()
            key = str(path.relative_to(folder))
            found[key] = (path.read_bytes(), info.st_ino, info.st_mtime_ns)
    return found


def run_read_only(folder, *args):
    """render_shot with ``folder`` (and all under it) read-only: chmod, and for root (whom
    permissions do not stop) a read-only bind mount in a mount namespace of its own, so a
    write there fails as on a farm's read-only share ([Errno 30])."""
    for path in [folder, *pathlib.Path(folder).rglob("*")]:
        mode = stat.S_IMODE(path.stat().st_mode)
        path.chmod(mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    cmd = [sys.executable, "-m", "render_shot", *map(str, args)]
    if os.geteuid() == 0:
        assert shutil.which("unshare"), "root needs unshare(1) to make the folder read-only"
        mount = 'mount --bind -o ro "$0" "$0" && exec "$@"'
        cmd = ["unshare", "-m", "sh", "-c", mount, str(folder), *cmd]
    try:
        return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    finally:
        for path in [folder, *pathlib.Path(folder).rglob("*")]:
            path.chmod(stat.S_IMODE(path.stat().st_mode) | stat.S_IWUSR)


@pytest.mark.parametrize("frames", [None, "1-2"], ids=["one frame", "frame range"])
def test_batch_leaves_a_read_only_shots_saved_maps_alone(saved_maps_shot, tmp_path, frames):
    blend, plates = saved_maps_shot
    folder = blend.parent
    before = snapshot(folder)
    out = tmp_path / "out"
    if frames is None:
        args = ("--plate", plates[1])  # another plate: maps unlike the saved ones
    else:
        args = ("--plate", str(plates[0]).replace("0001", "####"), "--frames", frames)
    r = run_read_only(folder, blend, *args, "--out", out, "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "Errno" not in r.stderr
    assert snapshot(folder) == before  # byte-identical, not even replaced by the same bytes
    # The maps the batch made are under --out.
    made = sorted(p.name for p in (out / "vr_maps").rglob("*.exr"))
    assert made == ["VR_Map_Sphere.exr"], made


def sphere_rgb(path):
    """Mean RGB of the frame's middle third (the sphere) of a render."""
    from sequence_shots import read

    pixels = read(path)
    h, w = pixels.shape[:2]
    return pixels[h // 3 : 2 * h // 3, w // 3 : 2 * w // 3, :3].reshape(-1, 3).mean(0)


@pytest.mark.parametrize("frames", [None, "2"], ids=["one frame", "frame range"])
def test_batch_makes_a_missing_saved_map_again_and_says_so(saved_maps_shot, tmp_path, frames):
    """The shot's saved map deleted (or left behind when the shot moved): the batch says so
    and makes it again, never a magenta sphere."""
    blend, plates = saved_maps_shot
    (blend.parent / "vr_maps" / "VR_Map_Sphere.exr").unlink()
    out = tmp_path / "out"
    if frames is None:
        args, render = ("--plate", plates[1]), out / "shot_render.exr"
    else:
        pattern = str(plates[0]).replace("0001", "####")
        args, render = ("--plate", pattern, "--frames", frames), out / "shot_render.0002.exr"
    r = subprocess.run(
        [sys.executable, "-m", "render_shot", blend, *map(str, args), "--out", out],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    if frames is None:  # one frame: its log; a range: its report
        said = [line for line in r.stdout.splitlines() if "warning: " in line]
    else:
        said = json.loads((out / "shot.report.json").read_text())["warnings"]
    said = [line for line in said if "missing" in line]
    assert said and "VR Map Sphere" in said[0] and "made again" in said[0], r.stdout[-2000:]
    red, green, blue = sphere_rgb(render)
    assert green > red and green > blue  # plate 2 is green; a missing map renders magenta
    assert not list(blend.parent.glob("vr_maps/*"))  # nothing written beside the shot
