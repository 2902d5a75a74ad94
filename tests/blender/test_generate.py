"""Generate / Remove on real scenes: datablocks, renders, restoration, undo and bad input."""

import bpy
import numpy as np
import pytest
from shots import (
    add_camera,
    node_tree_signature,  # noqa: E402
)


def make_scene(width=64, height=48):
    scene = bpy.context.scene
    add_camera(scene, size=(width, height))  # on -Y looking along +Y, Z up
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.cycles.device = "CPU"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    return scene


def add_sphere(name="Ball", location=(0, 0, 0), material=True):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=32, ring_count=16, location=location)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    if material:
        mat = bpy.data.materials.new(f"{name} paint")
        if not mat.node_tree:
            mat.use_nodes = True
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        bsdf.inputs["Base Color"].default_value = (0.8, 0.6, 0.2, 1.0)
        obj.data.materials.append(mat)
    return obj


def red_blue_plate(width=64, height=48):
    """Left half red, right half blue (scene-linear float image)."""
    image = bpy.data.images.new("Plate", width, height, alpha=False, float_buffer=True)
    px = np.zeros((height, width, 4), np.float32)
    px[..., 3] = 1
    px[:, : width // 2, 0] = 1.0
    px[:, width // 2 :, 2] = 1.0
    image.pixels.foreach_set(px[::-1].ravel())
    image.pack()
    return image


def render(scene, tmp_path, name="r"):
    path = str(tmp_path / f"{name}.exr")
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = path
    scene.render.film_transparent = True
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    w, h = img.size
    buf = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    return buf.reshape(h, w, 4)[::-1]


def signature(mat):

    return node_tree_signature(mat.node_tree) if mat and mat.node_tree else None


def test_register_unregister_leaves_nothing(addon_module):
    before = set(dir(bpy.types))
    module = addon_module
    module.register()
    assert hasattr(bpy.types.Scene, "virtual_reflections") and hasattr(bpy.ops.vr, "generate")
    module.unregister()
    assert not hasattr(bpy.types.Scene, "virtual_reflections")
    assert not hasattr(bpy.types.Object, "virtual_reflections")
    assert set(dir(bpy.types)) == before


def test_generate_builds_maps_and_nodes(addon, tmp_path):
    scene = make_scene()
    ball = add_sphere()
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.resolution = "256"
    original = signature(ball.data.materials[0])
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}
    image = bpy.data.images["VR Map Ball"]
    assert tuple(image.size) == (256, 128) and image.is_float
    slot = ball.material_slots[0]
    assert slot.link == "OBJECT" and slot.material is not ball.data.materials[0]
    assert any(n.type == "GROUP" for n in slot.material.node_tree.nodes)
    assert signature(ball.data.materials[0]) == original  # the user's material untouched
    assert "ms" in scene.virtual_reflections.last_report
    # The map is packed into the .blend when it is saved, and comes back with it.
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert bpy.data.images["VR Map Ball"].packed_file
    bpy.ops.wm.open_mainfile(filepath=path)
    ball = bpy.data.objects["Ball"]
    assert bpy.data.images["VR Map Ball"].packed_file and ball.material_slots[0].link == "OBJECT"
    # Regenerating updates the same image in place.
    assert bpy.ops.vr.generate() == {"FINISHED"}
    assert [i.name for i in bpy.data.images if i.name.startswith("VR Map")] == ["VR Map Ball"]


@pytest.mark.parametrize("method", ["PAPER", "CAMERA"])
def test_chrome_sphere_shows_the_plate_on_the_correct_sides(addon, tmp_path, method):
    scene = make_scene()
    ball = add_sphere()
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.method = method
    scene.virtual_reflections.combine = "REPLACE"
    scene.virtual_reflections.resolution = "256"
    ball.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}
    rgba = render(scene, tmp_path)
    alpha = rgba[..., 3] > 0.99
    cols = np.nonzero(alpha.any(0))[0]
    mid = (cols[0] + cols[-1]) / 2
    left = rgba[:, : int(mid) - 2][alpha[:, : int(mid) - 2]]
    right = rgba[:, int(mid) + 3 :][alpha[:, int(mid) + 3 :]]
    assert left[:, 0].mean() > 0.7 and left[:, 2].mean() < 0.2
    assert right[:, 2].mean() > 0.7 and right[:, 0].mean() < 0.2


