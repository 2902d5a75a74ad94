"""Live update (operators/live.py): the depsgraph handler notes which reflective objects changed,
the timer rebuilds their maps small while they move and full size once they rest, unrelated
edits do nothing, and the handler goes away on unregister and when another file loads.

The bpy module runs no timers, so the tests call the timer (`live.tick`) and its work
(`live.flush`) directly, as the benchmark does; `view_layer.update()` calls the handler as
Blender's own update after an edit does.
"""

import bpy
import numpy as np
import pytest
from shots import add_camera, addon_part, ramp_plate


def make_shot(resolution="512"):
    """A camera looking along +Y at a ball, a 96 x 64 plate (left half red, right half blue),
    the ball's map generated; returns (scene, ball, map image)."""
    scene = bpy.context.scene
    add_camera(scene, distance=8.0, size=(96, 64))
    plate = ramp_plate(96, 64)
    scene.virtual_reflections.plate_image = plate
    scene.virtual_reflections.resolution = resolution
    scene.virtual_reflections.method = "PAPER"  # its maps depend on the bounds: moves show
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=16, ring_count=8)
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.materials.append(bpy.data.materials.new("Paint"))
    generate = addon_part("operators.generate")
    report = generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball])
    assert report.done == ["Ball"], report.warnings
    bpy.context.view_layer.update()
    return scene, ball, bpy.data.images["VR Map Ball"]


def pixels(image):
    buf = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(buf)
    return buf


@pytest.fixture
def live(addon):
    module = addon_part("operators.live")
    yield module
    module.disable()


@pytest.fixture
def shot(live):
    scene, ball, image = make_shot()
    scene.virtual_reflections.live_update = True
    assert live.installed()
    return scene, ball, image


def test_toggle_installs_and_removes_the_handler(live):
    scene = bpy.context.scene
    assert not live.installed()
    scene.virtual_reflections.live_update = True
    assert live.installed()
    scene.virtual_reflections.live_update = False
    assert not live.installed()


def test_moved_object_gets_a_small_map_then_the_full_one(live, shot):
    scene, ball, image = shot
    maps = addon_part("operators.scene.maps")
    before, version = pixels(image), maps.version(image)
    ball.location.x += 0.6
    bpy.context.view_layer.update()  # Blender calls the handler here
    assert live.pending() == {"Ball"}
    assert bpy.app.timers.is_registered(live.tick)

    report = live.flush(scene, full=False)
    assert report.done == ["VR Map Ball"] and not live.pending()
    assert tuple(image.size) == (live.MOVING_WIDTH, live.MOVING_WIDTH // 2)  # while moving
    assert maps.version(image) > version and live.resting() == {"VR Map Ball"}
    assert tuple(ball.virtual_reflections.bounds)[0] > 0

    report = live.flush(scene, full=True)  # what the timer does once the object rests
    assert report.done == ["VR Map Ball"] and not live.resting()
    assert tuple(image.size) == (512, 256)
    after = pixels(image)
    assert after.shape == before.shape and np.abs(after - before).max() > 0.05


def test_the_timer_coalesces_and_finishes_at_rest(live, shot):
    scene, ball, image = shot
    for _ in range(5):  # a drag: many updates before the timer runs
        ball.location.z += 0.1
        bpy.context.view_layer.update()
    assert live.pending() == {"Ball"}
    live._state.last_pass = 0.0
    assert live.tick() == live.REST  # one preview pass for the five updates
    assert not live.pending() and live.resting() == {"VR Map Ball"}
    assert 0 < live.tick() <= live.REST  # not rested yet: come back later
    live._state.last_change -= live.REST
    assert live.tick() is None  # rested: the full map, then nothing left to do
    assert tuple(image.size) == (512, 256) and not live.resting()


def test_unchanged_bounds_rebuild_nothing(live, shot):
    scene, ball, image = shot
    ball.location.x += 0.4
    bpy.context.view_layer.update()
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    version = addon_part("operators.scene.maps").version(image)
    ball.location.x += 1e-5  # far below a plate pixel
    bpy.context.view_layer.update()
    assert live.pending() == {"Ball"}  # the handler only looks at what changed, cheaply
    assert live.flush(scene, full=False).done == []  # the rounded bounds are the same
    assert addon_part("operators.scene.maps").version(image) == version


def test_unrelated_edits_do_nothing(live, shot):
    scene, ball, image = shot
    bpy.ops.mesh.primitive_cube_add(location=(3, 0, 0))
    other = bpy.context.active_object  # no reflection
    bpy.context.view_layer.update()
    live.flush(scene)
    version = addon_part("operators.scene.maps").version(image)
    other.location.x += 1.0
    other.rotation_euler.z += 0.5
    bpy.context.view_layer.update()
    other.select_set(False)
    bpy.context.view_layer.update()
    assert live.pending() == set()
    assert live.flush(scene, full=True).done == []
    assert addon_part("operators.scene.maps").version(image) == version


def test_mesh_edits_and_camera_moves_are_followed(live, shot):
    scene, ball, image = shot
    for v in ball.data.vertices:
        v.co.x *= 1.6
    ball.data.update()
    bpy.context.view_layer.update()
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    scene.camera.location.x += 0.5
    bpy.context.view_layer.update()
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]


