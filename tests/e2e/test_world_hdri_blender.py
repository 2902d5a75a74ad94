"""Surroundings: World HDRI under a real Blender binary, as a TD runs it: a shot whose world is
one of Blender's bundled HDRIs, rendered headless with `--method ground --surroundings world`.
What the sphere's upper half reflects changes from the guessed grey to the HDRI, its lower half
(the ground the plate shows) does not, and the batch warns of nothing (no fallback to Auto)."""

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import ROOT

pytestmark = pytest.mark.e2e

SHOT = """
import bpy, math, os, sys
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.location = (0, -6, 1.6)
cam.rotation_euler = (math.radians(80), 0, 0)
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, segments=24, ring_count=12, location=(0, 0, 0.6))
scene.render.resolution_x, scene.render.resolution_y = 96, 54
scene.render.engine = "CYCLES"
scene.cycles.samples = 2
world = bpy.data.worlds.new("On Set")
if bpy.app.version < (5, 0, 0):
    world.use_nodes = True
tree = world.node_tree
env = tree.nodes.new("ShaderNodeTexEnvironment")
folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
env.image = bpy.data.images.load(os.path.join(folder, "forest.exr"))
tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
scene.world = world
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
"""


def halves(path):
    """The mean colour of the sphere's upper and lower halves in the render (its alpha)."""
    rgba = oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT)
    rows, cols = np.nonzero(rgba[..., 3] > 0.99)
    middle = 0.5 * (rows.min() + rows.max())
    upper, lower = rows < middle - 0.2 * np.ptp(rows), rows > middle + 0.2 * np.ptp(rows)
    pick = lambda m: rgba[rows[m], cols[m], :3].mean(0)  # noqa: E731
    return pick(upper), pick(lower)


def test_the_world_hdri_in_a_headless_batch(blender, tmp_path):
    shot = tmp_path / "shot.blend"
    script = tmp_path / "make_shot.py"
    script.write_text(SHOT)
    r = blender("-b", "--factory-startup", "--python", script, "--", shot)
    assert r.returncode == 0 and shot.exists(), r.stdout[-2000:] + r.stderr[-2000:]
    plate = ROOT / "sample_scenes/plates/courtyard.jpg"
    seen = {}
    for kind in ("auto", "world"):
        out = tmp_path / kind
        args = ["--plate", plate, "--out", out, "--resolution", 256, "--method", "ground"]
        r = blender(
            "-b", "--factory-startup", shot, "--python-exit-code", "1",
            "--python", ROOT / "render_shot.py", "--", *args, "--surroundings", kind,
        )  # fmt: skip
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
        assert "warning" not in r.stdout, r.stdout[-3000:]  # no fallback to Auto, no exposure
        seen[kind] = halves(out / "shot_render.exr")
    (sky_auto, ground_auto), (sky_world, ground_world) = seen["auto"], seen["world"]
    # the upper half shows the forest's sky, not the guessed grey; the ground below is the
    # plate's either way
    assert np.abs(sky_world - sky_auto).max() > 0.1 * sky_auto.mean(), (sky_world, sky_auto)
    np.testing.assert_allclose(ground_world, ground_auto, rtol=0.1, atol=0.01)
