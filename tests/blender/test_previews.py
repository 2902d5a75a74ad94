"""What the artist sees and picks: previews of the segmentation and the map (operators/
previews.py), the presets (ui/presets.py), Auto resolution and the fit warnings (generate.py),
and the preferences with their fallback when the add-on is loaded the test way
(preferences.py)."""

import bpy
import numpy as np
import pytest
from shots import PACKAGE, add_camera, addon_part, ramp_plate


def make_shot(resolution="256", radius=1.0, location=(0.0, 0.0, 0.0), generate=True):
    """A camera looking along +Y, a 96 x 64 plate (red left, blue right, a green ramp), a
    ball; with ``generate`` its map generated. Returns (scene, ball)."""
    scene = bpy.context.scene
    add_camera(scene, distance=8.0, size=(96, 64))
    plate = ramp_plate(96, 64)
    settings = scene.virtual_reflections
    settings.plate_image = plate
    settings.resolution = resolution
    settings.method = "PAPER"  # the previews draw the paper's segmentation
    bpy.ops.mesh.primitive_uv_sphere_add(
        radius=radius, segments=16, ring_count=8, location=location
    )
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.materials.append(bpy.data.materials.new("Paint"))
    if generate:
        report = addon_part("operators.generate").generate(
            bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
        )
        assert report.done == ["Ball"], report.warnings
    return scene, ball


def preview_pixels(preview):
    w, h = preview.image_size
    buf = np.empty(w * h * 4, np.float32)
    preview.image_pixels_float.foreach_get(buf)
    return buf.reshape(h, w, 4)


# --- previews -------------------------------------------------------------------------------------


def test_previews_show_the_segmentation_and_the_map(addon):
    previews = addon_part("operators.previews")
    scene, ball = make_shot()
    shown = previews.for_object(scene, ball)
    assert shown["image"] == bpy.data.images["VR Map Ball"]
    assert tuple(shown["map"].image_size) == (256, 128)
    assert tuple(shown["overlay"].image_size) == (96, 64)  # the plate is smaller than 256
    overlay, plate = preview_pixels(shown["overlay"]), scene.virtual_reflections.plate_image
    # The overlay is the plate, tinted by region and lined; the ball's region X is lighter.
    assert overlay[..., :3].std() > 0.05 and not np.allclose(overlay[..., 0], overlay[..., 2])
    assert plate is not None
    mp = preview_pixels(shown["map"])
    assert mp[..., 0].max() > 0.5 and mp[..., 2].max() > 0.5  # red and blue reach the map
    # An object without a reflection shows none.
    bpy.ops.mesh.primitive_cube_add()
    assert previews.for_object(scene, bpy.context.active_object)["map"] is None


def test_previews_follow_the_map(addon):
    previews = addon_part("operators.previews")
    live = addon_part("operators.live")
    scene, ball = make_shot(resolution="512")
    shown = previews.for_object(scene, ball)
    map_before = preview_pixels(shown["map"]).copy()
    overlay_before = preview_pixels(shown["overlay"]).copy()
    assert previews.for_object(scene, ball)["map"] is shown["map"]  # cached while unchanged

    scene.virtual_reflections.live_update = True
    try:
        ball.location.x += 1.2
        bpy.context.view_layer.update()
        live.flush(scene, full=False)  # the small map while moving updates the previews
        moving = preview_pixels(previews.for_object(scene, ball)["map"]).copy()
        assert np.abs(moving - map_before).max() > 0.05
        live.flush(scene, full=True)
        shown = previews.for_object(scene, ball)
        assert np.abs(preview_pixels(shown["overlay"]) - overlay_before).max() > 0.05
        assert np.abs(preview_pixels(shown["map"]) - map_before).max() > 0.05
    finally:
        scene.virtual_reflections.live_update = False

    # Generate (not live) also refreshes them.
    ball.location.x -= 2.4
    bpy.context.view_layer.update()
    before = preview_pixels(previews.for_object(scene, ball)["map"]).copy()
    addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    after = preview_pixels(previews.for_object(scene, ball)["map"])
    assert np.abs(after - before).max() > 0.05


