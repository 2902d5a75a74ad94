"""Saved and packed maps from the real Blender binary (its own Python and OpenImageIO) are
pipeline files: scene-linear half-float, compressed, tagged, with the envmap attribute
(issue 12; the bpy-module side: tests/blender/test_map_files.py)."""

import json
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

SCRIPT = r"""
import bpy, importlib.util, json, math, sys
import numpy as np
root, storage, folder = sys.argv[sys.argv.index("--") + 1 :]
spec = importlib.util.spec_from_file_location("vr_maps_addon", root + "/__init__.py",
                                              submodule_search_locations=[root])
addon = importlib.util.module_from_spec(spec); sys.modules[spec.name] = addon
spec.loader.exec_module(addon); addon.register()
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam); scene.camera = cam
cam.location = (0, -6, 0); cam.rotation_euler = (math.pi / 2, 0, 0)
scene.render.resolution_x, scene.render.resolution_y = 64, 36
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
sphere = bpy.context.active_object; sphere.name = "Sphere"
plate = bpy.data.images.new("Plate", 64, 36, alpha=False, float_buffer=True)
px = np.ones((36, 64, 4), np.float32); px[..., 0] = np.linspace(0, 3, 64)[None, :]
plate.pixels.foreach_set(px.ravel())
settings = scene.virtual_reflections
settings.plate_image = plate; settings.resolution = "256"; settings.map_storage = storage
bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
sphere.select_set(True); bpy.context.view_layer.objects.active = sphere
result = {"generate": list(bpy.ops.vr.generate())}
bpy.ops.wm.save_as_mainfile(filepath=folder + "/shot.blend")
image = bpy.data.images["VR Map Sphere"]
buf = np.empty(len(image.pixels), np.float32); image.pixels.foreach_get(buf)
np.save(folder + "/pixels.npy", buf.reshape(128, 256, 4)[::-1, :, :3])
if image.packed_file is not None:
    open(folder + "/packed.exr", "wb").write(image.packed_file.data)
result["packed"] = image.packed_file is not None
result["filepath"] = bpy.path.abspath(image.filepath)
print("RESULT=" + json.dumps(result), flush=True)
"""


@pytest.mark.parametrize("storage", ["FILES", "PACK"])
def test_blender_saves_and_packs_pipeline_maps(blender, tmp_path, storage):
    script = tmp_path / "maps.py"
    script.write_text(SCRIPT)
    r = blender("-b", "--factory-startup", "--python", script, "--", ROOT, storage, tmp_path)
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line is not None, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(line[len("RESULT=") :])
    assert result["generate"] == ["FINISHED"]
    if storage == "FILES":
        path = tmp_path / "vr_maps" / "VR_Map_Sphere.exr"
        assert not result["packed"] and result["filepath"] == str(path)
    else:
        path = tmp_path / "packed.exr"
        assert result["packed"]
    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    spec = image.spec()
    pixels = np.asarray(image.read_image(0, 0, 0, 3, "float")).reshape(128, 256, 3)
    image.close()
    assert str(spec.format) == "half" and spec.getattribute("compression") == "zip"
    assert spec.getattribute("textureformat") == "LatLong Environment"
    assert str(spec.getattribute("oiio:ColorSpace")).startswith("lin_rec709")
    # What Blender shows is what the file holds: scene-linear, values above 1 kept.
    shown = np.load(tmp_path / "pixels.npy")
    np.testing.assert_allclose(pixels, shown, rtol=2e-3, atol=1e-3)
    assert pixels.max() > 1.5
