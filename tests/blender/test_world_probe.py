"""Surroundings: World HDRI (operators/node_trees/world_probe.py): the scene's world, an
on-set HDRI, stands in for the guessed sky where the plate shows none, turned by its Mapping
node and as bright as its Background's Strength; the world is read, never changed; a world
without an HDRI says so and falls back to Auto.

The shot of test_surroundings: a camera 35 degrees down at a grey ground, so the plate shows no
sky and straight up from the ball the map holds the unseen sky alone.
"""

import math

import bpy
import numpy as np
import pytest
from shots import addon_part
from test_surroundings import GROUND, draw_main_panel, make_shot

ZENITH = (0.2, 0.4, 1.0)
RED = (3.0, 0.0, 0.0)
STRENGTH = 2.0


def hdri(name="On Set"):
    """A 128 x 64 float lat-long: blue within 20 degrees of the zenith, a red patch at the
    horizon's +X (the image's centre column, 10-30 degrees up), dim grey elsewhere."""
    h, w = 64, 128
    px = np.full((h, w, 4), 0.05, np.float32)
    px[..., 3] = 1.0
    rows = (np.arange(h) + 0.5) / h * 180.0  # degrees from the zenith, top row first
    px[rows < 20, :, :3] = ZENITH
    band = (rows > 60) & (rows < 80)
    px[np.ix_(band, np.arange(w // 2 - 6, w // 2 + 6))] = (*RED, 1.0)
    image = bpy.data.images.new(name, w, h, float_buffer=True)
    image.pixels.foreach_set(px[::-1].ravel())  # Blender stores the bottom row first
    image.pack()
    return image


def world_with(image, turn_deg=0.0):
    world = bpy.data.worlds.new("Set HDRI")
    if bpy.app.version < (5, 0, 0):  # 5.x: worlds always use nodes (use_nodes deprecated)
        world.use_nodes = True
    tree = world.node_tree
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = STRENGTH
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.vector_type = "POINT"
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(turn_deg))
    tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    return world


def the_map(scene, ball):
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"], report.warnings
    image = addon_part("operators.node_trees.shading").map_of(ball)
    return addon_part("operators.scene.images").read_pixels(image)[..., :3], report


def directions(scene, pixels):
    bounds = addon_part("operators.scene.bounds")
    projection = bounds.camera_projection(scene)
    d = addon_part("virtual_reflections.layouts").texel_directions("latlong", pixels.shape[1])
    to_engine = np.array(
        [bounds.to_engine_frame(projection, vector=v) for v in np.eye(3)]
    ).T  # world -> engine camera frame, column per world axis
    return d @ to_engine  # each texel's direction in the world


def toward(world_dirs, axis, sign):
    """Texels 14-26 degrees above the horizon (the red patch's band) within 8 degrees of the
    world's horizontal ``sign`` x ``axis`` (0: X, 1: Y)."""
    elevation = np.degrees(np.arcsin(np.clip(world_dirs[..., 2], -1, 1)))
    band = (elevation > 14) & (elevation < 26)
    return band & (sign * world_dirs[..., axis] > 0.99 * np.cos(np.radians(elevation)))


@pytest.mark.parametrize("combine", ["REPLACE", "WORLD"])
def test_the_world_hdri_fills_the_unseen_sky(addon, combine):
    scene, ball = make_shot()
    settings = scene.virtual_reflections
    settings.combine = combine
    # The world turned 90 degrees about Z (the texture is read at the turned direction): the
    # red patch (the image's +X) shows toward world -Y, behind the camera, and not toward +X.
    world = world_with(hdri(), turn_deg=90.0)
    scene.world = world
    settings.surroundings = "WORLD"
    pixels, report = the_map(scene, ball)
    assert not [w for w in report.warnings if "World HDRI" in w], report.warnings
    world_dirs = directions(scene, pixels)
    up = world_dirs[..., 2] > math.cos(math.radians(10))
    np.testing.assert_allclose(pixels[up].mean(0), np.multiply(ZENITH, STRENGTH), rtol=0.05)
    behind, side = toward(world_dirs, 1, -1), toward(world_dirs, 0, 1)
    assert behind.any() and side.any()
    assert pixels[behind][:, 0].mean() > 0.5 * RED[0] * STRENGTH
    assert pixels[side][:, 0].mean() < 0.2
    # what the plate shows is still the plate's
    bounds = addon_part("operators.scene.bounds")
    projection = bounds.camera_projection(scene)
    ahead = np.subtract(
        bounds.to_engine_frame(projection, point=(0.0, 2.2, 0.0)),
        bounds.to_engine_frame(projection, point=tuple(ball.location)),
    )
    ahead /= np.linalg.norm(ahead)
    d = addon_part("virtual_reflections.layouts").texel_directions("latlong", pixels.shape[1])
    np.testing.assert_allclose(
        pixels[d @ ahead > math.cos(math.radians(3))].mean(0), GROUND, atol=0.03
    )
    # the artist's world is read, not changed (in the World look, the add-on's own world
    # stands in the scene for now and the artist's comes back on Remove)
    assert world.node_tree.nodes["Background"].inputs["Strength"].default_value == STRENGTH
    addon_part("operators.generate").remove_all()
    assert scene.world == world


def test_the_world_look_reads_the_world_it_replaced(addon):
    """Generate twice in the World look: the second run finds the add-on's world in the scene
    and reads the artist's, which it replaced."""
    scene, ball = make_shot()
    settings = scene.virtual_reflections
    settings.combine = "WORLD"
    scene.world = world_with(hdri())
    settings.surroundings = "WORLD"
    first, _ = the_map(scene, ball)
    assert scene.world.name != "Set HDRI"  # the add-on's world is on
    second, report = the_map(scene, ball)
    assert not [w for w in report.warnings if "World HDRI" in w], report.warnings
    np.testing.assert_allclose(second, first, atol=1e-5)


def test_a_world_without_an_hdri_says_so_and_uses_auto(addon):
    scene, ball = make_shot()
    settings = scene.virtual_reflections
    plain = bpy.data.worlds.new("Plain")
    scene.world = plain
    auto, _ = the_map(scene, ball)
    addon_part("operators.generate").remove_all()
    settings.surroundings = "WORLD"
    named, report = the_map(scene, ball)
    assert any(
        "World HDRI: world 'Plain' has no Environment Texture" in w and w.endswith("used Auto")
        for w in report.warnings
    ), report.warnings
    np.testing.assert_allclose(named, auto, atol=1e-5)


def test_the_exposure_is_checked_against_the_plate(addon):
    """A level camera sees the sky; a world 8 times darker than the plate's sky is named."""
    scene, ball = make_shot()
    scene.camera.rotation_euler = (math.radians(85), 0.0, 0.0)  # 5 degrees down: sky on top
    ball.location = (0.0, 10.0, 0.5)
    bpy.context.view_layer.update()
    settings = scene.virtual_reflections
    image = hdri()
    px = np.array(image.pixels[:], np.float32).reshape(64, 128, 4)
    px[..., :3] = 0.02
    image.pixels.foreach_set(px.ravel())
    image.pack()
    scene.world = world_with(image)
    settings.surroundings = "WORLD"
    pixels = np.full((90, 160, 3), 0.5, np.float32)  # the sky and the ground alike
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [ball], pixels=pixels
    )
    assert any("stops darker than the plate" in w for w in report.warnings), report.warnings


def test_the_batch_option_names_the_world(addon):
    options = addon_part("operators.batch.options")
    render = addon_part("operators.batch.render")
    scene, _ = make_shot()
    scene.world = bpy.data.worlds.new("Plain")
    with pytest.raises(ValueError, match="^--surroundings world: world 'Plain' has no Environment"):
        render.configure(scene, options.BatchOptions(plate="p.exr", out="o", surroundings="world"))
    scene.world = world_with(hdri())
    render.configure(scene, options.BatchOptions(plate="p.exr", out="o", surroundings="world"))
    assert scene.virtual_reflections.surroundings == "WORLD"


def test_the_probe_is_the_world_cycles_renders(addon):
    """The frames agree with Blender's: a smooth HDRI (colour from the direction in its own
    frame) turned by a Mapping node on all three axes, seen by a camera looking up and to the
    side, rendered by Cycles, against the probe read along the same pixels' directions."""
    bounds = addon_part("operators.scene.bounds")
    world_probe = addon_part("operators.node_trees.world_probe")
    scene, ball = make_shot()
    ball.hide_render = True
    h, w = 64, 128
    theta = (np.arange(h) + 0.5) / h * math.pi
    phi = math.pi - 2 * math.pi * (np.arange(w) + 0.5) / w
    d = np.stack(
        [
            np.sin(theta)[:, None] * np.cos(phi)[None],
            np.sin(theta)[:, None] * np.sin(phi)[None],
            np.repeat(np.cos(theta)[:, None], w, 1),
        ],
        -1,
    )
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = 0.5 + 0.45 * d
    image = bpy.data.images.new("Smooth", w, h, float_buffer=True)
    image.pixels.foreach_set(px[::-1].ravel())
    image.pack()
    world = world_with(image)
    mapping = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (
        math.radians(10),
        math.radians(-15),
        math.radians(70),
    )
    mapping.vector_type = "VECTOR"
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = world
    scene.camera.rotation_euler = (math.radians(110), 0.0, math.radians(37))
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.render.filter_size = 0.01
    scene.render.resolution_x, scene.render.resolution_y = 48, 32
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.view_settings.view_transform = "Standard"
    bpy.context.view_layer.update()
    path = bpy.app.tempdir + "world_probe_check.exr"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    rendered = bpy.data.images.load(path)
    got = np.array(rendered.pixels[:], np.float32).reshape(32, 48, 4)[::-1, :, :3]
    projection = bounds.camera_projection(scene)
    probe = world_probe.world_probe(scene, projection)
    fx = 0.5 * 48 / math.tan(0.5 * scene.camera.data.angle_x)
    yy, xx = np.mgrid[0:32, 0:48]
    dirs = np.stack([-(xx + 0.5 - 24) / fx, -(yy + 0.5 - 16) / fx, np.ones(xx.shape)], -1)
    want = addon_part("virtual_reflections.probe").sample(probe.pixels, dirs @ probe.rotation.T)
    assert np.abs(got - want).max() < 0.02, np.abs(got - want).max()


def test_the_panel_names_the_hdri_it_reads(addon):
    """The panel names the HDRI World HDRI reads, or says Auto is used; the Sky Texture is
    greyed out while an HDRI is read (the HDRI is the sky), not while Auto stands in."""
    scene, _ = make_shot()
    scene.virtual_reflections.surroundings = "WORLD"
    scene.world = bpy.data.worlds.new("Plain")
    drawn = draw_main_panel(scene)
    labels = " ".join(drawn.labels)
    assert "world 'Plain' has no Environment Texture" in labels and "Auto is used" in labels
    assert "sky_texture" in drawn.props and "sky_texture" not in drawn.inactive
    scene.world = world_with(hdri("Set Panorama"))
    drawn = draw_main_panel(scene)
    labels = " ".join(drawn.labels)
    assert "Reads 'Set Panorama' from world 'Set HDRI'" in labels, labels
    assert drawn.inactive == ["sky_texture"]


def test_live_update_follows_the_world_being_turned(addon):
    """With Live Update on, turning the world's HDRI (its Mapping node) rebuilds the map, and
    the red patch moves with it; under Auto the same edit does nothing."""
    live = addon_part("operators.live")
    try:
        scene, ball = make_shot()
        world = world_with(hdri(), turn_deg=90.0)
        scene.world = world
        scene.virtual_reflections.surroundings = "WORLD"
        before, _ = the_map(scene, ball)
        scene.virtual_reflections.live_update = True
        bpy.context.view_layer.update()
        live.flush(scene, full=True)
        mapping = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value[2] = math.radians(-90.0)
        bpy.context.view_layer.update()
        assert live.pending() == {"Ball"}
        assert live.flush(scene, full=True).done
        image = addon_part("operators.node_trees.shading").map_of(ball)
        after = addon_part("operators.scene.images").read_pixels(image)[..., :3]
        behind = toward(directions(scene, after), 1, -1)
        assert before[behind][:, 0].mean() > 0.5 * RED[0] * STRENGTH  # red behind at +90
        assert after[behind][:, 0].mean() < 0.2  # turned away to +Y at -90
        scene.virtual_reflections.surroundings = "AUTO"
        live.flush(scene, full=True)
        mapping.inputs["Rotation"].default_value[2] = 0.0
        bpy.context.view_layer.update()
        assert live.pending() == set()
    finally:
        live.disable()


def test_every_frame_follows_an_animated_world(addon):
    """Update Every Frame: the world's turn keyed from +90 to -90 degrees, each frame's map
    holds the red patch where that frame's world puts it."""
    sequence = addon_part("operators.sequence")
    scene, ball = make_shot()
    world = world_with(hdri(), turn_deg=90.0)
    scene.world = world
    scene.virtual_reflections.surroundings = "WORLD"
    the_map(scene, ball)
    mapping = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeMapping")
    rotation = mapping.inputs["Rotation"]
    rotation.keyframe_insert("default_value", frame=1)
    rotation.default_value[2] = math.radians(-90.0)
    rotation.keyframe_insert("default_value", frame=2)
    red = {}
    for frame in (1, 2):
        scene.frame_set(frame)
        update = sequence.update(scene, bpy.context.evaluated_depsgraph_get(), frame=frame)
        assert update.maps, update.warnings
        image = addon_part("operators.node_trees.shading").map_of(ball)
        pixels = addon_part("operators.scene.images").read_pixels(image)[..., :3]
        red[frame] = pixels[toward(directions(scene, pixels), 1, -1)][:, 0].mean()
    assert red[1] > 0.5 * RED[0] * STRENGTH and red[2] < 0.2, red


def test_under_auto_the_panel_points_to_the_worlds_hdri(addon):
    """Auto does not read the world (it may light the shot without being the set), but when
    the artist's world holds an HDRI the panel says World HDRI would read it, in place of the
    no-sky hint; a world without one, or with its texture muted, leaves the no-sky hint."""
    scene, _ = make_shot()  # the camera sees no sky
    assert scene.virtual_reflections.surroundings == "AUTO"
    scene.world = bpy.data.worlds.new("Plain")
    labels = " ".join(draw_main_panel(scene).labels)
    assert "sees no sky" in labels and "holds" not in labels, labels
    world = world_with(hdri("Set Panorama"))
    scene.world = world
    labels = " ".join(draw_main_panel(scene).labels)
    assert "World 'Set HDRI' holds 'Set Panorama': World HDRI reads it" in labels, labels
    assert "sees no sky" not in labels
    env = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeTexEnvironment")
    env.mute = True
    labels = " ".join(draw_main_panel(scene).labels)
    assert "holds" not in labels and "sees no sky" in labels, labels
    env.mute = False
    scene.virtual_reflections.surroundings = "OPEN"  # named: no hint
    assert "holds" not in " ".join(draw_main_panel(scene).labels)
