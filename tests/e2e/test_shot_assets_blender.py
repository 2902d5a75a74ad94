"""A shot as it travels, in the real Blender binary (issue 40): its folder (.blend + vr_maps/)
moved still renders its saved maps, a missing one is said when the file opens, and an asset
brought in as a library override takes a reflection that survives save and open (the
bpy-module side: tests/blender/test_map_files.py, tests/blender/test_overrides.py)."""

import json
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

PRELUDE = r"""
import bpy, importlib.util, json, math, sys
import numpy as np
root, folder, step = sys.argv[sys.argv.index("--") + 1 :]
spec = importlib.util.spec_from_file_location("vr_assets_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
shading = importlib.import_module("vr_assets_addon.operators.node_trees.shading")


def shot(scene, sphere_name):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam); scene.camera = cam
    cam.location = (0, -6, 0); cam.rotation_euler = (math.pi / 2, 0, 0)
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.render.engine = "CYCLES"; scene.cycles.samples = 4; scene.cycles.use_denoising = False
    scene.render.film_transparent = True
    plate = bpy.data.images.new("Plate", 64, 36, alpha=False, float_buffer=True)
    px = np.ones((36, 64, 4), np.float32); px[..., :3] = (0.1, 0.8, 0.1)  # green
    plate.pixels.foreach_set(px.ravel()); plate.pack()
    settings = scene.virtual_reflections
    settings.plate_image = plate; settings.resolution = "256"; settings.combine = "REPLACE"


def sphere_rgb(scene):
    scene.render.filepath = folder + "/render.exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(folder + "/render.exr")
    buf = np.empty(len(image.pixels), np.float32); image.pixels.foreach_get(buf)
    px = buf.reshape(36, 64, 4)
    return [float(v) for v in px[12:24, 24:40, :3].reshape(-1, 3).mean(0)]
"""

MAPS = (
    PRELUDE
    + r"""
if step == "make":
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    shot(scene, "Sphere")
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    sphere = bpy.context.active_object; sphere.name = "Sphere"
    scene.virtual_reflections.map_storage = "FILES"
    bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
    sphere.select_set(True); bpy.context.view_layer.objects.active = sphere
    result = {"generate": list(bpy.ops.vr.generate())}
    bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
    result["sphere"] = sphere_rgb(scene)
else:
    bpy.ops.wm.open_mainfile(filepath=folder + "/shot.blend")
    scene = bpy.context.scene
    image = bpy.data.images["VR Map Sphere"]
    result = {"filepath": image.filepath, "has_data": image.has_data}
    if step == "render":
        result["sphere"] = sphere_rgb(scene)
print("RESULT=" + json.dumps(result), flush=True)
"""
)


def run(blender, tmp_path, script, folder, step):
    path = tmp_path / "script.py"
    path.write_text(script)
    r = blender("-b", "--factory-startup", "--python", path, "--", ROOT, folder, step)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line is not None, r.stdout[-3000:] + r.stderr[-3000:]
    return json.loads(line[len("RESULT=") :]), r


def test_a_moved_shot_renders_its_saved_maps(blender, tmp_path):
    before, after = tmp_path / "before", tmp_path / "after"
    before.mkdir()
    made, _ = run(blender, tmp_path, MAPS, before, "make")
    assert made["generate"] == ["FINISHED"]
    shutil.move(before, after)
    opened, _ = run(blender, tmp_path, MAPS, after, "render")
    red, green, blue = opened["sphere"]
    assert green > red and green > blue, opened  # the green plate, not magenta
    assert opened["sphere"] == pytest.approx(made["sphere"], abs=1e-3), (made, opened)
    assert opened["filepath"] == "//vr_maps/VR_Map_Sphere.exr"
    # The map's file gone: said when the shot opens, before any render.
    (after / "vr_maps" / "VR_Map_Sphere.exr").unlink()
    _, r = run(blender, tmp_path, MAPS, after, "open")
    said = [x for x in r.stdout.splitlines() if x.startswith("Virtual Reflections: ")]
    assert said == [
        "Virtual Reflections: map 'VR Map Sphere': its file //vr_maps/VR_Map_Sphere.exr is "
        "missing; Generate makes it again"
    ], r.stdout[-3000:]


OVERRIDE = (
    PRELUDE
    + r"""
if step == "library":
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    ball = bpy.context.active_object; ball.name = "Ball"
    chrome = bpy.data.materials.new("Chrome"); chrome.diffuse_color = (0.2, 0.4, 0.6, 1.0)
    ball.data.materials.append(chrome)
    asset = bpy.data.collections.new("Asset")
    bpy.context.scene.collection.children.link(asset)
    bpy.context.scene.collection.objects.unlink(ball); asset.objects.link(ball)
    bpy.ops.wm.save_as_mainfile(filepath=folder + "/lib.blend")
    result = {}
elif step == "generate":
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    shot(scene, "Ball")
    with bpy.data.libraries.load(folder + "/lib.blend", link=True) as (_, linked):
        linked.collections = ["Asset"]
    instance = bpy.data.objects.new("Asset", None)
    instance.instance_type = "COLLECTION"; instance.instance_collection = linked.collections[0]
    scene.collection.objects.link(instance)
    instance.select_set(True); bpy.context.view_layer.objects.active = instance
    made = list(bpy.ops.object.make_override_library())
    ball = next(o for o in bpy.data.objects if o.override_library is not None)
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True); bpy.context.view_layer.objects.active = ball
    result = {"override": made, "generate": list(bpy.ops.vr.generate()),
              "report": scene.virtual_reflections.last_report}
    bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
else:
    bpy.ops.wm.open_mainfile(filepath=folder + "/shot.blend")
    scene = bpy.context.scene
    ball = next(o for o in bpy.data.objects if o.override_library is not None)
    chrome = next(m for m in bpy.data.materials if m.library is not None)
    result = {"attached": shading.is_attached(ball), "sphere": sphere_rgb(scene),
              "chrome": [round(v, 3) for v in chrome.diffuse_color]}
    result["remove"] = list(bpy.ops.vr.remove())
    slot = ball.material_slots[0]
    result["after"] = [slot.link, slot.material.name, slot.material.library is not None,
                       shading.is_attached(ball),
                       sorted(m.name for m in bpy.data.materials if m.get("vr_created"))]
print("RESULT=" + json.dumps(result), flush=True)
"""
)


def test_a_library_override_reflects_the_plate_after_save_and_open(blender, tmp_path):
    run(blender, tmp_path, OVERRIDE, tmp_path, "library")
    made, _ = run(blender, tmp_path, OVERRIDE, tmp_path, "generate")
    assert made["override"] == ["FINISHED"] and made["generate"] == ["FINISHED"], made
    assert "linked" not in made["report"], made
    opened, _ = run(blender, tmp_path, OVERRIDE, tmp_path, "open")
    assert opened["attached"], opened
    red, green, blue = opened["sphere"]
    assert green > red and green > blue, opened  # the green plate, on the override
    assert opened["chrome"] == [0.2, 0.4, 0.6, 1.0]  # the library's material untouched
    assert opened["remove"] == ["FINISHED"]
    assert opened["after"] == ["DATA", "Chrome", True, False, []], opened
