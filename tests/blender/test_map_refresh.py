"""A map rewritten in place reaches a Cycles render that keeps its scene between frames
(Render > Performance > Persistent Data, and Cycles' own viewport, which always does): Update
Every Frame writes each frame's map into the same image (maps.overwrite), and Cycles reloads an
image only when the image is tagged for the dependency graph.

Found by the 3D study in motion (docs/scenes3d.md "In motion"): with Persistent Data every
frame rendered the first frame's map. bpy 5.2 reloads a tagged image; bpy 4.5's Cycles keeps
the pixels it loaded first whatever is tagged (strict xfail: it fails the day it works)."""

import bpy
import numpy as np
import OpenImageIO as oiio
import pytest
from shots import addon_part

RED, GREEN = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)


def world_of(image):
    world = bpy.data.worlds.new("Map World")
    if world.node_tree is None:  # 4.x; 5.x worlds always have nodes
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    background = nodes.new("ShaderNodeBackground")
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(env.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], out.inputs["Surface"])
    return world


def render_mean(scene, path) -> np.ndarray:
    scene.render.filepath = str(path)
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    return oiio.ImageBuf(str(path)).get_pixels()[..., :3].mean((0, 1))


@pytest.mark.xfail(
    bpy.app.version < (5, 0, 0),
    strict=True,
    reason="bpy 4.5: Cycles with Persistent Data keeps an image's first pixels",
)
def test_a_map_rewritten_in_place_shows_in_the_next_persistent_render(addon, tmp_path):
    maps = addon_part("operators.scene.maps")
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.render.use_persistent_data = True
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    image = maps.store_map("VR Map Test", np.full((4, 8, 3), RED, np.float32))
    scene.world = world_of(image)
    first = render_mean(scene, tmp_path / "first.exr")
    maps.overwrite(image, np.full((4, 8, 3), GREEN, np.float32))  # as sequence.update does
    second = render_mean(scene, tmp_path / "second.exr")
    assert np.allclose(first, RED, atol=0.02)
    assert np.allclose(second, GREEN, atol=0.02), second


def test_update_every_frame_turns_persistent_data_off_only_where_it_freezes_maps(addon):
    scene = bpy.context.scene
    scene.render.use_persistent_data = True
    scene.virtual_reflections.sequence = True
    try:
        assert scene.render.use_lock_interface
        assert scene.render.use_persistent_data == (bpy.app.version >= (5, 0, 0))
    finally:
        scene.virtual_reflections.sequence = False
