"""Which objects the batch makes reflect when none is marked (batch_render.shot_objects):
every visible object with a surface but the ground they stand on (floor.grounds_among): a
shadow catcher, the chosen Ground object, the flat floor under them; a marked one reflects."""

import json
import pathlib
import subprocess
import sys

import bpy
import pytest
from sequence_shots import build_scene, write_plates
from shots import addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]


def plane(name, z=-0.6, size=20.0, catcher=False):
    bpy.ops.mesh.primitive_plane_add(size=size, location=(0.0, 0.0, z))
    obj = bpy.context.active_object
    obj.name, obj.is_shadow_catcher = name, catcher
    return obj


@pytest.fixture
def shot_objects(addon):
    return addon_part("operators.batch.render").shot_objects


def names(objects):
    return sorted(o.name for o in objects)


def test_a_shadow_catcher_and_the_floor_are_not_mirrors(shot_objects):
    sphere = build_scene()
    sphere.virtual_reflections.enabled = False
    scene = bpy.context.scene
    catcher = plane("Catcher", catcher=True)
    assert names(shot_objects(scene, None)) == [sphere.name]
    catcher.is_shadow_catcher = False  # now a plain floor under the sphere
    assert names(shot_objects(scene, None)) == [sphere.name]
    bpy.ops.mesh.primitive_cube_add(size=0.5, location=(2.0, 0.0, 0.0))  # not flat: a mirror
    cube = bpy.context.active_object
    assert names(shot_objects(scene, None)) == names([sphere, cube])
    scene.virtual_reflections.ground_object = cube  # the chosen Ground: not a mirror
    assert names(shot_objects(scene, None)) == [sphere.name]
    catcher.virtual_reflections.enabled = True  # marked: it reflects, and only it
    assert names(shot_objects(scene, None)) == ["Catcher"]
    assert names(shot_objects(scene, ["Catcher", cube.name])) == names([catcher, cube])


def test_batch_updates_one_map_over_a_shadow_catcher(clean_file, tmp_path):
    """The issue's shot: one unmarked sphere over a shadow catcher, two frames: one map each,
    and no warning that the ground covers the plate."""
    plates = write_plates(tmp_path, size=(48, 24))
    build_scene(frames=2)  # the add-on is not registered here: the sphere is not marked
    plane("Catcher", catcher=True)
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    plate = str(plates[0]).replace("0001", "####")
    args = [blend, "--plate", plate, "--out", out, "--frames", "1-2", "--resolution", 256]
    r = subprocess.run(
        [sys.executable, "-m", "render_shot", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "shot.report.json").read_text())
    updated = [e["changes"]["maps_updated"] for e in report["frames"]]
    assert [len(u) for u in updated] == [1, 1], updated
    assert "Ground covers" not in r.stdout + r.stderr
