"""Assets brought into a shot from a library (issue 40): a library override of a linked object
takes a reflection, its linked material copied and never edited, and Remove restores it; a
linked object that is not an override is refused with what to do."""

import bpy
import pytest
from shots import add_camera, addon_part, ramp_plate


@pytest.fixture
def library(tmp_path, clean_file):
    """lib.blend: a collection "Asset" holding the sphere "Ball" with the material "Chrome"."""
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    ball = bpy.context.active_object
    ball.name = "Ball"
    chrome = bpy.data.materials.new("Chrome")
    chrome.diffuse_color = (0.2, 0.4, 0.6, 1.0)
    ball.data.materials.append(chrome)
    asset = bpy.data.collections.new("Asset")
    bpy.context.scene.collection.children.link(asset)
    bpy.context.scene.collection.objects.unlink(ball)
    asset.objects.link(ball)
    path = tmp_path / "lib.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def shot_with_asset(addon, library):
    """A new shot with the library's Asset instanced into it; returns (scene, instance)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    with bpy.data.libraries.load(str(library), link=True) as (_, linked):
        linked.collections = ["Asset"]
    scene = bpy.context.scene
    add_camera(scene, size=(96, 64))
    scene.virtual_reflections.plate_image = ramp_plate()
    scene.virtual_reflections.resolution = "256"
    instance = bpy.data.objects.new("Asset", None)
    instance.instance_type = "COLLECTION"
    instance.instance_collection = linked.collections[0]
    scene.collection.objects.link(instance)
    return scene, instance


def material_state(obj):
    shading = addon_part("operators.node_trees.shading")
    name = lambda mat: mat and (mat.name, mat.library is not None)  # noqa: E731
    return [(link, name(data), name(own)) for link, data, own in shading.slot_states(obj)]


def test_a_library_override_takes_a_reflection_and_gives_it_back(addon, library, tmp_path):
    scene, instance = shot_with_asset(addon, library)
    bpy.ops.object.select_all(action="DESELECT")
    bpy.context.view_layer.objects.active = instance
    instance.select_set(True)
    assert bpy.ops.object.make_override_library() == {"FINISHED"}
    ball = next(o for o in bpy.data.objects if o.override_library is not None)
    chrome = ball.material_slots[0].material
    assert chrome.library is not None  # the override's material is the library's
    before = material_state(ball)
    chrome_colour = tuple(chrome.diffuse_color)
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True)
    bpy.context.view_layer.objects.active = ball
    assert bpy.ops.vr.generate() == {"FINISHED"}
    last = scene.virtual_reflections.last_report
    assert "linked" not in last and "read-only" not in last, last
    shading = addon_part("operators.node_trees.shading")
    assert shading.is_attached(ball) and shading.map_of(ball) is not None
    slot = ball.material_slots[0]
    assert slot.link == "OBJECT" and slot.material.library is None  # its own copy, local
    assert chrome.library is not None and tuple(chrome.diffuse_color) == chrome_colour
    # Saved and opened again: the override keeps its reflection (the overrides are re-made
    # from the library on load).
    bounds = tuple(ball.virtual_reflections.bounds)
    assert any(bounds)
    shot = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))
    bpy.ops.wm.open_mainfile(filepath=str(shot))
    ball = next(o for o in bpy.data.objects if o.override_library is not None)
    assert shading.is_attached(ball) and ball.material_slots[0].link == "OBJECT"
    assert shading.map_of(ball) == bpy.data.images["VR Map Ball"]
    assert tuple(ball.virtual_reflections.bounds) == bounds  # the panel's preview
    assert bpy.ops.vr.remove() == {"FINISHED"}
    assert not shading.is_attached(ball) and material_state(ball) == before
    assert not [m for m in bpy.data.materials if m.get("vr_created")]
    assert not [s for s in bpy.data.scenes if s.get("vr_override_shading")]


def test_a_linked_object_says_to_make_it_a_library_override(addon, library):
    scene, _ = shot_with_asset(addon, library)
    ball = next(o for o in bpy.data.objects if o.library is not None and o.type == "MESH")
    generate = addon_part("operators.generate")
    report = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert not report.done
    said = [w for w in report.warnings if "Ball" in w]
    assert said and "Object > Library Override > Make" in said[0], report.warnings
    assert ball.material_slots[0].link == "DATA"
