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


REDO_SCRIPT = r"""
import bpy, importlib.util, json, sys
import numpy as np
root, out = sys.argv[sys.argv.index("--") + 1 :][:2]
spec = importlib.util.spec_from_file_location("vr_ui_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
result = {}

def map_pixels():
    image = bpy.data.images["VR Map Sphere"]
    a = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(a)
    return a.reshape(-1, 4)[:, :3]

crops = {}

def render(name):
    # The sphere fills the middle of a small Cycles render; its mean colour there (the
    # pixels kept in crops).
    scene = bpy.context.scene
    scene.render.filepath = out + "/" + name + ".exr"
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(scene.render.filepath)
    w, h = image.size
    a = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(a)
    a = a.reshape(h, w, 4)[h // 3 : 2 * h // 3, w // 3 : 2 * w // 3, :3]
    bpy.data.images.remove(image)
    crops[name] = a
    return float(a.mean())

def run():
    try:
        win = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=win):
            scene = bpy.context.scene  # the factory scene: its camera looks at the origin
            bpy.data.objects.remove(bpy.data.objects["Cube"])
            bpy.ops.mesh.primitive_uv_sphere_add(radius=1)
            bpy.ops.object.select_all(action="DESELECT")
            bpy.data.objects["Sphere"].select_set(True)
            scene.render.engine = "CYCLES"
            scene.cycles.samples = 4
            scene.render.resolution_x, scene.render.resolution_y = 96, 54
            scene.render.image_settings.file_format = "OPEN_EXR"
            scene.virtual_reflections.plate_image = bpy.data.images.load(
                root + "/sample_scenes/plates/courtyard.jpg")
            scene.virtual_reflections.resolution = "256"
            scene.virtual_reflections.combine = "REPLACE"
            result["before"] = render("before")
            bpy.ops.ed.undo_push(message="scene ready")
            result["generate"] = sorted(bpy.ops.vr.generate("EXEC_DEFAULT", True))
            generated = map_pixels()
            result["map_max"] = float(generated.max())
            result["generated"] = render("generated")
            result["generated_vs_before"] = float(
                np.abs(crops["generated"] - crops["before"]).mean())
            bpy.ops.ed.undo()
            result["map_after_undo"] = "VR Map Sphere" in bpy.data.images
            bpy.ops.ed.redo()
            result["redo_map_diff"] = float(np.abs(map_pixels() - generated).max())
            result["redone"] = render("redone")
    except Exception as exc:
        import traceback; traceback.print_exc()
        result["error"] = repr(exc)
    print("RESULT=" + json.dumps(result), flush=True)
    bpy.ops.wm.quit_blender()

bpy.app.timers.register(run, first_interval=0.5)
"""


def test_redo_brings_the_maps_pixels_back(blender_gui, tmp_path):
    """Generate, Ctrl+Z, Ctrl+Shift+Z: the map has its pixels again and the sphere renders
    as it did after Generate (it rendered black before: undo keeps no generated pixels)."""
    script = tmp_path / "redo.py"
    script.write_text(REDO_SCRIPT)
    r = blender_gui(script, ROOT, tmp_path)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result.get("error")
    assert result["generate"] == ["FINISHED"] and result["map_max"] > 0.1, result
    assert not result["map_after_undo"], result
    assert result["redo_map_diff"] == 0.0, result  # the very pixels Generate wrote
    # The sphere shows the map: not the plain render (pixel by pixel: a map of the plate's own
    # colours may keep the sphere's mean), and after redo as after Generate.
    assert result["generated_vs_before"] > 0.02, result
    assert abs(result["redone"] - result["generated"]) < 0.05 * result["generated"], result


# What the scripts run in Blender's window share: the extension loaded from the checkout, a
# step that prints its error as the RESULT line and quits, the panel opened and its draws
# counted while a run is under way (its progress bar).
WINDOW_PREAMBLE = r"""
import bpy, importlib, importlib.util, json, sys
root = sys.argv[sys.argv.index("--") + 1]
spec = importlib.util.spec_from_file_location("vr_ui_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
generate = importlib.import_module("vr_ui_addon.operators.generate")
panel = importlib.import_module("vr_ui_addon.ui.panel")

def guarded(step):
    def run():
        try:
            return step()
        except Exception as exc:
            import traceback; traceback.print_exc()
            print("RESULT=" + json.dumps({"error": repr(exc)}), flush=True)
            bpy.ops.wm.quit_blender()
    return run

def open_panel():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=win, area=area, region=region):
        bpy.ops.wm.call_panel(name="VR_PT_main", keep_open=True)

def record_panel_draws(result):
    draw = panel.VR_PT_main.draw
    def recording_draw(self, context):
        draw(self, context)
        result["drawn_running"] += generate.running() is not None
    panel.VR_PT_main.draw = recording_draw
"""


