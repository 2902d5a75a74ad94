"""operators/compositor.py and plate.py: plate pixels, the scene's plate, compositor set-up and
undo, alpha-over (operators/scene/composite.py).

Plates are written with OpenImageIO (top row first) into tmp_path. Colour: arrays are
scene-linear Rec.709 float32; 8-bit files are sRGB-encoded. The compositor differs between
Blender 4.5 (``scene.node_tree`` + Composite node) and 5.x (``scene.compositing_node_group``, a
node group whose Group Output is the result); both are exercised by whichever bpy runs this.
"""

import importlib
import math
import types

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
oiio = pytest.importorskip("OpenImageIO")

GROUPS = "compositing_node_group" in bpy.types.Scene.bl_rna.properties  # Blender 5.0+


@pytest.fixture
def comp(addon):
    """operators/compositor.py, imported from the extension package on a fresh empty file."""
    return importlib.import_module(addon.__name__ + ".operators.compositor")


@pytest.fixture
def plates(addon):
    """operators/scene/plate.py: the scene's plate and its pixels."""
    return importlib.import_module(addon.__name__ + ".operators.scene.plate")


@pytest.fixture
def composite(addon):
    return importlib.import_module(addon.__name__ + ".operators.scene.composite")


@pytest.fixture
def colour(addon):
    return importlib.import_module(addon.__name__ + ".virtual_reflections.colour")


def write_image(path, pixels, dtype):
    """(H, W, C) array, top row first -> an image file (format from the extension)."""
    height, width, channels = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(width, height, channels, dtype)), oiio.geterror()
    assert out.write_image(pixels), out.geterror()
    out.close()
    return path


def read_image(path):
    """An image file -> (H, W, C) float32, top row first."""
    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    pixels = image.read_image("float")
    image.close()
    return pixels