def test_world_mode_follows_the_union(live):
    scene, ball, image = make_shot()
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(2.0, 0, 0))
    other = bpy.context.active_object
    scene.virtual_reflections.combine = "WORLD"
    addon_part("operators.generate").generate(
        bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [ball, other]
    )
    scene.virtual_reflections.live_update = True
    other.location.z += 1.0
    bpy.context.view_layer.update()
    assert live.flush(scene, full=True).done == ["VR World Map"]


def test_waits_while_a_render_runs(live, shot, monkeypatch):
    scene, ball, image = shot
    ball.location.x += 0.5
    bpy.context.view_layer.update()
    monkeypatch.setattr(live, "render_running", lambda: True)
    live._state.last_pass = 0.0
    assert live.tick() == 0.5 and live.pending() == {"Ball"}  # kept for after the render
    monkeypatch.setattr(live, "render_running", lambda: False)
    assert live.tick() == live.REST and not live.pending()


def test_removed_on_unregister(addon, live, shot):
    scene, ball, image = shot
    ball.location.x += 0.5
    bpy.context.view_layer.update()
    assert bpy.app.timers.is_registered(live.tick)
    addon.unregister()
    try:
        assert not live.installed() and not bpy.app.timers.is_registered(live.tick)
        assert live.pending() == set()
    finally:
        addon.register()  # the fixture unregisters


def test_removed_when_another_file_loads_and_back_with_a_live_file(live, shot, tmp_path):
    path = str(tmp_path / "live.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert not live.installed() and live.pending() == set()
    bpy.ops.wm.open_mainfile(filepath=path)  # its scene has live update on
    assert live.installed()
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert not live.installed()


def test_off_does_nothing(live):
    scene, ball, image = make_shot()
    live.enable()  # handler in, but the scene's toggle is off
    ball.location.x += 0.5
    bpy.context.view_layer.update()
    assert live.pending() == set()


def test_settings_that_shape_the_map_are_followed(live, shot):
    scene, ball, image = shot
    scene.virtual_reflections.strength = 0.5  # shading only: no new map
    assert live.pending() == set()
    scene.virtual_reflections.enlarge = 12.0  # the segmentation changes
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    scene.virtual_reflections.resolution = "1024"
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    assert tuple(image.size) == (1024, 512)
    # The artist's own sky (Surroundings Custom): dragging its Sky Brightness rebuilds
    scene.virtual_reflections.surroundings = "CUSTOM"
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    scene.virtual_reflections.sky_brightness = 3.0
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
    scene.virtual_reflections.contact_shadow = 0.5  # the ground the objects darken
    assert live.pending() == {"Ball"}
    live.flush(scene, full=True)  # (the material reads the ground: perhaps the same map)
    assert live.pending() == set()
    scene.virtual_reflections.sky_texture = 0.5  # the unseen sky takes the plate's texture
    assert live.pending() == {"Ball"}
    assert live.flush(scene, full=True).done == ["VR Map Ball"]
