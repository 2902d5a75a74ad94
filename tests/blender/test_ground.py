"""Camera View + Ground: a mirror object on the ground reflects the ground where the photo
shows it (parallax), in Blender's frames, with the ground found as the artist would expect.

The plate is made analytically for the Blender camera: every pixel's ray meets the ground
Z = 0 (world), coloured red where world X > 0 and blue where X < 0 (behind the sphere, in
front of it, left and right), or is sky (green). A sphere of radius 0.5 stands on the ground
5 m in front of the camera. A direction from the sphere's centre toward a ground point must
read that point's colour in the map.
"""

import math

import bpy
import numpy as np
import pytest
from shots import addon_part, ground_plate

W, H = 160, 90
RED, BLUE, SKY = (0.9, 0.05, 0.05), (0.05, 0.05, 0.9), (0.1, 0.8, 0.1)


def make_shot(method="GROUND", ground_object=False, red=lambda x, y: x > 0, combine="WORLD"):
    """The shot; ``combine`` WORLD by default: the map seen from the object's centre holds the
    ground (in the Replace, Modulate and Mix looks the material reads it per shading point:
    tests/blender/test_ground_nodes.py)."""
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -5.0, 1.6)
    cam.rotation_euler = (math.radians(90 - 10), 0.0, 0.0)  # looks along +Y, 10 deg down
    cam.data.lens = 24.0  # 74 x 46 degrees: the ground 1 m in front of the ball is in view
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 0.0, 0.5))
    ball = bpy.context.active_object
    ball.name = "Ball"
    if ground_object:
        bpy.ops.mesh.primitive_plane_add(size=40.0, location=(0.0, 0.0, -0.3))
        bpy.context.active_object.name = "Floor"
    settings = scene.virtual_reflections
    settings.method = method
    settings.combine = combine
    settings.resolution = "512"
    settings.plate_image = ground_plate(
        scene,
        -0.3 if ground_object else 0.0,
        lambda x, y: np.where(red(x, y)[..., None], RED, BLUE),
        SKY,
    )
    return scene, ball


def map_colour(image, direction):
    """The map's colour along a camera-frame direction (docs/conventions.md, lat-long)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    w, h = image.size
    lon, lat = math.atan2(d[0], d[2]), math.asin(d[1])
    col = int((-lon / (2 * math.pi) + 0.5) * w) % w
    row = min(max(int((-lat / math.pi + 0.5) * h), 0), h - 1)
    pixels = addon_part("operators.scene.images").read_pixels(image)
    return pixels[row, col, :3]


def toward(scene, ball, world_point):
    """The camera-frame direction from the ball's centre toward a world point."""
    bounds = addon_part("operators.scene.bounds")
    projection = bounds.camera_projection(scene)
    a = np.array(bounds.to_engine_frame(projection, point=world_point))
    b = np.array(bounds.to_engine_frame(projection, point=tuple(ball.location)))
    return a - b


def generate(scene, ball):
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"], report.warnings
    return addon_part("operators.node_trees.shading").map_of(ball)


POINTS = [((1.2, 1.5, 0.0), RED), ((-1.2, 1.5, 0.0), BLUE), ((1.0, -1.0, 0.0), RED),
          ((-1.0, -1.0, 0.0), BLUE)]  # fmt: skip


@pytest.mark.parametrize("point, colour", POINTS)
def test_the_ground_is_read_where_the_photo_shows_it(addon, point, colour):
    """Behind the ball and between it and the camera (which the distant model cannot place),
    left and right, all in the camera's view: the map shows the ground point's colour."""
    scene, ball = make_shot()
    image = generate(scene, ball)
    got = map_colour(image, toward(scene, ball, point))
    np.testing.assert_allclose(got, colour, atol=0.08)


def test_the_distant_camera_view_cannot_place_the_ground_in_front(addon):
    """The same direction under the distant Camera View: not the ground point's colour (the
    direction back toward the camera is unseen: a fill), so the test above can fail."""
    scene, ball = make_shot(method="CAMERA")
    image = generate(scene, ball)
    got = map_colour(image, toward(scene, ball, (1.0, -1.0, 0.0)))
    assert np.abs(got - np.array(RED)).max() > 0.2


