"""Saved and packed maps are pipeline files: the engine's scene-linear half-float EXR, ZIP
compressed, tagged scene-linear Rec.709, with the standard envmap attribute (issue 12)."""

import bpy
import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest
from shots import add_camera, addon_part, ramp_plate

maps = addon_part("operators.scene.maps")
images = addon_part("operators.scene.images")


def smooth_map(width=256):
    """A lat-long map with values above 1 (an HDR sky) and a gradient: (H, W, 3) float32."""
    h = width // 2
    y, x = np.mgrid[0:h, 0:width].astype(np.float32)
    env = np.stack([x / width * 8.0, y / h, np.full_like(x, 0.25)], axis=-1)
    return env.astype(np.float32)


def read_back(path):
    """(pixels (H, W, C) float32, the OIIO spec) of an image file."""
    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    try:
        spec = image.spec()
        pixels = image.read_image(0, 0, 0, spec.nchannels, "float")
    finally:
        image.close()
    return np.asarray(pixels).reshape(spec.height, spec.width, -1), spec


def assert_pipeline_map(path, env):
    """``path`` holds ``env`` as a scene-linear half-float compressed lat-long EXR."""
    pixels, spec = read_back(path)
    assert pixels.shape == env.shape
    np.testing.assert_allclose(pixels, env, rtol=2e-3, atol=1e-3)  # half precision
    assert str(spec.format) == "half"
    assert spec.getattribute("compression") in ("zip", "dwaa")
    assert spec.getattribute("textureformat") == "LatLong Environment"
    assert str(spec.getattribute("oiio:ColorSpace")).startswith("lin_rec709")  # 3.0 / 3.1+ name
    header = OpenEXR.File(str(path), header_only=True).header()
    assert header["envmap"] == OpenEXR.ENVMAP_LATLONG
    np.testing.assert_allclose(header["chromaticities"][:2], (0.64, 0.33), atol=1e-6)
    # Half floats and ZIP: well under the 12 bytes a pixel of uncompressed float32 RGB.
    h, w = env.shape[:2]
    assert path.stat().st_size < w * h * 12 / 3


def test_a_saved_map_is_a_half_float_latlong_exr(addon, tmp_path):
    env = smooth_map()
    image = maps.store_map("VR Map Probe", env, str(tmp_path))
    path = tmp_path / "VR_Map_Probe.exr"
    assert_pipeline_map(path, env)
    # The image reads that file: what Blender shows is what was saved.
    assert image.source == "FILE" and bpy.path.abspath(image.filepath) == str(path)
    assert image.colorspace_settings.name in images.LINEAR_SPACES and not image.is_dirty
    pixels, _ = read_back(path)
    np.testing.assert_array_equal(images.read_pixels(image)[..., :3], pixels)
    # Stored again (a regeneration): the same file, replaced whole, the same image.
    env2 = env * 0.5
    assert maps.store_map("VR Map Probe", env2, str(tmp_path)) == image
    assert_pipeline_map(path, env2)
    np.testing.assert_allclose(images.read_pixels(image)[..., :3], env2, rtol=2e-3, atol=1e-3)


@pytest.mark.parametrize("storage", ["FILES", "PACK"])
def test_generate_keeps_pipeline_maps(addon, tmp_path, storage):
    scene = bpy.context.scene
    add_camera(scene, size=(64, 48))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    ball = bpy.context.active_object
    ball.name = "Ball"
    scene.virtual_reflections.plate_image = ramp_plate()
    scene.virtual_reflections.resolution = "256"
    scene.virtual_reflections.map_storage = storage
    blend = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))  # FILES: the maps go beside it
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}, scene.virtual_reflections.last_report
    image = bpy.data.images["VR Map Ball"]
    env = images.read_pixels(image)[..., :3].copy()
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    if storage == "FILES":
        path = tmp_path / "vr_maps" / "VR_Map_Ball.exr"
        assert image.packed_file is None
    else:
        assert image.packed_file is not None
        path = tmp_path / "packed.exr"
        path.write_bytes(image.packed_file.data)
    assert_pipeline_map(path, env)
    # The .blend opens with the same map (from the file or the packed EXR).
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    image = bpy.data.images["VR Map Ball"]
    assert image.source == "FILE" and image.is_float
    np.testing.assert_allclose(images.read_pixels(image)[..., :3], env, rtol=2e-3, atol=1e-3)


def test_packing_without_openimageio_still_keeps_the_map(addon, tmp_path, monkeypatch):
    """No OpenImageIO in this Blender: the map is packed Blender's way, never lost on save."""
    env = smooth_map(64)
    maps.store_map("VR Map Fallback", env)
    imagefiles = addon_part("virtual_reflections.imagefiles")
    image_error = addon_part("virtual_reflections.atomic_files").ImageError

    def missing():
        raise image_error("OpenImageIO is not installed (pip install OpenImageIO)")

    monkeypatch.setattr(imagefiles, "openimageio", missing)
    blend = tmp_path / "fallback.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    monkeypatch.undo()
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    image = bpy.data.images["VR Map Fallback"]
    assert image.packed_file is not None
    np.testing.assert_allclose(images.read_pixels(image)[..., :3], env, rtol=1e-3, atol=1e-3)