def add_camera(scene, name="Camera"):
    data = bpy.data.cameras.new(name)
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def gradient_plate(width=6, height=4):
    """(H, W, 3) float32 with a different value at every pixel (so flips show), some > 1."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    return np.stack([x / width * 2.0, y / height, np.full_like(x, 0.25)], axis=-1)


# --- plate_image_pixels --------------------------------------------------------------------------


def test_png_is_srgb_decoded_and_top_row_first(comp, plates, colour, tmp_path):
    pixels = np.zeros((2, 3, 3), np.uint8)
    pixels[0] = 128  # top row of the file
    pixels[1] = 255
    pixels[0, 0] = (255, 0, 64)  # top-left marker
    image = bpy.data.images.load(str(write_image(tmp_path / "p8.png", pixels, "uint8")))
    plate, info = plates.image_pixels(image)
    assert plate.shape == (2, 3, 3) and plate.dtype == np.float32
    assert plate[0, 1:] == pytest.approx(0.2158, abs=5e-4)  # 128 -> sRGB EOTF
    assert np.allclose(plate[0, 1:], colour.srgb_to_linear(128 / 255), atol=1e-6)
    assert np.allclose(plate[1], 1.0)
    assert np.allclose(plate[0, 0], colour.srgb_to_linear(np.array([255, 0, 64]) / 255), atol=1e-6)
    assert "sRGB" in info and "3x2" in info


def test_exr_is_used_as_is(comp, plates, tmp_path):
    pixels = gradient_plate()
    pixels[1, 2] = (-0.5, 7.0, 1000.0)  # scene-linear values outside [0, 1] survive
    image = bpy.data.images.load(str(write_image(tmp_path / "p.exr", pixels, "float")))
    plate, info = plates.image_pixels(image)
    assert plate.shape == pixels.shape
    assert np.array_equal(plate, pixels)  # top row first, no colour change
    assert "scene-linear" in info


def test_sixteen_bit_png_is_linear_float(comp, plates, colour, tmp_path):
    pixels = np.full((2, 2, 3), 32768, np.uint16)
    image = bpy.data.images.load(str(write_image(tmp_path / "p16.png", pixels, "uint16")))
    assert image.is_float  # Blender loads 16-bit PNGs into a linearised float buffer
    plate, _ = plates.image_pixels(image)
    assert np.allclose(plate, colour.srgb_to_linear(32768 / 65535), atol=1e-4)


def test_non_color_images_are_used_as_is(comp, plates, tmp_path):
    pixels = np.full((2, 2, 3), 128, np.uint8)
    image = bpy.data.images.load(str(write_image(tmp_path / "data.png", pixels, "uint8")))
    image.colorspace_settings.name = "Non-Color"
    plate, info = plates.image_pixels(image)
    assert np.allclose(plate, 128 / 255)
    assert "Non-Color" in info and "as is" in info

    data = bpy.data.images.new("Data", 2, 2, float_buffer=True)
    data.colorspace_settings.name = "Non-Color"
    data.pixels.foreach_set(np.full(16, 0.5, np.float32))
    plate, info = plates.image_pixels(data)
    assert np.allclose(plate, 0.5) and "Non-Color" in info


def test_missing_file_names_the_file(comp, plates, tmp_path):
    path = write_image(tmp_path / "gone.png", np.zeros((2, 2, 3), np.uint8), "uint8")
    image = bpy.data.images.load(str(path))
    path.unlink()
    image.reload()
    with pytest.raises(ValueError, match="file not found: .*gone.png"):
        plates.image_pixels(image)

    never = bpy.data.images.new("Never", 2, 2)
    never.source = "FILE"
    never.filepath = str(tmp_path / "never_existed.exr")
    with pytest.raises(ValueError, match="never_existed.exr"):
        plates.image_pixels(never)


def test_unloadable_file(comp, plates, tmp_path):
    path = tmp_path / "damaged.png"
    path.write_bytes(b"not a png at all")
    image = bpy.data.images.load(str(path))
    with pytest.raises(ValueError, match="could not be loaded from .*damaged.png"):
        plates.image_pixels(image)


def test_no_image_and_empty_image(comp, plates):
    with pytest.raises(ValueError, match="No plate image"):
        plates.image_pixels(None)
    empty = bpy.data.images.new("Empty", 4, 4)
    empty.source = "FILE"  # a file image without a file: no pixels at all
    with pytest.raises(ValueError, match=r"'Empty' has no pixels \(0x0\)"):
        plates.image_pixels(empty)


def test_nan_and_inf_are_replaced_and_counted(comp, plates):
    image = bpy.data.images.new("Bad", 3, 2, float_buffer=True)
    values = np.full((2, 3, 4), 0.5, np.float32)
    values[0, 0, 0] = np.nan
    values[1, 2, 1] = np.inf
    values[1, 1, 2] = -np.inf
    values[0, 1, 3] = np.nan  # alpha: ignored, not counted
    image.pixels.foreach_set(values.ravel())
    plate, info = plates.image_pixels(image)
    assert np.isfinite(plate).all()
    assert "3 NaN/Inf values replaced" in info
    # Blender's row 0 is the bottom: the NaN at (bottom, left) is at the last row here.
    assert plate[1, 0, 0] == 0.0


# --- scene_plate ---------------------------------------------------------------------------------


def test_scene_plate_prefers_the_property_then_the_camera_background(comp, plates):
    scene = bpy.context.scene
    assert plates.scene_plate(scene) is None  # no camera
    camera = add_camera(scene)
    assert plates.scene_plate(scene) is None  # no background images
    hidden, shown = bpy.data.images.new("Hidden", 2, 2), bpy.data.images.new("Shown", 2, 2)
    entry = camera.data.background_images.new()
    entry.image, entry.show_background_image = hidden, False
    entry = camera.data.background_images.new()
    entry.image = shown
    assert plates.scene_plate(scene) == shown

    chosen = bpy.data.images.new("Chosen", 2, 2)
    with_property = types.SimpleNamespace(
        virtual_reflections=types.SimpleNamespace(plate_image=chosen), camera=camera
    )
    assert plates.scene_plate(with_property) == chosen
    unset = types.SimpleNamespace(
        virtual_reflections=types.SimpleNamespace(plate_image=None), camera=camera
    )
    assert plates.scene_plate(unset) == shown


# --- setup_from_plate / undo ---------------------------------------------------------------------


def node_state(tree):
    """Everything about a node tree's nodes and links that a user would notice."""
    nodes = {}
    for node in tree.nodes:
        settings = {}
        for prop in node.bl_rna.properties:
            if prop.is_readonly or prop.type in {"POINTER", "COLLECTION"}:
                continue
            value = getattr(node, prop.identifier)
            settings[prop.identifier] = (
                tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value
            )
        for name in ("image", "scene", "node_tree"):
            if hasattr(node, name):
                settings[name] = getattr(getattr(node, name), "name", None)
        inputs = [
            (
                s.identifier,
                tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value,
            )
            for s in node.inputs
            if hasattr(s, "default_value") and not isinstance(s.default_value, str)
        ]
        nodes[node.name] = (node.bl_idname, settings, inputs)
    links = sorted(
        (lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
        for lk in tree.links
    )
    active = tree.nodes.active.name if tree.nodes.active else None
    return nodes, links, active


def scene_state(scene):
    """Render settings, camera backgrounds and the compositor, for before/after comparisons."""
    render = scene.render
    state = {
        "render": (
            render.resolution_x,
            render.resolution_y,
            render.resolution_percentage,
            render.pixel_aspect_x,
            render.pixel_aspect_y,
            render.film_transparent,
            render.use_compositing,
        ),
        "record": "vr_plate_setup" in scene,
        "cameras": {
            c.name: (
                c.show_background_images,
                [
                    (b.image.name if b.image else None, b.show_background_image, b.alpha)
                    for b in c.background_images
                ],
            )
            for c in bpy.data.cameras
        },
        "images": sorted((i.name, i.users) for i in bpy.data.images),
    }
    if GROUPS:
        group = scene.compositing_node_group
        state["group"] = group.name if group else None
        state["groups"] = {g.name: (g.users, node_state(g)) for g in bpy.data.node_groups}
    else:
        state["use_nodes"] = scene.use_nodes
        state["tree"] = node_state(scene.node_tree) if scene.node_tree else None
    return state


def assert_restored(scene, before):
    """The scene is as `before`. One exception, 4.5 only: a scene without a compositor gets the
    embedded default tree when use_nodes is first switched on; it cannot be deleted, so undo
    switches use_nodes off again and leaves Blender's default nodes (and their Viewer image)."""
    after = scene_state(scene)
    if not GROUPS and before["tree"] is None and after["tree"] is not None:
        nodes, links, _ = after["tree"]
        kinds = {kind for kind, _, _ in nodes.values()}
        assert not scene.use_nodes
        assert not [name for name in nodes if name.startswith("VR ")]
        assert kinds <= {"CompositorNodeRLayers", "CompositorNodeComposite", "NodeReroute",
                         "CompositorNodeViewer"}  # fmt: skip
        assert any(link[2:] == ("Composite", "Image") for link in links)
        after["tree"] = None
        if "CompositorNodeViewer" in kinds:
            after["images"] = [i for i in after["images"] if i[0] != "Viewer Node"]
    assert after == before


def plate_scene(tmp_path, width=64, height=36):
    """An empty scene with a camera at 1920x1080 50 %, pixel aspect 2:1, and a plate image."""
    scene = bpy.context.scene
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = 1920, 1080, 50
    render.pixel_aspect_x, render.pixel_aspect_y = 2.0, 1.0
    render.film_transparent = render.use_compositing = False
    add_camera(scene)
    path = write_image(tmp_path / "plate.exr", gradient_plate(width, height), "float")
    return scene, bpy.data.images.load(str(path))


def compositor_output(scene):
    """(tree, the socket that is the compositor's result) for either API."""
    if GROUPS:
        tree = scene.compositing_node_group
        output = next(n for n in tree.nodes if n.bl_idname == "NodeGroupOutput")
        return tree, output.inputs[0]
    tree = scene.node_tree
    return tree, next(n for n in tree.nodes if n.type == "COMPOSITE").inputs[0]


def test_setup_sets_render_background_film_and_compositor(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    record = comp.setup_from_plate(scene, image)
    render = scene.render
    assert (render.resolution_x, render.resolution_y, render.resolution_percentage) == (64, 36, 100)
    assert (render.pixel_aspect_x, render.pixel_aspect_y) == (1.0, 1.0)
    assert render.film_transparent and render.use_compositing
    camera = scene.camera.data
    assert camera.show_background_images
    assert [(b.image, b.show_background_image) for b in camera.background_images] == [(image, True)]
    assert record["resolution"] == [1920, 1080, 50] and record["camera"]["added"]

    tree, result = compositor_output(scene)
    over = result.links[0].from_node
    assert over.name == "VR Alpha Over"
    scale = over.inputs[0 if GROUPS else 1].links[0].from_node  # the background input
    assert scale.bl_idname == "CompositorNodeScale"  # the plate stretched to the render size
    plate_node = scale.inputs[0].links[0].from_node
    assert plate_node.bl_idname == "CompositorNodeImage" and plate_node.image == image
    foreground = over.inputs[1 if GROUPS else 2].links[0].from_node
    assert foreground.bl_idname in {"CompositorNodeRLayers", "NodeReroute"}
    viewers = [n for n in tree.nodes if n.bl_idname == "CompositorNodeViewer"]
    assert any(v.inputs[0].links and v.inputs[0].links[0].from_node == over for v in viewers)
    if GROUPS:
        assert tree.name == "VR Composite" and tree.bl_idname == "CompositorNodeTree"
    else:
        assert scene.use_nodes


def test_undo_without_a_previous_compositor(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    before = scene_state(scene)
    comp.setup_from_plate(scene, image)
    assert scene_state(scene) != before
    assert comp.undo_setup_from_plate(scene)
    assert_restored(scene, before)
    assert "VR Composite" not in bpy.data.node_groups
    assert not comp.undo_setup_from_plate(scene)  # nothing left to undo


def add_user_compositor(scene):
    """The user's own compositor: Render Layers -> Exposure (+1 stop) -> output, plus extras."""
    if GROUPS:
        other = bpy.data.node_groups.new("Unrelated", "CompositorNodeTree")
        other.use_fake_user = True
        tree = bpy.data.node_groups.new("My Compositing", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        output = tree.nodes.new("NodeGroupOutput")
        scene.compositing_node_group = tree
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        for node in list(tree.nodes):
            tree.nodes.remove(node)
        output = tree.nodes.new("CompositorNodeComposite")
        output.name = "My Composite"
    layers = tree.nodes.new("CompositorNodeRLayers")
    layers.name = "My Layers"
    exposure = tree.nodes.new("CompositorNodeExposure")
    exposure.name = "My Exposure"
    exposure.inputs["Exposure"].default_value = 1.0
    blur = tree.nodes.new("CompositorNodeBlur")  # a side branch that must survive unchanged
    blur.name, blur.mute, blur.location = "My Blur", True, (123, -45)
    tree.links.new(layers.outputs["Image"], exposure.inputs["Image"])
    tree.links.new(exposure.outputs["Image"], output.inputs[0])
    tree.links.new(layers.outputs["Image"], blur.inputs["Image"])
    tree.nodes.active = blur
    return exposure


def test_undo_restores_a_user_compositor(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    exposure = add_user_compositor(scene)
    before = scene_state(scene)
    comp.setup_from_plate(scene, image)
    tree, result = compositor_output(scene)
    over = result.links[0].from_node
    foreground = over.inputs[1 if GROUPS else 2].links[0].from_node
    if GROUPS:  # the user's group, nested: its result goes over the plate
        assert foreground.bl_idname == "CompositorNodeGroup"
        assert foreground.node_tree.name == "My Compositing"
    else:  # routed through: the user's last node feeds our Alpha Over
        assert foreground == exposure
        assert tree.nodes["My Blur"].mute and tuple(tree.nodes["My Blur"].location) == (123, -45)
    assert comp.undo_setup_from_plate(scene)
    assert_restored(scene, before)


def test_setup_twice_does_not_stack(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    add_user_compositor(scene)
    before = scene_state(scene)
    comp.setup_from_plate(scene, image)
    once = scene_state(scene)
    comp.setup_from_plate(scene, image)
    assert scene_state(scene) == once
    assert len(scene.camera.data.background_images) == 1
    assert comp.undo_setup_from_plate(scene)
    assert_restored(scene, before)


def test_setup_reuses_an_existing_background_entry(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    camera = scene.camera.data
    other = camera.background_images.new()
    other.image = bpy.data.images.new("Other", 2, 2)
    mine = camera.background_images.new()
    mine.image, mine.show_background_image, mine.alpha = image, False, 0.3
    before = scene_state(scene)
    comp.setup_from_plate(scene, image)
    assert len(camera.background_images) == 2 and camera.background_images[1].show_background_image
    comp.undo_setup_from_plate(scene)
    assert_restored(scene, before)


def test_setup_rejects_missing_plates(comp, tmp_path):
    scene, image = plate_scene(tmp_path)
    (tmp_path / "plate.exr").unlink()
    image.reload()
    before = scene_state(scene)
    with pytest.raises(ValueError, match="plate.exr"):
        comp.setup_from_plate(scene, image)
    assert scene_state(scene) == before


# --- composite_over_plate, and Blender's compositor agreeing with it ----------------------------


def test_composite_over_plate_numbers(comp, composite):
    render = np.array([[[0.5, 0.25, 0.0, 0.5], [0, 0, 0, 0], [2.0, 1.0, 0.5, 1.0]]], np.float32)
    plate = np.array([[[1.0, 1.0, 1.0], [0.2, 0.3, 0.4], [9.0, 9.0, 9.0]]], np.float32)
    out = composite.over(render, plate)
    assert out.dtype == np.float32
    assert np.allclose(out, [[[1.0, 0.75, 0.5], [0.2, 0.3, 0.4], [2.0, 1.0, 0.5]]])
    with pytest.raises(ValueError, match="RGBA"):
        composite.over(render[..., :3], plate)
    with pytest.raises(ValueError, match="plate"):
        composite.over(render, plate[:, :2])


def build_render_scene(scene):
    """A camera, a tilted red plane partly covering the frame, a blue world: Cycles CPU, linear."""
    camera = scene.camera
    camera.location, camera.rotation_euler = (0, -5, 0), (math.pi / 2, 0, 0)
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], [], [(0, 1, 2, 3)])
    plane = bpy.data.objects.new("Plane", mesh)
    scene.collection.objects.link(plane)
    plane.rotation_euler = (0, 0.3, 0.2)  # edges cross pixels: fractional alpha
    material = bpy.data.materials.new("Red")
    material.diffuse_color = (0.8, 0.2, 0.1, 1.0)
    mesh.materials.append(material)
    world = bpy.data.worlds.new("Sky")
    world.color = (0.5, 0.6, 0.9)
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.render.compositor_device = "CPU"  # 5.x defaults to GPU; none here
    view = scene.view_settings
    view.view_transform, view.look, view.exposure, view.gamma = "Standard", "None", 0.0, 1.0
    if hasattr(bpy.data, "colorspace"):  # 5.x: the working space is per file
        assert bpy.data.colorspace.working_space == "Linear Rec.709"
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", "RGBA"


def render_to(scene, path, compositing):
    scene.render.use_compositing = compositing
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_image(path)


@pytest.mark.parametrize("plate_format", ["exr", "png"])
@pytest.mark.parametrize("user_compositor", [False, True], ids=["fresh", "user-compositor"])
def test_blender_composite_matches_numpy(
    comp, composite, plates, tmp_path, plate_format, user_compositor
):
    scene, image = plate_scene(tmp_path)
    if plate_format == "png":  # 8-bit sRGB: Blender's Image node decodes it through OCIO
        encoded = np.clip(gradient_plate(64, 36), 0, 1) ** (1 / 2.2)
        path = write_image(
            tmp_path / "plate.png", (encoded * 255).round().astype(np.uint8), "uint8"
        )
        image = bpy.data.images.load(str(path))
    build_render_scene(scene)
    if user_compositor:
        add_user_compositor(scene)
    comp.setup_from_plate(scene, image)
    plate, _ = plates.image_pixels(image)

    raw = render_to(scene, tmp_path / "raw.exr", compositing=False)  # Cycles is deterministic
    blended = render_to(scene, tmp_path / "composite.exr", compositing=True)
    assert raw.shape == (36, 64, 4) and blended.shape == (36, 64, 4)
    alpha = raw[..., 3]
    assert alpha.min() == 0.0 and alpha.max() == 1.0 and ((alpha > 0) & (alpha < 1)).any()
    if user_compositor:  # the user's Exposure node (+1 stop) runs underneath the plate
        raw = raw * np.array([2.0, 2.0, 2.0, 1.0], np.float32)
    expected = composite.over(raw, plate)
    tolerance = 1e-4 if plate_format == "png" else 1e-5  # OCIO's sRGB vs the exact EOTF
    assert np.abs(blended[..., :3] - expected).max() < tolerance
    assert np.abs(blended[..., :3] - plate).max() > 0.1  # the plane is really there


@pytest.mark.parametrize("percent", [200, 50])
def test_composite_at_another_resolution_is_the_plate_to_its_border(comp, tmp_path, percent):
    """At 200 % the plate is stretched to twice its size: its outermost pixels too are the
    plate, opaque (a bilinear scale reading past the plate's edge made them 0.75 alpha, 0.56
    in the corners, the colour faded with it)."""
    scene, _ = plate_scene(tmp_path)
    colour = (0.6, 0.3, 0.15)
    path = write_image(tmp_path / "flat.exr", np.full((8, 16, 3), colour, np.float32), "float")
    comp.setup_from_plate(scene, bpy.data.images.load(str(path)))  # nothing before the camera
    build_render_scene(scene)
    bpy.data.objects.remove(bpy.data.objects["Plane"])
    scene.render.resolution_percentage = percent
    out = render_to(scene, tmp_path / "out.exr", compositing=True)
    assert out.shape == (8 * percent // 100, 16 * percent // 100, 4)
    assert np.abs(out[..., 3] - 1.0).max() < 1e-6, out[..., 3]
    assert np.abs(out[..., :3] - colour).max() < 1e-5