def test_full_size_segmentation_image_is_ours_and_removed_with_the_maps(addon):
    previews = addon_part("operators.previews")
    scene, ball = make_shot()
    image = previews.overlay_image(scene, ball)
    assert image.name == "VR Segmentation Ball" and tuple(image.size) == (96, 64)
    assert previews.overlay_image(scene, ball) == image  # updated in place
    assert bpy.ops.vr.remove() == {"FINISHED"}
    assert "VR Segmentation Ball" not in bpy.data.images


def test_show_image_needs_blenders_window(addon):
    make_shot()
    assert not bpy.ops.vr.show_image.poll()  # the bpy module (background): greyed out


# --- presets ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("preset", "expected"),
    [
        ("CHROME", {"combine": "REPLACE", "strength": 1.0}),
        ("CAR_PAINT", {"combine": "MODULATE", "strength": 1.0}),
        ("GLOSSY", {"combine": "MIX", "strength": 1.0, "ior": 1.5}),
    ],
)
def test_presets_set_what_they_claim(addon, preset, expected):
    presets = addon_part("ui.presets")
    settings = bpy.context.scene.virtual_reflections
    settings.combine, settings.strength, settings.ior = "WORLD", 0.3, 2.5
    assert bpy.ops.vr.apply_preset(preset=preset) == {"FINISHED"}
    for key, value in expected.items():
        assert (
            getattr(settings, key) == pytest.approx(value)
            if isinstance(value, float)
            else (getattr(settings, key) == value)
        ), key
    assert presets.matches(settings, preset)
    assert [k for k in presets.PRESETS if presets.matches(settings, k)] == [preset]


def test_preset_changes_the_look_of_objects_that_reflect(addon):
    shading = addon_part("operators.node_trees.shading")
    scene, ball = make_shot()
    assert ball[shading.RECORD]["mode"] == "REPLACE"
    ball.select_set(True)
    assert bpy.ops.vr.apply_preset(preset="CAR_PAINT") == {"FINISHED"}
    assert ball[shading.RECORD]["mode"] == "MODULATE"
    assert bpy.ops.vr.apply_preset(preset="GLOSSY") == {"FINISHED"}
    assert ball[shading.RECORD]["mode"] == "MIX"


# --- Auto resolution and warnings ---------------------------------------------------------------


def test_auto_width_from_the_size_on_screen(addon):
    choices = addon_part("operators.scene.choices")
    auto_map_width = addon_part("virtual_reflections.mapsize").auto_map_width
    assert auto_map_width(10) == 256  # pi x 10 -> 32, raised to the floor
    assert auto_map_width(100) == 512  # pi x 100 = 314 -> 512
    assert auto_map_width(400) == 2048  # pi x 400 = 1257 -> 2048
    assert auto_map_width(1e5) == 4096
    assert choices.map_width("512", 700) == 512
    assert choices.map_width("AUTO") == 1024
    scene = bpy.context.scene
    scene.virtual_reflections.resolution = "AUTO"
    assert choices.map_width(scene.virtual_reflections.resolution, 200) == 1024


def test_auto_resolution_generates_a_map_sized_for_the_object(addon):
    scene, ball = make_shot(resolution="AUTO", generate=False)
    # The ball spans 14.3 degrees of the camera's 39.6: 36 % of the render's width.
    scene.render.resolution_x, scene.render.resolution_y = 192, 128  # ~69 px: pi x 69 -> 256
    report = addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"]
    assert tuple(bpy.data.images["VR Map Ball"].size) == (256, 128)
    scene.render.resolution_x, scene.render.resolution_y = 960, 640  # ~345 px: 1084 -> 2048
    addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert tuple(bpy.data.images["VR Map Ball"].size) == (2048, 1024)


def test_auto_resolution_is_for_the_full_size_render(addon):
    """A Generate during a 50 % preview sizes the map for the 100 % render that follows (the
    map stays), not for the preview: the same width as at 100 %."""
    scene, ball = make_shot(resolution="AUTO", generate=False)
    scene.render.resolution_x, scene.render.resolution_y = 960, 640  # ~345 px: 2048
    generate = addon_part("operators.generate").generate
    for percent in (50, 25, 100):
        scene.render.resolution_percentage = percent
        generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball])
        assert tuple(bpy.data.images["VR Map Ball"].size) == (2048, 1024), percent


