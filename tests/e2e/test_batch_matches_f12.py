"""Issue 42: the farm renders what the artist saw. A shot Set Up From Plate and generated in
the panel, saved, then rendered two ways in a real Blender with the installed extension:
Blender's own F12 path (`blender -b shot.blend -f 1`, the render and the compositor the
file holds) and `blender -c virtual_reflections` on the same plate. The two PNGs agree; the
batch used to undo the artist's Set Up first (view transform back to AgX, ground deleted)."""

import numpy as np
import pytest
from conftest import ROOT
from test_cli_command import built  # noqa: F401  (the extension's zip, a fixture)

pytestmark = pytest.mark.e2e

PLATE = ROOT / "sample_scenes/plates/courtyard.jpg"
ARTIST = """
import bpy, sys
plate, shot = sys.argv[-2:]
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.location = (0, -6, 0.3)
cam.rotation_euler = (1.5707963, 0, 0)
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=24, ring_count=12)
scene.render.engine = "CYCLES"
scene.cycles.samples = 4
scene.cycles.seed = 1
scene.cycles.use_denoising = False
scene.view_settings.view_transform = "AgX"  # Blender's default; Set Up makes it Standard
scene.virtual_reflections.plate_image = bpy.data.images.load(plate)
assert bpy.ops.vr.setup_plate(ground=True, lens=False) == {"FINISHED"}
scene.render.resolution_percentage = 10  # a preview size; the batch gets --scale 10
for o in scene.objects:
    o.select_set(o.type == "MESH" and not o.is_shadow_catcher)
assert bpy.ops.vr.generate() == {"FINISHED"}
bpy.ops.wm.save_as_mainfile(filepath=shot)
"""


def test_the_batch_renders_what_f12_renders(blender, built, tmp_path):  # noqa: F811
    env = {"BLENDER_USER_RESOURCES": str(tmp_path / "user")}  # a private user folder
    r = blender(
        "--command", "extension", "install-file", "-r", "user_default", "--enable", built, env=env
    )
    assert r.returncode == 0, r.stdout + r.stderr
    script, shot = tmp_path / "artist.py", tmp_path / "shot.blend"
    script.write_text(ARTIST)
    r = blender("-b", "--python-exit-code", 1, "--python", script, "--", PLATE, shot, env=env)
    assert r.returncode == 0 and shot.exists(), r.stdout[-3000:] + r.stderr[-3000:]

    f12 = tmp_path / "f12_"
    r = blender("-b", shot, "-o", f"{f12}#", "-F", "PNG", "-f", 1, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    out = tmp_path / "out"
    r = blender(
        "-c", "virtual_reflections", shot, "--plate", PLATE, "--out", out, "--scale", 10, env=env
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]

    import OpenImageIO as oiio

    def pixels(path):
        image = oiio.ImageBuf(str(path))
        assert not image.has_error, image.geterror()
        return image.get_pixels(oiio.FLOAT)[..., :3] * 255

    window, farm = pixels(f"{f12}1.png"), pixels(out / "shot_composite.png")
    assert window.shape == farm.shape == (72, 128, 3)
    off = np.abs(window - farm)
    assert np.median(off) < 1.0 and off.mean() < 2.0, (np.median(off), off.mean())