MODAL_SCRIPT = (
    WINDOW_PREAMBLE
    + r"""
result = {"stages": [], "drawn_running": 0}
record_panel_draws(result)

def snapshot():
    sphere = bpy.data.objects["Sphere"]
    return {
        "images": sorted(i.name for i in bpy.data.images),
        "materials": sorted(m.name for m in bpy.data.materials),
        "groups": sorted(g.name for g in bpy.data.node_groups),
        "slots": [(s.link, s.material and s.material.name) for s in sphere.material_slots],
    }

def invoke():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    with bpy.context.temp_override(window=win, area=area):
        return sorted(bpy.ops.vr.generate("INVOKE_DEFAULT"))

def setup():
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1)
    bpy.ops.object.select_all(action="DESELECT")
    bpy.data.objects["Sphere"].select_set(True)
    scene.virtual_reflections.plate_image = bpy.data.images.load(
        root + "/sample_scenes/plates/courtyard.jpg")
    scene.virtual_reflections.resolution = "1024"
    bpy.ops.ed.undo_push(message="scene ready")
    result["before"] = snapshot()
    # Esc right away: the run stops before it changes anything.
    result["cancel_invoke"] = invoke()
    result["running_after_invoke"] = generate.running() is not None
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
    bpy.app.timers.register(guarded(after_cancel), first_interval=1.0)

def after_cancel():
    result["running_after_esc"] = generate.running() is not None
    result["after_esc"] = snapshot()
    result["invoke"] = invoke()
    open_panel()  # drawn as it runs
    bpy.app.timers.register(guarded(watch), first_interval=0.01)

def watch():
    job = generate.running()
    if job is not None:
        if not result["stages"] or result["stages"][-1] != job.stage:
            result["stages"].append(job.stage)
        return 0.005
    result["after_run"] = snapshot()
    result["map"] = "VR Map Sphere" in bpy.data.images
    result["report"] = bpy.context.scene.virtual_reflections.last_report
    bpy.ops.ed.undo()  # the finished run is one undo step
    result["after_undo"] = snapshot()
    print("RESULT=" + json.dumps(result), flush=True)
    bpy.ops.wm.quit_blender()

bpy.app.timers.register(guarded(setup), first_interval=0.5)
"""
)


def test_generate_from_the_window_shows_its_stages_and_esc_stops_it(blender, tmp_path):
    """The button's Generate (INVOKE_DEFAULT) runs step by step with the window drawing: the
    stages follow each other, Esc stops it with the scene as before, and a finished run is
    one undo step."""
    import shutil

    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed (apt-get install xvfb)")
    script = tmp_path / "modal.py"
    script.write_text(MODAL_SCRIPT)
    r = blender(
        "--factory-startup", "--enable-event-simulate", "--python", script, "--", ROOT,
        timeout=120, wrap=["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"],
    )  # fmt: skip
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result.get("error")
    assert result["cancel_invoke"] == ["RUNNING_MODAL"] and result["running_after_invoke"]
    assert not result["running_after_esc"]
    assert result["after_esc"] == result["before"], result  # nothing attached or made
    assert result["invoke"] == ["RUNNING_MODAL"]
    stages = result["stages"]
    wanted = ["Building the table (Sphere)", "Gathering (Sphere)", "Writing the maps"]
    assert [s for s in stages if s in wanted] == wanted, stages  # in order, each seen
    assert result["map"] and result["after_run"]["slots"][0][0] == "OBJECT", result
    assert result["report"].startswith("1 reflection(s)"), result["report"]
    assert result["after_undo"] == result["before"], result
    assert result["drawn_running"] > 0, result
    assert "Traceback" not in r.stderr, r.stderr[-3000:]  # the panel drew every stage