def test_the_sky_stays_the_sky(addon):
    scene, ball = make_shot()
    image = generate(scene, ball)
    got = map_colour(image, toward(scene, ball, (0.0, 40.0, 3.0)))  # up and ahead
    np.testing.assert_allclose(got, SKY, atol=0.1)


@pytest.mark.parametrize("floor", ["chosen", "found", "hidden"])
def test_the_floor_under_a_floating_object_sets_the_plane(addon, floor):
    """The ball floats 0.3 above the Floor (ground red nearer the camera than Y = -0.8). With
    the Floor chosen, or found under the ball (a flat mesh, no shadow catcher:
    `floor.floor_under`), the ground is read at the Floor's height: the ray toward
    (0.1, -1, -0.3) meets it at Y = -1 (red). With the Floor hidden, the ball's lowest point
    (Z = 0) is taken for the ground, and the same ray meets that at Y = -0.625, which shows
    blue. Both darkened by the ball's contact shadow, the share of the sky a sphere of the
    ball's radius hides there."""
    scene, ball = make_shot(ground_object=True, red=lambda x, y: y < -0.8)
    if floor == "chosen":
        scene.virtual_reflections.ground_object = bpy.data.objects["Floor"]
    elif floor == "hidden":
        bpy.data.objects["Floor"].hide_set(True)
    image = generate(scene, ball)
    got = map_colour(image, toward(scene, ball, (0.1, -1.0, -0.3)))
    seen = floor != "hidden"
    np.testing.assert_allclose(got, np.multiply(RED if seen else BLUE, sky_left(seen)), atol=0.1)


def test_the_floor_under_is_the_highest_mesh_below_the_objects_when_flat(addon):
    """`floor.floor_under` over a ball whose lowest point is Z = 0.5: of a ground plane
    (Z = 0), a slab under it (Z = 0.2), a plane beside it (not under), a wall (on edge, beside)
    and a plane through the ball (above its lowest point), the slab is the floor; hidden, the
    ground plane. A column under the ball, up to its lowest point, is what it stands on (not
    flat): None, and the ball's lowest point is the ground, as with no floor at all. The
    panel's line (`ground_source`) names the floor."""
    floor = addon_part("operators.scene.floor")
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 0.0, 1.0))
    ball = bpy.context.active_object

    def plane(name, size, location, rotation=(0.0, 0.0, 0.0)):
        bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
        bpy.context.active_object.name = name
        return bpy.context.active_object

    ground = plane("Ground", 40.0, (0.0, 0.0, 0.0))
    slab = plane("Slab", 3.0, (0.0, 0.0, 0.2))
    plane("Beside", 1.0, (3.0, 0.0, 0.4))
    plane("Wall", 4.0, (0.0, 0.5, 2.0), rotation=(math.radians(90), 0.0, 0.0))
    plane("Through", 4.0, (0.0, 0.0, 0.7))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert floor.floor_under(scene, depsgraph, [ball]) == slab
    assert floor.ground_height(scene, depsgraph, [ball]) == pytest.approx(0.2)
    assert "'Slab', the floor under" in floor.ground_source(scene, depsgraph, [ball])
    slab.hide_set(True)
    assert floor.floor_under(scene, depsgraph, [ball]) == ground
    bpy.ops.mesh.primitive_cylinder_add(radius=0.1, depth=0.5, location=(0.0, 0.0, 0.25))
    column = bpy.context.active_object
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert floor.floor_under(scene, depsgraph, [ball]) is None
    assert floor.ground_height(scene, depsgraph, [ball]) == pytest.approx(0.5)
    column.hide_set(True)
    ground.hide_set(True)
    assert floor.floor_under(scene, depsgraph, [ball]) is None
    assert floor.ground_height(scene, depsgraph, [ball]) == pytest.approx(0.5)
    assert "lowest point" in floor.ground_source(scene, depsgraph, [ball])


