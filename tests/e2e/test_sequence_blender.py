"""Sequence plates in a real Blender: the batch entry with --frames under `blender -b`, and an
interactive animation render (F12 in Blender's window, Xvfb) with live update, whose handlers
run on the render job's thread. Skipped with the reason when Blender or xvfb-run is missing."""

import json
import shutil
from pathlib import Path

import pytest
from gl_libraries import skip_without_gl

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

SHOT_SCRIPT = r"""
import bpy, sys
root, folder = sys.argv[sys.argv.index("--") + 1 :]
sys.path.insert(0, root + "/tests/blender")
from sequence_shots import build_scene, write_plates
bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
write_plates(folder)
build_scene()
bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
"""

F12_SCRIPT = r"""
import bpy, importlib.util, json, sys, threading
root, folder = sys.argv[sys.argv.index("--") + 1 :]
sys.path.insert(0, root + "/tests/blender")
from sequence_shots import COLOURS, build_scene, read, write_plates
spec = importlib.util.spec_from_file_location("vr_f12_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
seq = sys.modules["vr_f12_addon.operators.sequence"]
generate = sys.modules["vr_f12_addon.operators.generate"]
result = {"frames": []}

def record(scene, depsgraph=None):  # after ours: Python state only, safe on any thread
    result["frames"].append({
        "frame": scene.frame_current,
        "main": threading.current_thread() is threading.main_thread(),
        "job": bpy.app.is_job_running("RENDER"),
        "status": seq.status(scene),
    })

def finish():
    if bpy.app.is_job_running("RENDER"):
        return 0.2
    try:
        colours = []
        for frame in (1, 2, 3):
            rgba = read(f"{folder}/f12_{frame:04d}.exr")
            colours.append(rgba[rgba[..., 3] > 0.99][:, :3].mean(0).tolist())
        result["colours"] = colours
    except Exception as exc:
        result["error"] = repr(exc)
    print("RESULT=" + json.dumps(result), flush=True)
    addon.unregister()
    bpy.ops.wm.quit_blender()

def start():
    try:
        win = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=win):
            for obj in list(bpy.data.objects):
                bpy.data.objects.remove(obj)
            plates = write_plates(folder)
            scene = bpy.context.scene
            sphere = build_scene()
            image = bpy.data.images.load(str(plates[0]))
            image.source = "SEQUENCE"
            scene.virtual_reflections.plate_image = image
            scene.virtual_reflections.resolution = "256"
            scene.frame_set(1)

            generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [sphere])
            scene.virtual_reflections.sequence = True
            result["lock"] = scene.render.use_lock_interface
            bpy.app.handlers.frame_change_post.append(record)
            scene.render.use_compositing = False
            scene.render.film_transparent = True
            scene.render.image_settings.file_format = "OPEN_EXR"
            scene.render.filepath = folder + "/f12_"
            result["invoke"] = sorted(bpy.ops.render.render("INVOKE_DEFAULT", animation=True))
    except Exception as exc:
        result["error"] = repr(exc)
    bpy.app.timers.register(finish, first_interval=0.5)

bpy.app.timers.register(start, first_interval=0.5)
"""


def test_frames_under_blender_b(blender, tmp_path):
    script = tmp_path / "shot.py"
    script.write_text(SHOT_SCRIPT)
    r = blender("-b", "--python", script, "--", ROOT, tmp_path)
    assert r.returncode == 0 and (tmp_path / "shot.blend").exists(), r.stderr[-2000:]
    out = tmp_path / "out"
    args = ["--plate", tmp_path / "plate.%04d.png", "--out", out, "--resolution", 256]
    r = blender("-b", tmp_path / "shot.blend", "--python", ROOT / "render_shot.py", "--", *args)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]  # the scene's range, 1-3
    assert [x.split()[1] for x in r.stdout.splitlines() if x.startswith("frame ")] == [
        "1/3",
        "2/3",
        "3/3",
    ]
    report = json.loads((out / "shot.report.json").read_text())
    assert report["complete"] and [e["frame"] for e in report["frames"]] == [1, 2, 3]
    for frame in (1, 2, 3):
        assert (out / f"shot.{frame:04d}.exr").exists()
    r = blender(
        "-b", tmp_path / "shot.blend", "--python", ROOT / "render_shot.py", "--", *args,
        "--frames", "2-4",
    )  # fmt: skip
    assert r.returncode == 2
    errors = [x for x in r.stderr.splitlines() if x.startswith("render_shot: error")]
    assert len(errors) == 1 and "plate frame 4 is missing" in errors[0]


def test_interactive_animation_render(blender, tmp_path):
    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed (apt-get install xvfb)")
    script = tmp_path / "f12.py"
    script.write_text(F12_SCRIPT)
    r = blender(
        "--factory-startup", "--python", script, "--", ROOT, tmp_path,
        wrap=["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"], timeout=300,
    )  # fmt: skip
    skip_without_gl(r, failed_only=False)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result
    assert result["lock"] and result["invoke"] == ["RUNNING_MODAL"]
    rendered = [f for f in result["frames"] if f["job"] and not f["main"]]
    assert [f["frame"] for f in rendered] == [1, 2, 3], result["frames"]
    assert all("map(s) updated" in f["status"] for f in rendered), rendered
    colours = result["colours"]
    for frame, rgb in enumerate(colours, 1):
        assert max(range(3), key=rgb.__getitem__) == frame - 1, colours  # red, green, blue