@pytest.mark.parametrize("mode", ["REPLACE", "MODULATE", "MIX", "WORLD"])
def test_remove_restores_everything(addon, mode):
    scene = make_scene()
    ball = add_sphere()
    plain = add_sphere("Plain", location=(2.5, 0, 0), material=False)
    world = bpy.data.worlds.new("User World")
    scene.world = world
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.combine = mode
    scene.virtual_reflections.resolution = "256"
    before = {
        "materials": sorted(m.name for m in bpy.data.materials),
        "worlds": sorted(w.name for w in bpy.data.worlds),
        "images": sorted(i.name for i in bpy.data.images),
        "groups": sorted(g.name for g in bpy.data.node_groups),
        "sig": signature(ball.data.materials[0]),
        "slots": [(s.link, s.material) for s in ball.material_slots],
        "plain": len(plain.material_slots),
    }
    for obj in (ball, plain):
        obj.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}
    if mode == "WORLD":
        assert scene.world.name == "VR World"
    assert bpy.ops.vr.remove() == {"FINISHED"}
    after = {
        "materials": sorted(m.name for m in bpy.data.materials),
        "worlds": sorted(w.name for w in bpy.data.worlds),
        "images": sorted(i.name for i in bpy.data.images),
        "groups": sorted(g.name for g in bpy.data.node_groups),
        "sig": signature(ball.data.materials[0]),
        "slots": [(s.link, s.material) for s in ball.material_slots],
        "plain": len(plain.material_slots),
    }
    assert after == before
    assert scene.world == world


def test_generate_works_on_curves_and_text(addon):
    scene = make_scene()
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.resolution = "256"
    bpy.ops.curve.primitive_bezier_circle_add(radius=1.0)
    curve = bpy.context.active_object
    curve.data.bevel_depth = 0.2
    bpy.ops.object.text_add(location=(0, 0, -1.5))
    text = bpy.context.active_object
    text.data.extrude = 0.1
    for obj in (curve, text):
        obj.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}
    assert "VR Map " + curve.name in bpy.data.images and "VR Map " + text.name in bpy.data.images