@pytest.fixture
def user_folder(addon, tmp_path, monkeypatch):
    """Saved maps go to the extension's user folder (here tmp_path/user: the add-on is loaded
    the test way, not installed, so Blender has no user folder for it)."""
    preferences = addon_part("preferences")
    monkeypatch.setattr(preferences.DEFAULTS, "map_folder", "USER")
    root = tmp_path / "user"

    def extension_path_user(package, path="", create=False):
        folder = root / package / path
        if create:
            folder.mkdir(parents=True, exist_ok=True)
        return str(folder)

    monkeypatch.setattr(bpy.utils, "extension_path_user", extension_path_user)
    return root


def save_a_map(value):
    """A map of one ``value`` saved where the scene saves maps; returns its file's path."""
    settings = bpy.context.scene.virtual_reflections
    settings.map_storage = "FILES"
    env = np.full((32, 64, 3), value, np.float32)
    image = maps.store_map("VR Map Ball", env, maps.save_folder(settings))
    return bpy.path.abspath(image.filepath)


def test_two_shots_of_one_name_keep_their_own_maps_in_the_user_folder(user_folder, tmp_path):
    """Two shots called lighting.blend in two folders: each its own maps (issue 40)."""
    paths = []
    for value, where in ((0.25, "sh010"), (0.75, "sh020")):
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        (tmp_path / where).mkdir()
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / where / "lighting.blend"))
        paths.append(save_a_map(value))
        assert paths[-1].startswith(str(user_folder)) and "lighting" in paths[-1]
    assert paths[0] != paths[1]
    for path, value in zip(paths, (0.25, 0.75), strict=True):
        pixels, _ = read_back(path)
        np.testing.assert_allclose(pixels, value, atol=1e-3)
    # The same shot again: the same folder (its maps are found again, not multiplied).
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "sh010" / "lighting.blend"))
    assert save_a_map(0.5) == paths[0]


def test_unsaved_files_keep_their_own_maps_in_the_user_folder(user_folder):
    """Two unsaved files: two folders, not one shared "untitled"; one file keeps its own."""
    paths = []
    for value in (0.25, 0.75):
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        paths.append(save_a_map(value))
        assert save_a_map(value) == paths[-1]  # the same file: the same folder every time
    assert paths[0] != paths[1]
    for path, value in zip(paths, (0.25, 0.75), strict=True):
        pixels, _ = read_back(path)
        np.testing.assert_allclose(pixels, value, atol=1e-3)


def files_shot(folder):
    """folder/shot.blend, its Ball's map saved beside it (folder/vr_maps/); returns the map's
    pixels (H, W, 3)."""
    scene = bpy.context.scene
    add_camera(scene, size=(64, 48))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    ball = bpy.context.active_object
    ball.name = "Ball"
    scene.virtual_reflections.plate_image = plate = ramp_plate()
    plate.pack()  # kept in the .blend: a reopened shot makes the same map
    scene.virtual_reflections.resolution = "256"
    scene.virtual_reflections.map_storage = "FILES"
    folder.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "shot.blend"))
    bpy.ops.object.select_all(action="DESELECT")
    ball.select_set(True)
    assert bpy.ops.vr.generate() == {"FINISHED"}, scene.virtual_reflections.last_report
    env = images.read_pixels(bpy.data.images["VR Map Ball"])[..., :3].copy()
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "shot.blend"))
    return env


def test_a_moved_shot_finds_its_saved_maps(addon, tmp_path):
    """The shot's folder (.blend + vr_maps/) moved elsewhere: its maps still load (issue 40)."""
    env = files_shot(tmp_path / "before")
    image = bpy.data.images["VR Map Ball"]
    assert image.filepath.startswith("//"), image.filepath
    (tmp_path / "before").rename(tmp_path / "after")
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "after" / "shot.blend"))
    image = bpy.data.images["VR Map Ball"]
    assert image.filepath.startswith("//"), image.filepath
    np.testing.assert_allclose(images.read_pixels(image)[..., :3], env, rtol=2e-3, atol=1e-3)
    assert image.has_data and maps.missing_file(image) is None


def test_a_missing_saved_map_is_said_and_made_again(addon, tmp_path, capsys):
    """A saved map's file deleted: opening says so, the panel says so, Generate makes it again
    (its warning says so too), never a magenta map."""
    env = files_shot(tmp_path)
    path = tmp_path / "vr_maps" / "VR_Map_Ball.exr"
    path.unlink()
    capsys.readouterr()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "shot.blend"))
    said = capsys.readouterr().out
    assert "VR Map Ball" in said and "missing" in said and "Generate" in said, said
    image = bpy.data.images["VR Map Ball"]
    note = maps.missing_file(image)
    assert note and "missing" in note and "VR_Map_Ball.exr" in note, note
    ball = bpy.data.objects["Ball"]
    advice = addon_part("operators.previews").for_object(bpy.context.scene, ball)["advice"]
    assert advice == [f"{note}: Generate makes it again"]  # what the object's panel says
    report = addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"]
    assert any("missing" in w and "VR Map Ball" in w for w in report.warnings), report.warnings
    assert path.exists() and maps.missing_file(image) is None
    np.testing.assert_allclose(images.read_pixels(image)[..., :3], env, rtol=2e-3, atol=1e-3)
