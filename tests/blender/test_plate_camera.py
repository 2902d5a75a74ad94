"""Blender sees what the engine says it sees: a camera set up from a sample plate's json, in a
world that is the same HDRI on an Environment Texture, renders `panorama.perspective_plate`.

This pins Blender's equirectangular mapping, the camera rotation (Euler XYZ), the lens from the
horizontal field of view and the plate's pixel grid (a half-pixel shift or a mirror fails).
"""

import json
import math
import pathlib

import numpy as np
import pytest

from study import panorama

bpy = pytest.importorskip("bpy", reason="the bpy module is not installed in this environment")
oiio = pytest.importorskip("OpenImageIO")

ROOT = pathlib.Path(__file__).resolve().parents[2]
PLATES = ROOT / "sample_scenes" / "plates"
NAMES = ("courtyard", "city", "sunset")
LINEAR = "Linear Rec.709"
# Small renders: 1/8 of the plate, so the committed 1280 x 720 EXR compares by 8 x 8 averages.
WIDTH, HEIGHT, SCALE = 160, 90, 8
SAMPLES = 32
TOLERANCE = 0.02  # mean |render - plate| / mean(plate); measured ~0.002-0.005


def plate_camera_json(name):
    return json.loads((PLATES / f"{name}.json").read_text())


def hdri_path(filename):
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    return pathlib.Path(folder) / filename


def use_linear_rec709_working_space():
    """Blender 5.x files carry their own working space; the plates are linear Rec.709."""
    colorspace = getattr(bpy.data, "colorspace", None)
    if colorspace is not None and colorspace.working_space != LINEAR:
        bpy.ops.wm.set_working_color_space(convert_colors=False, working_space=LINEAR)


def add_plate_camera(scene, camera_json):
    data = bpy.data.cameras.new("Plate")
    data.type = "PERSP"
    data.sensor_fit = camera_json["sensor_fit"]
    data.sensor_width = 36.0
    data.lens = panorama.lens_mm(camera_json["hfov_deg"], data.sensor_width)
    data.shift_x = data.shift_y = 0.0
    camera = bpy.data.objects.new("Plate", data)
    scene.collection.objects.link(camera)
    camera.location = camera_json["camera_location"]
    camera.rotation_mode = "XYZ"
    camera.rotation_euler = camera_json["camera_rotation_euler"]
    scene.camera = camera
    return camera


def set_hdri_world(scene, path):
    """World = Background(Environment Texture(HDRI)), Blender's own default mapping."""
    world = bpy.data.worlds.new("Plate HDRI")
    if world.node_tree is None:  # 4.x; in 5.x worlds have node trees (use_nodes is deprecated)
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    image = bpy.data.images.load(str(path), check_existing=True)
    image.colorspace_settings.name = LINEAR
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = image
    texture.projection = "EQUIRECTANGULAR"
    texture.interpolation = "Linear"
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = 1.0
    output = nodes.new("ShaderNodeOutputWorld")
    links.new(texture.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], output.inputs["Surface"])
    scene.world = world


def render_linear(scene, path):
    """Cycles render -> float EXR in linear Rec.709 -> `(H, W, 3)` float32 (y down)."""
    render = scene.render
    render.engine = "CYCLES"
    render.resolution_x, render.resolution_y = WIDTH, HEIGHT
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.film_transparent = False
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = SAMPLES
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = 0
    # A box of one pixel: its expectation is perspective_plate's n x n box average.
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    settings = render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGB"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    settings.color_management = "OVERRIDE"
    settings.linear_colorspace_settings.name = LINEAR
    render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return np.asarray(oiio.ImageBuf(str(path)).get_pixels(oiio.FLOAT))[:, :, :3]


def relative_error(got, expected):
    return float(np.abs(got - expected).mean() / expected.mean())


@pytest.mark.parametrize("name", NAMES)
def test_camera_from_json_is_the_engine_camera(clean_file, name):
    camera_json = plate_camera_json(name)
    scene = clean_file.scene
    camera = add_plate_camera(scene, camera_json)
    bpy.context.view_layer.update()
    rotation = np.array(camera.matrix_world)[:3, :3]
    expected = panorama.camera_rotation(camera_json["heading_deg"], camera_json["pitch_deg"])
    np.testing.assert_allclose(rotation, expected, atol=1e-6)
    # the horizontal field of view of the frame Blender draws
    scene.render.resolution_x, scene.render.resolution_y = 1280, 720
    corners = np.array([tuple(c) for c in camera.data.view_frame(scene=scene)])
    half_width = corners[:, 0].max() / -corners[0, 2]
    assert math.degrees(2 * math.atan(half_width)) == pytest.approx(camera_json["hfov_deg"])
    assert corners[:, 1].max() / corners[:, 0].max() == pytest.approx(720 / 1280)


def test_camera_euler_with_roll(clean_file):
    camera = add_plate_camera(
        clean_file.scene,
        {
            "sensor_fit": "HORIZONTAL",
            "hfov_deg": 60.0,
            "camera_location": [0, 0, 0],
            "camera_rotation_euler": panorama.camera_rotation_euler(-150, 10, 15),
        },
    )
    bpy.context.view_layer.update()
    np.testing.assert_allclose(
        np.array(camera.matrix_world)[:3, :3], panorama.camera_rotation(-150, 10, 15), atol=1e-6
    )


@pytest.mark.parametrize("name", NAMES)
def test_render_matches_perspective_plate(clean_file, tmp_path, name):
    camera_json = plate_camera_json(name)
    use_linear_rec709_working_space()
    scene = clean_file.scene
    add_plate_camera(scene, camera_json)
    hdri = hdri_path(camera_json["hdri"])
    set_hdri_world(scene, hdri)
    rendered = render_linear(scene, tmp_path / f"{name}.exr")
    assert rendered.shape == (HEIGHT, WIDTH, 3)

    expected = panorama.perspective_plate(
        panorama.load_equirect(hdri),
        WIDTH,
        HEIGHT,
        camera_json["hfov_deg"],
        camera_json["heading_deg"],
        camera_json["pitch_deg"],
        camera_json["roll_deg"],
        supersample=6,
    )
    error = relative_error(rendered, expected)
    assert error < TOLERANCE
    # the comparison can tell: a mirrored plate is far off
    assert relative_error(rendered, expected[:, ::-1]) > 5 * TOLERANCE

    # and the committed full-size plate, averaged down 8 x 8, is the same picture
    committed = oiio.ImageBuf(str(PLATES / f"{name}.exr")).get_pixels(oiio.FLOAT)[:, :, :3]
    committed = committed.reshape(HEIGHT, SCALE, WIDTH, SCALE, 3).mean(axis=(1, 3))
    assert relative_error(rendered, committed) < TOLERANCE