def test_poll_messages_and_bad_input(addon, tmp_path):
    from vr_addon_under_test.operators import generate

    ctx = bpy.context
    assert generate.why_not_generate(ctx) == "The scene has no camera: add one and make it active"
    scene = make_scene()
    ball = add_sphere()
    ball.select_set(True)
    assert "plate" in generate.why_not_generate(ctx)
    # A plate whose file is missing on disk: a clear error, nothing changed.
    missing = bpy.data.images.new("Gone", 8, 8)
    missing.filepath = str(tmp_path / "gone.png")
    missing.source = "FILE"
    scene.virtual_reflections.plate_image = missing
    sig = signature(ball.data.materials[0])
    with pytest.raises(ValueError, match="gone.png"):
        generate.generate(ctx.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert not generate.anything_attached() and signature(ball.data.materials[0]) == sig
    with pytest.raises(RuntimeError, match="gone.png"):  # the operator reports an ERROR
        bpy.ops.vr.generate()
    # An object entirely off-screen: a warning, skipped.
    scene.virtual_reflections.plate_image = red_blue_plate()
    ball.location = (0, 0, 50)
    report = generate.generate(ctx.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert not report.done and "outside the camera view" in report.warnings[0]


def test_linked_objects_are_refused_and_left_alone(addon, tmp_path):
    # A library file with a sphere, linked (read-only) into the shot.
    add_sphere("Linked Ball")
    lib = str(tmp_path / "lib.blend")
    bpy.data.libraries.write(lib, {bpy.data.objects["Linked Ball"]})
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = make_scene()
    with bpy.data.libraries.load(lib, link=True) as (src, dst):
        dst.objects = ["Linked Ball"]
    linked = dst.objects[0]
    scene.collection.objects.link(linked)
    local = add_sphere("Local Ball", location=(2.5, 0, 0))
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.resolution = "256"
    from vr_addon_under_test.operators import generate

    report = generate.generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [linked, local]
    )
    assert report.done == ["Local Ball"]
    assert any("linked" in w and "Linked Ball" in w for w in report.warnings)
    assert linked.material_slots[0].link == "DATA" and "VR Map Linked Ball" not in bpy.data.images


def test_camera_method_places_the_plate_where_the_camera_saw_it(addon):
    """With the camera-view method, the map texel looking through a plate pixel holds that
    pixel, also with a shifted lens (the intrinsics come from the Blender camera)."""
    from vr_addon_under_test.operators import generate
    from vr_addon_under_test.virtual_reflections.layouts import texel_directions

    scene = make_scene(64, 48)
    scene.camera.data.shift_x = 0.1
    ball = add_sphere()
    plate = bpy.data.images.new("Ramp", 64, 48, alpha=False, float_buffer=True)
    py, px = np.mgrid[0:48, 0:64]
    pixels = np.ones((48, 64, 4), np.float32)
    pixels[..., 0], pixels[..., 1] = px / 63.0, py / 47.0  # top-row-first coordinates
    plate.pixels.foreach_set(pixels[::-1].ravel())
    settings = scene.virtual_reflections
    settings.plate_image, settings.method, settings.resolution = plate, "CAMERA", "1024"
    report = generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert report.done == ["Ball"]
    image = bpy.data.images["VR Map Ball"]
    w, h = image.size
    env = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(env)
    env = env.reshape(h, w, 4)[::-1]
    d = texel_directions("latlong", w)
    # Project every texel direction through the Blender camera and keep those inside the frame.
    cam = scene.camera
    # The camera frame is Blender's camera-local frame rotated 180 degrees about Y.
    blender_cam = np.stack([-d[..., 0], d[..., 1], -d[..., 2]], -1)
    frame = [v for v in cam.data.view_frame(scene=scene)]
    xs = [v.x / -v.z for v in frame]
    ys = [v.y / -v.z for v in frame]
    u = blender_cam[..., 0] / -blender_cam[..., 2]
    v = blender_cam[..., 1] / -blender_cam[..., 2]
    fpx = (u - min(xs)) / (max(xs) - min(xs)) * 64
    fpy = (max(ys) - v) / (max(ys) - min(ys)) * 48
    inside = (blender_cam[..., 2] < 0) & (fpx > 2) & (fpx < 62) & (fpy > 2) & (fpy < 46)
    assert inside.sum() > 1000
    assert np.abs(env[inside, 0] - (fpx[inside] - 0.5) / 63.0).max() < 0.02
    assert np.abs(env[inside, 1] - (fpy[inside] - 0.5) / 47.0).max() < 0.02


def test_a_new_plate_under_an_old_name_is_read_again(addon):
    """The plate cache must not hand back the pixels of a removed image whose replacement has
    the same name, size and (empty) file path."""
    scene = make_scene()
    ball = add_sphere()
    settings = scene.virtual_reflections
    settings.resolution = "256"
    settings.plate_image = red_blue_plate()
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}
    bpy.data.images.remove(bpy.data.images["Plate"])
    green = bpy.data.images.new("Plate", 64, 48, alpha=False, float_buffer=True)
    px = np.zeros((48, 64, 4), np.float32)
    px[..., 1] = px[..., 3] = 1.0
    green.pixels.foreach_set(px.ravel())
    green.pack()
    settings.plate_image = green
    assert bpy.ops.vr.generate() == {"FINISHED"}
    image = bpy.data.images["VR Map Ball"]
    rgb = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(rgb)
    mean = rgb.reshape(-1, 4)[:, :3].mean(0)
    # green, not the old red/blue plate (above the horizon the unseen sky is a neutral grey)
    assert mean[1] > 0.5 and mean[1] > max(mean[0], mean[2]) + 0.2, mean


# --- map images never leak into the file (issue 14, case 15) ---------------------------------


def _maps():
    return sorted(i.name for i in bpy.data.images if i.get("vr_created") == "map")


def test_a_name_at_the_length_limit_gets_one_map(addon):
    from vr_addon_under_test.operators import generate

    scene = make_scene()
    scene.virtual_reflections.plate_image = red_blue_plate()
    ball = add_sphere("B" * 63)  # Blender's longest name: "VR Map " + it would be cut
    for _ in range(3):
        report = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [ball])
        assert report.done == [ball.name], report.warnings
    assert len(_maps()) == 1 and len(_maps()[0].encode()) <= 63


def test_renaming_an_object_leaves_no_old_map(addon):
    from vr_addon_under_test.operators import generate

    scene = make_scene()
    scene.virtual_reflections.plate_image = red_blue_plate()
    ball = add_sphere("Ball")
    generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert _maps() == ["VR Map Ball"]
    ball.name = "Renamed"
    generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert _maps() == ["VR Map Renamed"]


def test_a_deleted_objects_map_can_be_removed(addon):
    from vr_addon_under_test.operators import generate

    scene = make_scene()
    scene.virtual_reflections.plate_image = red_blue_plate()
    ball, other = add_sphere("Ball"), add_sphere("Other", location=(2, 0, 0))
    generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [ball])
    bpy.data.objects.remove(ball)
    generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [other])
    assert _maps() == ["VR Map Other"]  # Generate clears the map no object reflects
    bpy.data.objects.remove(other)
    assert _maps() == ["VR Map Other"]  # kept (packed at the next save) until ...
    assert generate.anything_attached()  # ... Remove, which is offered
    assert bpy.ops.vr.remove() == {"FINISHED"}
    assert _maps() == []