def sky_left(chosen):
    """The contact shadow of the ball (radius 0.5, centre Z 0.5) on the ground point the ray
    toward (0.1, -1, -0.3) meets: 1 - (r / t)^2 cos (the form factor of a sphere)."""
    centre = np.array((0.0, 0.0, 0.5))
    d = np.array((0.1, -1.0, -0.3)) - centre
    floor = -0.3 if chosen else 0.0
    point = centre + d * (floor - centre[2]) / d[2]
    t = np.linalg.norm(point - centre)
    return 1.0 - (0.5 / t) ** 2 * (centre[2] - floor) / t


def test_live_update_and_every_frame_follow_the_ground(addon):
    """The ball moves sideways: Live Update's moving pass and full pass, and Update Every
    Frame, rebuild its map with the ground seen from the new place (the ground behind it
    turns from red/blue split to all red once it stands at X = +1.5)."""
    scene, ball = make_shot()
    image = generate(scene, ball)
    live, sequence = addon_part("operators.live"), addon_part("operators.sequence")
    behind = (0.0, 1.5, 0.0)  # the ground point behind the ball's first place
    assert map_colour(image, toward(scene, ball, behind))[2] > 0.3  # on the red/blue border
    try:
        scene.virtual_reflections.live_update = True
        ball.location.x = 1.5
        bpy.context.view_layer.update()
        live.queue(scene, {ball.name})
        assert live.flush(scene, full=False).done == [image.name]
        assert live.flush(scene, full=True).done == [image.name]
    finally:
        scene.virtual_reflections.live_update = False
        live.disable()
    got = map_colour(image, toward(scene, ball, (1.5, 1.5, 0.0)))
    np.testing.assert_allclose(got, RED, atol=0.1)
    ball.location.x = -1.5
    bpy.context.view_layer.update()
    update = sequence.update(scene, bpy.context.evaluated_depsgraph_get(), filters={})
    assert update.maps == [image.name], update.warnings
    got = map_colour(image, toward(scene, ball, (-1.5, 1.5, 0.0)))
    np.testing.assert_allclose(got, BLUE, atol=0.1)


def test_the_map_changes_smoothly_with_motion(addon):
    """The ball walks toward the camera in equal steps, so the ground in front of it leaves
    the plate's bottom edge: the map changes every step, and no step changes it twice as much
    as its neighbours do (a pop: the ground switched on or off at some pose, a seam jumping;
    checked: the test fails when the ground is dropped for part of the walk)."""
    scene, ball = make_shot(red=lambda x, y: np.sin(2.0 * x) + np.cos(1.5 * y) > 0)
    changes, previous = [], None
    for y in np.linspace(3.0, -1.5, 19):
        ball.location.y = y
        bpy.context.view_layer.update()
        image = generate(scene, ball)
        pixels = addon_part("operators.scene.images").read_pixels(image)[..., :3].copy()
        if previous is not None:
            changes.append(float(np.abs(pixels - previous).mean()))
        previous = pixels
    changes = np.array(changes)
    assert changes.min() > 0  # it moves every step ...
    neighbours = 0.5 * (changes[:-2] + changes[2:])
    assert (changes[1:-1] < 2.0 * neighbours).all(), changes  # ... and no step jumps


def test_a_ground_above_the_camera_falls_back_to_camera_view(addon):
    """The ball on a column whose top is above the camera: its lowest point is no ground the
    plate could show, so the map is Camera View's."""
    scene, ball = make_shot()
    ball.location.z = 2.5  # lowest point 2.0 m, the camera at 1.6 m
    bpy.context.view_layer.update()
    ground = addon_part("operators.scene.images").read_pixels(generate(scene, ball)).copy()
    scene.virtual_reflections.method = "CAMERA"
    camera = addon_part("operators.scene.images").read_pixels(generate(scene, ball))
    np.testing.assert_array_equal(ground, camera)
