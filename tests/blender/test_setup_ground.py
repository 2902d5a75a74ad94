"""Set Up From Plate's shadow-catcher ground (operators/compositor.py `add_ground`): a plane
under the objects that `floor.ground_height` finds, tagged as ours, removed by Undo; and
through the operator, a Cycles render where the ground darkens the plate under the object."""

import importlib

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
oiio = pytest.importorskip("OpenImageIO")


@pytest.fixture
def modules(addon):
    name = addon.__name__ + ".operators."
    return (
        importlib.import_module(name + "compositor"),
        importlib.import_module(name + "scene.floor"),
    )


def write_plate(path, width=48, height=32, value=180):
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(width, height, 3, "uint8"))
    out.write_image(np.full((height, width, 3), value, np.uint8))
    out.close()
    return path


def scene_with_cube(tmp_path, z=1.5):
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    camera.location, camera.rotation_euler = (0, -8, 4), (1.1, 0, 0)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.5, 0.0, z))
    cube = bpy.context.active_object
    image = bpy.data.images.load(str(write_plate(tmp_path / "plate.png")))
    scene.virtual_reflections.plate_image = image
    return scene, cube, image


def test_ground_under_the_objects_is_found_and_undone(modules, tmp_path):
    comp, floor = modules
    scene, cube, image = scene_with_cube(tmp_path)
    before = {o.name for o in bpy.data.objects}, {m.name for m in bpy.data.meshes}
    record = comp.setup_from_plate(scene, image, ground=True)
    ground = bpy.data.objects[record["ground"]["object"]]
    assert ground.is_shadow_catcher and ground.get("vr_created") == "ground"
    assert ground.data.get("vr_created") == "ground"
    assert ground.location.z == pytest.approx(1.0)  # the cube's bottom
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert floor.ground_height(scene, depsgraph, [cube]) == pytest.approx(1.0)
    assert comp.undo_setup_from_plate(scene)
    assert ({o.name for o in bpy.data.objects}, {m.name for m in bpy.data.meshes}) == before


def test_no_second_ground(modules, tmp_path):
    comp, _ = modules
    scene, cube, image = scene_with_cube(tmp_path)
    scene.virtual_reflections.ground_object = cube
    assert comp.setup_from_plate(scene, image, ground=True)["ground"] is None
    comp.undo_setup_from_plate(scene)
    scene.virtual_reflections.ground_object = None
    bpy.ops.mesh.primitive_plane_add(size=10)
    bpy.context.active_object.is_shadow_catcher = True
    assert comp.setup_from_plate(scene, image, ground=True)["ground"] is None
    assert comp.setup_from_plate(scene, image)["ground"] is None  # the default: no ground


EEVEE = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"


def surface_of(material, target):
    """The type of the shader node feeding ``material``'s output for ``target``'s engine."""
    output = material.node_tree.get_output_node(target)
    return output.inputs["Surface"].links[0].from_node.type


def test_ground_holds_out_in_eevee_and_catches_shadows_in_cycles(modules, tmp_path):
    """EEVEE (Blender's default engine) has no shadow catcher: the ground gives it a Holdout,
    so F12 shows the plate there; Cycles keeps its shadow catcher with the default grey
    surface. The file's engine is left as it is, and Undo removes the material too."""
    comp, _ = modules
    scene, _cube, image = scene_with_cube(tmp_path)
    scene.render.engine = EEVEE
    record = comp.setup_from_plate(scene, image, ground=True)
    assert scene.render.engine == EEVEE
    ground = bpy.data.objects[record["ground"]["object"]]
    assert ground.is_shadow_catcher
    (material,) = ground.data.materials
    name = material.name
    assert material.get("vr_created") == "ground"
    assert surface_of(material, "EEVEE") == "HOLDOUT"
    assert surface_of(material, "CYCLES") == "BSDF_DIFFUSE"
    assert not [line for line in record["advice"] if "shadow catcher" in line]
    assert comp.undo_setup_from_plate(scene)
    assert name not in bpy.data.materials


def test_operator_says_what_eevee_shows(modules, tmp_path):
    scene, _cube, _image = scene_with_cube(tmp_path)
    scene.render.engine = EEVEE
    reports = []
    operator = type("Op", (), {"ground": True, "lens": False})()
    operator.report = lambda level, text: reports.append((set(level), text))
    setup = bpy.types.VR_OT_setup_plate
    assert setup.execute(operator, bpy.context) == {"FINISHED"}
    assert "EEVEE shows the plate there" in reports[0][1], reports


def test_a_shadow_catcher_of_the_artist_in_eevee_is_warned_about(modules, tmp_path):
    """Set Up does not edit the artist's own shadow catcher, which EEVEE draws opaque: it
    says so (in Cycles it does not need to)."""
    comp, _ = modules
    scene, _cube, image = scene_with_cube(tmp_path)
    bpy.ops.mesh.primitive_plane_add(size=10)
    bpy.context.active_object.is_shadow_catcher = True
    bpy.context.active_object.name = "Floor"
    scene.render.engine = "CYCLES"
    assert not [x for x in comp.setup_from_plate(scene, image)["advice"] if "Floor" in x]
    scene.render.engine = EEVEE
    (line,) = [x for x in comp.setup_from_plate(scene, image)["advice"] if "Floor" in x]
    assert line.startswith("Warning: EEVEE draws the shadow catcher 'Floor' as an opaque")


def render(scene, path):
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    found = oiio.ImageInput.open(str(path))
    out = found.read_image("uint8").astype(int)
    found.close()
    return out


def test_operator_ground_catches_the_shadow(modules, tmp_path):
    scene, cube, image = scene_with_cube(tmp_path, z=1.0)
    cube.scale = (2, 2, 2)  # 2 m across, standing on Z = 0
    light = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    light.data.energy = 3.0
    light.rotation_euler = (0.8, 0.4, 0)  # a long shadow
    scene.collection.objects.link(light)
    assert bpy.ops.vr.setup_plate() == {"FINISHED"}  # the ground is on by default
    assert bpy.data.objects["VR Ground"].is_shadow_catcher
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples, scene.cycles.use_denoising = "CPU", 8, False
    scene.render.compositor_device = "CPU"
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "PNG", "8", "RGB"
    out = render(scene, tmp_path / "out.png")
    ground = bpy.data.objects["VR Ground"]
    ground.hide_render = True
    floating = render(scene, tmp_path / "floating.png")
    ground.hide_render = False
    # Away from the cube and its shadow the plate is untouched; the shadow darkens some of it.
    plate_level = (np.abs(out - 180) <= 1).all(axis=2).mean()
    shadow = (out.max(axis=2) < floating.max(axis=2) - 20).mean()
    assert plate_level > 0.5 and shadow > 0.02, (plate_level, shadow)
    assert bpy.ops.vr.undo_setup_plate() == {"FINISHED"}
    assert "VR Ground" not in bpy.data.objects and "VR Ground" not in bpy.data.meshes
