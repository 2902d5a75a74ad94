"""The batch and a shot whose maps are saved as files (issue 40): the batch writes nothing
outside --out, never the shot's own maps, even where the shot's folder is read-only (a farm)."""

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
