"""Live Update in Blender's own window (Xvfb), where the depsgraph handler and the timer run as
they do for an artist: a drag moves the sphere over several event-loop turns, the map follows
without any operator being called, the full-size map comes once the sphere rests, an edit to
another object does nothing, and loading another file switches it all off."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

LIVE_SCRIPT = r"""
import bpy, importlib.util, json, sys
import numpy as np
root = sys.argv[sys.argv.index("--") + 1]
spec = importlib.util.spec_from_file_location("vr_live_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
live = sys.modules["vr_live_addon.operators.live"]
result = {"maps": []}

def pixels():
    image = bpy.data.images["VR Map Sphere"]
    buf = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(buf)
    return tuple(image.size), buf

def fail(exc):
    result["error"] = repr(exc)
    print("RESULT=" + json.dumps(result), flush=True)
    bpy.ops.wm.quit_blender()

steps = iter(range(6))
waited = [0]
def step():  # one turn of a drag: move, let Blender update, come back once the timer ran
    try:
        if live.pending() and waited[0] < 100:  # a loaded machine: give the timer its turn
            waited[0] += 1
            return 0.1
        waited[0] = 0
        i = next(steps, None)
        if live._state.passes:
            record()
        if i is None:
            bpy.app.timers.register(rested, first_interval=1.0)
            return None
        bpy.data.objects["Sphere"].location.x = 0.15 * (i + 1)
        bpy.context.view_layer.update()
        return 0.1
    except Exception as exc:
        fail(exc)

def record():  # the map as the previous move left it, once its preview pass ran
    size, buf = pixels()
    result["maps"].append([list(size), float(buf.sum())])

def rested():
    try:
        size, buf = pixels()
        result["rested_size"] = list(size)
        result["passes"] = live._state.passes
        result["status"] = live.status(bpy.context.scene)
        before = live._state.passes
        bpy.data.objects["Cube"].location.z += 0.5  # no reflection: nothing to do
        bpy.context.view_layer.update()
        bpy.app.timers.register(lambda: after_unrelated(before), first_interval=0.6)
    except Exception as exc:
        fail(exc)

def after_unrelated(before):
    try:
        result["passes_after_unrelated"] = live._state.passes - before
        result["installed_before_load"] = live.installed()
        bpy.ops.wm.read_homefile(use_empty=True)
        result["installed_after_load"] = live.installed()
        result["timer_after_load"] = bpy.app.timers.is_registered(live.tick)
    except Exception as exc:
        result["error"] = repr(exc)
    print("RESULT=" + json.dumps(result), flush=True)
    addon.unregister()
    bpy.ops.wm.quit_blender()

def start():
    try:
        win = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=win):
            scene = bpy.context.scene  # the factory scene: camera, cube, light
            bpy.data.objects["Cube"].location = (4.0, 4.0, 0.0)
            bpy.ops.mesh.primitive_uv_sphere_add(radius=1)
            bpy.ops.object.select_all(action="DESELECT")
            bpy.data.objects["Sphere"].select_set(True)
            settings = scene.virtual_reflections
            plate = root + "/sample_scenes/plates/courtyard.jpg"
            settings.plate_image = bpy.data.images.load(plate)
            settings.resolution = "512"
            settings.method = "PAPER"  # maps that depend on where the object is: moves show
            result["generate"] = sorted(bpy.ops.vr.generate("EXEC_DEFAULT", True))
            size, buf = pixels()
            result["maps"].append([list(size), float(buf.sum())])
            settings.live_update = True
            result["installed"] = live.installed()
        bpy.app.timers.register(step, first_interval=0.3)
    except Exception as exc:
        fail(exc)

bpy.app.timers.register(start, first_interval=0.5)
"""


def test_live_update_follows_a_drag_in_blenders_window(blender_gui, tmp_path):
    script = tmp_path / "live.py"
    script.write_text(LIVE_SCRIPT)
    r = blender_gui(script, ROOT)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result.get("error")
    assert result["generate"] == ["FINISHED"] and result["installed"]
    sums = [s for _, s in result["maps"]]
    # Every turn of the drag saw a new map (the timer ran between the moves), small while moving.
    assert len(set(sums)) >= 4, result["maps"]
    assert any(size == [256, 128] for size, _ in result["maps"][1:]), result["maps"]
    # Once the sphere rests the map is full size again; the panel's line says so.
    assert result["rested_size"] == [512, 256] and result["status"].startswith("full"), result
    assert result["passes"] >= 4
    assert result["passes_after_unrelated"] == 0
    assert result["installed_before_load"]
    assert not result["installed_after_load"] and not result["timer_after_load"]