PASSES_SCRIPT = (
    WINDOW_PREAMBLE
    + r"""
result = {"stages": [], "drawn_running": 0, "render_job_seen": False}
record_panel_draws(result)

def snapshot():
    render = bpy.context.scene.render
    out = {
        "images": sorted(i.name for i in bpy.data.images if i.type != "RENDER_RESULT"),
        "materials": sorted(m.name for m in bpy.data.materials),
        "groups": sorted(g.name for g in bpy.data.node_groups),
        "render": [render.filepath, render.use_border, render.film_transparent,
                   render.image_settings.file_format],
    }
    for name in ("Left", "Right"):
        obj = bpy.data.objects[name]
        out[name] = [obj.pass_index,
                     [(s.link, s.material and s.material.name) for s in obj.material_slots]]
    return out

def invoke():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    with bpy.context.temp_override(window=win, area=area):
        return sorted(bpy.ops.vr.render_passes("INVOKE_DEFAULT", passes=3))

def finish():
    print("RESULT=" + json.dumps(result), flush=True)
    bpy.ops.wm.quit_blender()

def setup():
    scene = bpy.context.scene
    bpy.data.objects.remove(bpy.data.objects["Cube"])
    for name, x in (("Left", -1.1), ("Right", 1.1)):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.9, location=(x, 0, 0))
        bpy.context.active_object.name = name
    bpy.ops.object.select_all(action="DESELECT")
    for name in ("Left", "Right"):
        bpy.data.objects[name].select_set(True)
    scene.virtual_reflections.plate_image = bpy.data.images.load(
        root + "/sample_scenes/plates/courtyard.jpg")
    scene.virtual_reflections.resolution = "256"
    scene.virtual_reflections.combine = "REPLACE"
    scene.virtual_reflections.method = "CAMERA"  # the paper's passes: a map built per pass
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = 160, 90
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    bpy.ops.ed.undo_push(message="scene ready")
    result["before"] = snapshot()
    stop_in("Pass 2 of 3: gathering (Right)", "esc_gathering", then=lambda: stop_in(
        "Pass 2 of 3: rendering", "esc_rendering", then=full_run))

def stop_in(stage, key, then):
    # Invoke, press Esc when the run reaches `stage`, record the scene once it has stopped.
    result[key] = {"invoke": invoke(), "seen": []}
    def wait_for_stage():
        job = generate.running()
        if job is None:
            result[key]["error"] = "the run ended before " + stage
            return finish()
        if not result[key]["seen"] or result[key]["seen"][-1] != job.stage:
            result[key]["seen"].append(job.stage)
        if job.stage != stage or (stage.endswith("rendering") and not job.rendering):
            return 0.002
        result[key]["during"] = snapshot()  # pass 1 has attached the maps by now
        result[key]["rendering_at_esc"] = job.rendering
        bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
        bpy.app.timers.register(guarded(wait_for_stop), first_interval=0.05)
        return None
    def wait_for_stop():
        if generate.running() is not None:  # a render under way ends first
            return 0.05
        result[key]["after"] = snapshot()
        bpy.app.timers.register(guarded(then), first_interval=0.2)
        return None
    bpy.app.timers.register(guarded(wait_for_stage), first_interval=0.002)

def full_run():
    # the default method: pass 2 ray traced (traced_pass.py), the run ends after it
    bpy.context.scene.virtual_reflections.method = "GROUND"
    result["invoke"] = invoke()
    open_panel()  # drawn as it runs
    bpy.app.timers.register(guarded(watch), first_interval=0.01)

def watch():
    job = generate.running()
    if job is not None:
        result["render_job_seen"] |= job.rendering and bpy.app.is_job_running("RENDER")
        if not result["stages"] or result["stages"][-1] != job.stage:
            result["stages"].append(job.stage)
        return 0.005
    result["after_run"] = snapshot()
    result["report"] = bpy.context.scene.virtual_reflections.last_report
    image = bpy.data.images.get("VR Inter-Reflections")
    result["composite"] = list(image.size) if image is not None else None
    finish()

bpy.app.timers.register(guarded(setup), first_interval=0.5)
"""
)


def test_inter_reflections_from_the_window_show_their_passes_and_esc_stops_them(blender, tmp_path):
    """The button's Render Inter-Reflections (INVOKE_DEFAULT) runs pass by pass with the window
    drawing, the stage in the panel and each render as Blender's render job (as F12). Esc in
    pass 2 -- after pass 1 attached the maps and rendered -- while the maps are built, and
    again while Blender renders (the run stops once that render ends), puts the scene back as
    it was (materials, maps, pass indices, render settings) -- both with Camera View,
    whose passes build maps; a full run with the default method (its pass 2 ray traced) ends
    after two passes with the composite image, the report and nothing of the traced pass left."""
    import shutil

    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed (apt-get install xvfb)")
    script = tmp_path / "passes.py"
    script.write_text(PASSES_SCRIPT)
    r = blender(
        "--factory-startup", "--enable-event-simulate", "--python", script, "--", ROOT,
        timeout=300, wrap=["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"],
    )  # fmt: skip
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert "error" not in result, result
    for key, rendering in (("esc_gathering", False), ("esc_rendering", True)):
        stopped = result[key]
        assert "error" not in stopped, stopped
        assert stopped["invoke"] == ["RUNNING_MODAL"], stopped
        assert stopped["rendering_at_esc"] is rendering, stopped
        assert stopped["during"] != result["before"], stopped  # the run had changed the scene
        assert stopped["after"] == result["before"], (key, stopped, result["before"])
    assert result["invoke"] == ["RUNNING_MODAL"]
    stages = result["stages"]
    traced = "Pass 2 of 3: rendering (ray traced)"
    assert "Pass 1 of 3: rendering" in stages and traced in stages, stages
    assert stages.index("Pass 1 of 3: rendering") < stages.index(traced)
    assert not any(s.startswith("Pass 3") for s in stages), stages
    assert result["render_job_seen"], result  # Blender's render job, not a blocking render
    assert result["composite"] == [160, 90], result
    assert result["report"].startswith("2 pass(es)"), result["report"]
    assert not any(m.startswith("VR Traced") for m in result["after_run"]["materials"]), result
    assert result["after_run"]["render"] == result["before"]["render"], result
    assert result["after_run"]["Left"][1][0][0] == "OBJECT", result  # the maps stay on
    assert result["drawn_running"] > 0, result
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
