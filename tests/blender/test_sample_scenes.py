"""sample_scenes/: the paper's example scenes over the sample plates, and the sample render.

Scenes are built tiny (64 x 36, the plate at 5 %); one Cycles render of the chrome sphere
without and with reflections (4 samples, no denoising) checks that the sphere changes and
the background is the plate's own pixels.
"""

import importlib
import importlib.util
import json
import math
import pathlib

import numpy as np
import pytest
from shots import project_points  # noqa: E402

from study import panorama

bpy = pytest.importorskip("bpy", reason="the bpy module is not installed in this environment")

ROOT = pathlib.Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_scenes"
TINY = (64, 36)  # the 1280 x 720 plates at 5 %


def _load(name, filename):
    spec = importlib.util.spec_from_file_location(name, SAMPLES / filename)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def render_sample():
    return _load("vr_test_render_sample", "render_sample.py")


@pytest.fixture(scope="module")
def scenes(render_sample):
    return render_sample.load_build_scenes()


def submodule(addon, name):
    return importlib.import_module(f"{addon.__name__}.{name}")


# --- building ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "plate"), [("spheres", "courtyard"), ("fig10", "city"), ("car", "sunset")]
)
def test_scene_is_built_over_the_plate(addon, scenes, kind, plate):
    built = scenes.build(kind, plate, size=TINY, scale=100, samples=4, denoise=False)
    scene = built.scene
    camera_json = json.loads((SAMPLES / "plates" / f"{plate}.json").read_text())

    # the plate's camera, exactly (tests/blender/test_plate_camera.py checks it renders the plate)
    camera = scene.camera
    assert camera is built.camera and camera.type == "CAMERA"
    assert camera.data.lens == pytest.approx(camera_json["lens_mm"])
    assert camera.data.sensor_width == pytest.approx(camera_json["sensor_width_mm"])
    assert camera.data.sensor_fit == camera_json["sensor_fit"]
    assert tuple(camera.location) == pytest.approx(camera_json["camera_location"])
    bpy.context.view_layer.update()
    expected = panorama.camera_rotation(camera_json["heading_deg"], camera_json["pitch_deg"])
    np.testing.assert_allclose(np.array(camera.matrix_world)[:3, :3], expected, atol=1e-6)

    # quick render settings
    render = scene.render
    assert (render.resolution_x, render.resolution_y, render.resolution_percentage) == (*TINY, 100)
    assert render.engine == "CYCLES" and scene.cycles.samples == 4 and render.film_transparent
    assert scene.view_settings.view_transform == "Standard"

    # the objects: where the layout says, standing on the ground, marked, with materials
    layout = scenes.LAYOUT_OVERRIDES.get((kind, plate), scenes.LAYOUTS[kind])
    assert [o.name for o in built.objects] == [name for name, *_ in layout]
    bounds = submodule(addon, "operators.scene.bounds")
    height = scenes.CAMERA_HEIGHT[plate]
    for obj, (_, fx, fy, _) in zip(built.objects, layout):
        assert obj.type == "MESH" and len(obj.data.polygons) >= 26
        assert obj.virtual_reflections.enabled
        assert obj.material_slots and all(slot.material for slot in obj.material_slots)
        corners = np.array([obj.matrix_world @ v.co for v in obj.data.vertices])
        assert corners[:, 2].min() == pytest.approx(-height, abs=1e-4)
        pixel, in_front = project_points(bounds, np.array(obj.location), scene)
        assert in_front[0]
        np.testing.assert_allclose(pixel[0], (fx * TINY[0], fy * TINY[1]), atol=1e-3)
        box = bounds.object_bounds(obj, bpy.context.evaluated_depsgraph_get(), scene)
        assert box.visible and box.x0 >= 0 and box.x1 <= TINY[0] and box.y1 <= TINY[1]
    assert built.ground is not None and built.ground.is_shadow_catcher
    assert built.ground.location.z == 0
    assert built.ground.data.vertices[0].co.z == pytest.approx(-height)

    settings = scene.virtual_reflections
    assert settings.plate_image == built.plate_image
    assert settings.combine == built.combine == ("MODULATE" if kind == "car" else "REPLACE")
    assert built.plate_image.size[:] == (1280, 720)


def test_car_materials(addon, scenes):
    built = scenes.build("car", "sunset", size=TINY, scale=100, samples=4, denoise=False)
    (car,) = built.objects
    names = [slot.material.name for slot in car.material_slots]
    assert names == ["Car Paint", "Car Glass", "Car Tyre", "Car Chrome"]
    used = {p.material_index for p in car.data.polygons}
    assert used == {0, 1, 2, 3}
    paint = car.material_slots[0].material.node_tree.nodes["Principled BSDF"]
    r, g, b, _ = paint.inputs["Base Color"].default_value
    assert r > 5 * max(g, b)  # a red paint for MODULATE to tint the map with


@pytest.mark.parametrize("kind", ["spheres", "fig10", "car"])
def test_generate_makes_a_map_per_object(addon, scenes, kind):
    built = scenes.build(kind, "courtyard", size=TINY, scale=100, samples=4, denoise=False)
    built.scene.virtual_reflections.resolution = "256"
    generate = submodule(addon, "operators.generate")
    maps = submodule(addon, "operators.scene.maps")
    shading = submodule(addon, "operators.node_trees.shading")
    report = generate.generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), built.objects
    )
    assert sorted(report.done) == sorted(o.name for o in built.objects), report.warnings
    for obj in built.objects:
        image = bpy.data.images.get(maps.map_name(obj.name))
        assert image is not None and image.get("vr_created") == maps.KIND
        assert image.size[:] == (256, 128)
        assert shading.is_attached(obj)
        assert all(slot.link == "OBJECT" for slot in obj.material_slots)
    assert not shading.is_attached(built.ground)


