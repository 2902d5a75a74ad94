"""Set Up From Plate's advice on matching the camera to the photo (operators/scene/camera_match.py):
the focal length from the plate's EXIF (35 mm equivalent), recorded and undone; what it says
without metadata (fSpy's importer); a warning when the camera was framed for another aspect."""

import importlib
import math

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
oiio = pytest.importorskip("OpenImageIO")


@pytest.fixture
def comp(addon):
    return importlib.import_module(addon.__name__ + ".operators.compositor")


def photo(path, width, height, **exif):
    spec = oiio.ImageSpec(width, height, 3, "uint8")
    for name, value in exif.items():
        spec.attribute("Exif:" + name, value)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec)
    out.write_image(np.full((height, width, 3), 128, np.uint8))
    out.close()
    return bpy.data.images.load(str(path))


def scene_with_camera():
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 1920, 1080
    return scene, camera.data


def test_lens_from_the_35mm_equivalent_gives_the_photos_field_of_view(comp, tmp_path):
    scene, data = scene_with_camera()
    image = photo(tmp_path / "phone.jpg", 40, 30, FocalLength=4.2, FocalLengthIn35mmFilm=26)
    before = (data.lens, data.sensor_width, data.sensor_fit)
    record = comp.setup_from_plate(scene, image, lens=True)
    # The photo's diagonal field of view: 26 mm on the 36 x 24 mm frame (43.27 mm diagonal).
    photo_fov = 2 * math.atan(math.hypot(36, 24) / 2 / 26)
    # The camera's: the sensor width spans the plate's width, so its diagonal spans
    # 36 * hypot(W, H) / W mm.
    camera_fov = 2 * math.atan(36 * math.hypot(40, 30) / 40 / 2 / data.lens)
    assert data.sensor_fit == "HORIZONTAL" and data.sensor_width == 36
    assert camera_fov == pytest.approx(photo_fov, rel=1e-4)
    assert "26 mm (35 mm equivalent)" in record["advice"][0]
    assert any(line.startswith("Warning") and "1.778:1" in line for line in record["advice"])
    comp.undo_setup_from_plate(scene)
    assert (data.lens, data.sensor_width, data.sensor_fit) == before


def test_without_metadata_it_points_to_fspy_and_keeps_the_lens(comp, tmp_path):
    scene, data = scene_with_camera()
    image = photo(tmp_path / "plain.png", 64, 36)  # 16:9, as the camera was framed
    record = comp.setup_from_plate(scene, image, lens=True)
    assert record["lens"] is None and data.lens == 50
    assert record["advice"] == [
        "No focal length in the plate's metadata: match the camera to the photo "
        "(fSpy and its Blender importer)"
    ]


def test_metadata_is_only_advice_unless_asked(comp, tmp_path):
    scene, data = scene_with_camera()
    image = photo(tmp_path / "phone.jpg", 40, 30, FocalLengthIn35mmFilm=26)
    record = comp.setup_from_plate(scene, image)
    assert record["lens"] is None and data.lens == 50
    assert "Focal Length" in record["advice"][0] and "fSpy" in record["advice"][0]


def test_operator_reports_the_advice(addon, tmp_path):
    scene, data = scene_with_camera()
    image = photo(tmp_path / "phone.jpg", 40, 30, FocalLengthIn35mmFilm=26)
    scene.virtual_reflections.plate_image = image
    assert bpy.ops.vr.setup_plate() == {"FINISHED"}
    assert data.lens != 50 and data.sensor_fit == "HORIZONTAL"  # on by default
    assert bpy.ops.vr.undo_setup_plate() == {"FINISHED"}
    assert data.lens == 50 and data.sensor_fit == "AUTO"