def test_warnings_near_the_border_and_for_a_huge_object(addon):
    generate = addon_part("operators.generate")
    scene, ball = make_shot(location=(3.2, 0.0, 0.0), generate=False)  # at the right edge
    report = generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert report.done == ["Ball"]  # a warning, not an error
    assert any("Ball is so close to the plate's border" in w for w in report.warnings)
    ball.location = (0.0, 0.0, 0.0)
    ball.scale = (3.5, 3.5, 3.5)
    bpy.context.view_layer.update()
    report = generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert report.done == ["Ball"]
    assert any("covers" in w and "little is left" in w for w in report.warnings)
    advice = addon_part("operators.previews").for_object(scene, ball)["advice"]
    assert any("covers" in w for w in advice)
    assert bpy.ops.vr.generate() == {"FINISHED"}  # the operator reports them as warnings


# --- preferences -----------------------------------------------------------------------------


def test_preferences_fall_back_to_defaults_when_not_an_enabled_addon(addon):
    preferences = addon_part("preferences")
    assert bpy.context.preferences.addons.get(PACKAGE) is None
    assert preferences.get() is preferences.DEFAULTS
    assert preferences.VR_AddonPreferences.bl_idname == PACKAGE
    assert preferences.DEFAULTS.resolution == "AUTO" and preferences.DEFAULTS.map_storage == "PACK"


def test_new_files_take_the_preferred_defaults(addon, monkeypatch):
    preferences = addon_part("preferences")
    monkeypatch.setattr(preferences.DEFAULTS, "combine", "MIX")
    monkeypatch.setattr(preferences.DEFAULTS, "map_storage", "FILES")
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)  # File > New
    settings = bpy.context.scene.virtual_reflections
    assert settings.combine == "MIX" and settings.resolution == "AUTO"
    assert settings.map_storage == "FILES" and settings.defaults_applied


def test_a_scene_with_reflections_keeps_its_settings_on_load(addon, tmp_path, monkeypatch):
    preferences = addon_part("preferences")
    scene, ball = make_shot(resolution="512")
    path = str(tmp_path / "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    monkeypatch.setattr(preferences.DEFAULTS, "resolution", "2048")
    bpy.ops.wm.open_mainfile(filepath=path)
    assert bpy.context.scene.virtual_reflections.resolution == "512"


def test_saved_maps_folder(addon, tmp_path, monkeypatch):
    preferences = addon_part("preferences")
    maps = addon_part("operators.scene.maps")
    with pytest.raises(ValueError, match="save the .blend first"):
        maps.maps_folder()
    # The user folder needs an installed extension; loaded the test way it falls back.
    monkeypatch.setattr(preferences.DEFAULTS, "map_folder", "USER")
    with pytest.raises(ValueError, match="save the .blend first"):
        maps.maps_folder()
    make_shot(generate=False)
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    assert maps.maps_folder() == str(tmp_path / "vr_maps")
    scene = bpy.context.scene
    scene.virtual_reflections.map_storage = "FILES"
    ball = bpy.data.objects["Ball"]
    report = addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"]
    assert [p.name for p in (tmp_path / "vr_maps").iterdir()] == ["VR_Map_Ball.exr"]


def test_the_table_cache_follows_the_preference(addon, monkeypatch):
    """Registering applies the preferred table-cache budget to the engine (MB)."""
    preferences = addon_part("preferences")
    cache = addon_part("virtual_reflections.cache")
    monkeypatch.setattr(preferences.DEFAULTS, "table_cache_mb", 7)
    preferences._apply_cache_limit()
    try:
        assert cache.limit() == 7 * 2**20
    finally:
        monkeypatch.setattr(preferences.DEFAULTS, "table_cache_mb", 512)
        preferences._apply_cache_limit()
    assert cache.limit() == 512 * 2**20