def test_bad_names(addon, scenes, render_sample, capsys):
    with pytest.raises(ValueError, match="unknown scene"):
        scenes.build("teapot", "courtyard")
    with pytest.raises(ValueError, match="plate image not found"):
        scenes.plate_files("/nowhere/plate.exr")
    assert render_sample.main(["--scene", "nope"]) == render_sample.EXIT_BAD_INPUT
    assert render_sample.main(["--plate", "/nowhere/plate.exr"]) == render_sample.EXIT_BAD_INPUT
    assert "plate image not found" in capsys.readouterr().err


def test_ground_point_sees_the_pixel(scenes):
    camera_json = json.loads((SAMPLES / "plates" / "courtyard.json").read_text())
    for fx, fy in ((0.5, 0.8), (0.1, 0.95), (0.9, 0.6)):
        point = scenes.ground_point(camera_json, fx, fy, 1.5)
        assert point.z == pytest.approx(-1.5)
        origin, direction = scenes.pixel_ray(camera_json, fx, fy)
        assert (point - origin).normalized().dot(direction) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="not on the ground"):
        scenes.ground_point(camera_json, 0.5, 0.1, 1.5)  # above the horizon
    # the centre of the frame looks along the camera's heading, pitched down
    _, centre = scenes.pixel_ray(camera_json, 0.5, 0.5)
    assert math.degrees(math.asin(centre.z)) == pytest.approx(camera_json["pitch_deg"])
    # so the horizon crosses the centre column f tan(8°) above the middle (f = 640 / tan 30°)
    row = 360 - 640 / math.tan(math.radians(30)) * math.tan(math.radians(8))
    assert scenes.horizon_row(camera_json) * 720 == pytest.approx(row)
    _, level = scenes.pixel_ray(camera_json, 0.5, scenes.horizon_row(camera_json))
    assert level.z == pytest.approx(0.0, abs=1e-6)


# --- rendering -----------------------------------------------------------------------------------


def test_sphere_render_without_and_with(addon, render_sample, tmp_path):
    without, with_, built = render_sample.render_pair(
        addon, "spheres", "courtyard", tmp_path, scale=5, samples=4, ground=False, denoise=False
    )
    assert without.shape == with_.shape == (TINY[1], TINY[0], 3)
    x0, y0, x1, y1 = (v / 20 for v in built.objects[0].virtual_reflections.bounds)  # plate px
    inside = np.zeros(without.shape[:2], bool)
    inside[math.ceil(y0) : math.floor(y1), math.ceil(x0) : math.floor(x1)] = True
    assert inside.sum() > 10
    difference = np.abs(with_ - without).mean(axis=2)
    assert difference[inside].mean() > 0.02  # the sphere shows the plate now

    # the background is the plate's own pixels (sampled as the batch entry scales it)
    imagefiles = submodule(addon, "virtual_reflections.imagefiles")
    plate = imagefiles.read_plate(built.plate_path).pixels
    ys = ((np.arange(TINY[1]) + 0.5) * 720 / TINY[1]).astype(int)
    xs = ((np.arange(TINY[0]) + 0.5) * 1280 / TINY[0]).astype(int)
    plate = plate[ys][:, xs]
    outside = np.ones_like(inside)
    outside[max(0, int(y0) - 2) : int(y1) + 3, max(0, int(x0) - 2) : int(x1) + 3] = False
    for composite in (without, with_):
        np.testing.assert_allclose(composite[outside], plate[outside], rtol=2e-3, atol=2e-3)

    paths = render_sample.write_outputs(addon, "spheres", without, with_, tmp_path, built.combine)
    for path in paths:
        assert pathlib.Path(path).stat().st_size > 0
    picture = imagefiles.read_plate(paths[2]).pixels
    assert picture.shape == (TINY[1], 2 * TINY[0] + render_sample.GAP, 3)


def test_sphere_shows_the_plates_left_on_its_left(addon, render_sample, tmp_path):
    """A plate red on its left half and blue on its right (with the courtyard camera): the
    chrome sphere in the middle is red on its left, blue on its right (docs/conventions.md)."""
    oiio = pytest.importorskip("OpenImageIO")
    plate = np.zeros((720, 1280, 3), np.float32)
    plate[:, :640, 0] = plate[:, 640:, 2] = 0.5
    path = tmp_path / "red_blue.exr"
    assert oiio.ImageBuf(plate).write(str(path)), oiio.geterror()
    (tmp_path / "red_blue.json").write_text((SAMPLES / "plates" / "courtyard.json").read_text())

    _, with_, built = render_sample.render_pair(
        addon, "spheres", path, tmp_path, scale=10, samples=4, ground=False, denoise=False
    )
    x0, y0, x1, y1 = (v / 10 for v in built.objects[0].virtual_reflections.bounds)
    middle = (x0 + x1) / 2
    rows = slice(math.ceil(y0) + 1, math.floor(y1) - 1)
    left = with_[rows, math.ceil(x0) + 1 : math.floor(middle) - 1]
    right = with_[rows, math.ceil(middle) + 1 : math.floor(x1) - 1]
    assert left.size and right.size
    redness = lambda part: float((part[..., 0] - part[..., 2]).mean())  # noqa: E731
    assert redness(left) > 0.1 and redness(right) < -0.1
