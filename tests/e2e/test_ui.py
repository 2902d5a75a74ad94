"""The add-on in Blender's own window (Xvfb): undo after Generate, as an artist would press
Ctrl+Z. Needs a real Blender binary and xvfb-run; skipped with the reason otherwise."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

UNDO_SCRIPT = r"""
import bpy, importlib.util, json, math, sys
root = sys.argv[sys.argv.index("--") + 1]
spec = importlib.util.spec_from_file_location("vr_ui_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
result = {}

def run():
    try:
        win = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=win):
            scene = bpy.context.scene  # the factory scene: its camera looks at the origin
            bpy.ops.mesh.primitive_uv_sphere_add(radius=1)
            bpy.ops.object.select_all(action="DESELECT")
            bpy.data.objects["Sphere"].select_set(True)
            scene.virtual_reflections.plate_image = bpy.data.images.load(
                root + "/sample_scenes/plates/courtyard.jpg")
            scene.virtual_reflections.resolution = "256"
            bpy.ops.ed.undo_push(message="scene ready")
            # As a click on the button does: run, then push an undo step.
            result["generate"] = sorted(bpy.ops.vr.generate("EXEC_DEFAULT", True))
            result["map_after_generate"] = "VR Map Sphere" in bpy.data.images
            result["link_after_generate"] = bpy.data.objects["Sphere"].material_slots[0].link
            bpy.ops.ed.undo()
            result["map_after_undo"] = "VR Map Sphere" in bpy.data.images
            result["slots_after_undo"] = len(bpy.data.objects["Sphere"].material_slots)
            bpy.ops.ed.redo()
            result["map_after_redo"] = "VR Map Sphere" in bpy.data.images
    except Exception as exc:
        result["error"] = repr(exc)
    print("RESULT=" + json.dumps(result), flush=True)
    bpy.ops.wm.quit_blender()

bpy.app.timers.register(run, first_interval=0.5)
"""


def test_undo_after_generate(blender_gui, tmp_path):
    script = tmp_path / "undo.py"
    script.write_text(UNDO_SCRIPT)
    r = blender_gui(script, ROOT)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result.get("error")
    assert result["generate"] == ["FINISHED"]
    assert result["map_after_generate"] and result["link_after_generate"] == "OBJECT"
    assert not result["map_after_undo"] and result["slots_after_undo"] == 0, result
    assert result["map_after_redo"]
