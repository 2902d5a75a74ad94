"""operators/scene/bounds.py: screen bounds in plate pixels (origin top-left, y down,
x1/y1 exclusive).

The expected values come from `reference_pixels`, pinhole/orthographic maths written out here
independently of the implementation, from Blender's frame (`Camera.view_frame`) and from Cycles.
"""

import importlib
import math

import numpy as np
import pytest
from shots import project_points  # noqa: E402

bpy = pytest.importorskip("bpy")


@pytest.fixture
def bounds(addon):
    """operators/scene/bounds.py, imported from the extension package on a fresh empty file."""
    return importlib.import_module(addon.__name__ + ".operators.scene.bounds")


# A unit cube: 8 corners, 6 quads.
CUBE_VERTS = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
CUBE_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def add_camera(scene, location=(0, 0, 0), rotation=(0, 0, 0), **settings):
    data = bpy.data.cameras.new("Camera")
    for name, value in settings.items():
        setattr(data, name, value)
    obj = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler = location, rotation
    scene.camera = obj
    return obj


def add_object(scene, data, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1)):
    obj = bpy.data.objects.new(data.name if data else "Empty", data)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    return obj


def add_mesh(scene, verts=CUBE_VERTS, faces=CUBE_FACES, **placement):
    mesh = bpy.data.meshes.new("Mesh")
    mesh.from_pydata(verts, [], faces)
    return add_object(scene, mesh, **placement)


def world_points(obj, local):
    """(N, 3) local points -> (N, 3) world points through obj.matrix_world."""
    matrix = np.array(obj.matrix_world)
    return np.asarray(local, dtype=float) @ matrix[:3, :3].T + matrix[:3, 3]


def reference_pixels(points_world, scene):
    """(N, 3) world points in front of the camera -> (N, 2) plate pixels, y down.

    Written from the manual's description: the sensor (or ortho_scale) spans the fitted side of
    the frame measured in square units (pixels times pixel aspect); AUTO fits the sensor width
    to the longer side; shift moves the frame by a fraction of that span.
    """
    render, cam_obj = scene.render, scene.camera
    cam = cam_obj.data
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    square_w, square_h = width * render.pixel_aspect_x, height * render.pixel_aspect_y
    if cam.sensor_fit == "AUTO":
        fitted, sensor = max(square_w, square_h), cam.sensor_width
    elif cam.sensor_fit == "HORIZONTAL":
        fitted, sensor = square_w, cam.sensor_width
    else:
        fitted, sensor = square_h, cam.sensor_height
    to_camera = np.array(cam_obj.matrix_world.inverted())
    p = np.asarray(points_world, dtype=float) @ to_camera[:3, :3].T + to_camera[:3, 3]
    x, y, depth = p[:, 0], p[:, 1], -p[:, 2]
    if cam.type == "ORTHO":
        u, v = x * fitted / cam.ortho_scale, y * fitted / cam.ortho_scale
    else:
        focal = cam.lens / sensor * fitted  # focal length in square units
        u, v = focal * x / depth, focal * y / depth
    u, v = u - cam.shift_x * fitted, v - cam.shift_y * fitted  # the frame moves, the point stays
    px = (square_w / 2 + u) / render.pixel_aspect_x
    py = (square_h / 2 - v) / render.pixel_aspect_y
    return np.stack([px, py], axis=1)


def reference_box(points_world, scene):
    pixels = reference_pixels(points_world, scene)
    return (*pixels.min(axis=0), *pixels.max(axis=0))


def box_of(b):
    return (b.x0, b.y0, b.x1, b.y1)


def depsgraph():
    return bpy.context.evaluated_depsgraph_get()


# Render settings and camera data for the projection cases.
CASES = {
    "auto-landscape": {"res": (1920, 1080)},
    "auto-portrait": {"res": (1080, 1920)},
    "horizontal-portrait": {"res": (1080, 1920), "cam": {"sensor_fit": "HORIZONTAL"}},
    "vertical-landscape": {
        "res": (1920, 1080),
        "cam": {"sensor_fit": "VERTICAL", "sensor_height": 20.0, "lens": 35.0},
    },
    "shift": {"res": (1920, 1080), "cam": {"shift_x": 0.1, "shift_y": -0.2}},
    "pixel-aspect-wide": {"res": (1920, 1080), "aspect": (2.0, 1.0)},
    "pixel-aspect-tall": {"res": (1920, 1080), "aspect": (1.0, 2.0)},  # AUTO fits vertically
    "percentage-50": {"res": (1920, 1080), "percentage": 50, "cam": {"shift_y": 0.05}},
    "ortho-shift": {
        "res": (1280, 720),
        "cam": {"type": "ORTHO", "ortho_scale": 7.0, "shift_x": 0.15, "shift_y": 0.05},
    },
    "ortho-vertical": {
        "res": (720, 1280),
        "cam": {"type": "ORTHO", "ortho_scale": 5.0, "sensor_fit": "VERTICAL"},
    },
}


def set_up_case(scene, case):
    render = scene.render
    render.resolution_x, render.resolution_y = case["res"]
    render.resolution_percentage = case.get("percentage", 100)
    render.pixel_aspect_x, render.pixel_aspect_y = case.get("aspect", (1.0, 1.0))
    return add_camera(
        scene, (1.0, -8.0, 2.0), (math.radians(82), 0, math.radians(6)), **case.get("cam", {})
    )


@pytest.mark.parametrize("name", CASES)
def test_bounds_match_hand_projection(bounds, name):
    scene = bpy.context.scene
    set_up_case(scene, CASES[name])
    cube = add_mesh(scene, location=(0.5, 0.0, 1.5), rotation=(0.3, 0.2, 0.5), scale=(1.5, 1, 1))

    b = bounds.object_bounds(cube, depsgraph(), scene)

    expected = reference_box(world_points(cube, CUBE_VERTS), scene)
    assert box_of(b) == pytest.approx(expected, abs=1e-3)
    render = scene.render
    assert (b.width, b.height) == (
        render.resolution_x * render.resolution_percentage // 100,
        render.resolution_y * render.resolution_percentage // 100,
    )
    assert b.visible and b.vertex_count == 8


@pytest.mark.parametrize("name", CASES)
def test_frame_corners_land_on_plate_corners(bounds, name):
    """Blender's own frame (view_frame: sensor fit, shift, pixel aspect) maps onto the plate."""
    scene = bpy.context.scene
    camera = set_up_case(scene, CASES[name])
    corners = world_points(camera, [tuple(c) for c in camera.data.view_frame(scene=scene)])

    pixels, in_front = project_points(bounds, corners, scene)

    w, h = bounds.camera_projection(scene).width, bounds.camera_projection(scene).height
    # view_frame's order: top-right, bottom-right, bottom-left, top-left.
    # view_frame is single precision: ~1e-5 pixels.
    assert pixels == pytest.approx(np.array([(w, 0), (w, h), (0, h), (0, 0)]), abs=1e-3)
    assert in_front.all()


def test_points_behind_the_near_plane_are_masked(bounds):
    scene = bpy.context.scene
    add_camera(scene, clip_start=0.5)
    pixels, in_front = project_points(
        bounds, np.array([(0, 0, -2), (0, 0, -0.25), (0, 0, 3)]), scene
    )
    assert in_front.tolist() == [True, False, False]
    assert pixels[0] == pytest.approx((960, 540))
    assert np.isnan(pixels[1:]).all()


def test_object_straddling_the_near_plane_is_clipped(bounds):
    """A strip from behind the camera to far in front: its bound is that of the part beyond
    z = -clip_start, whose corners are the far vertices and where the long sides cross."""
    scene = bpy.context.scene
    add_camera(scene, clip_start=1.0, lens=20.0)
    x, y = (0.2, 0.5), -0.3
    strip = add_mesh(
        scene, [(x[0], y, 3), (x[1], y, 3), (x[1], y, -6), (x[0], y, -6)], [(0, 1, 2, 3)]
    )

    b = bounds.object_bounds(strip, depsgraph(), scene)

    clipped = [(x[0], y, -1), (x[1], y, -1), (x[1], y, -6), (x[0], y, -6)]
    assert box_of(b) == pytest.approx(reference_box(clipped, scene), abs=1e-3)
    assert b.visible


def test_unbounded_clip_is_clamped(bounds):
    """Grazing the near plane far off-axis projects very far out: finite, clamped, still seen."""
    scene = bpy.context.scene
    add_camera(scene, clip_start=1e-6)
    strip = add_mesh(
        scene, [(-1e3, -1, 1), (1e3, -1, 1), (1e3, -1, -5), (-1e3, -1, -5)], [(0, 1, 2, 3)]
    )
    b = bounds.object_bounds(strip, depsgraph(), scene)
    assert (b.x0, b.x1, b.y1) == (-bounds.LIMIT, bounds.LIMIT, bounds.LIMIT)
    assert b.visible


@pytest.mark.parametrize(
    "location, behind",
    [((0, 0, 5), True), ((0, 0, -0.3), True), ((40, 0, -10), False), ((0, -30, -10), False)],
    ids=["behind", "nearer-than-clip-start", "off-right", "off-below"],
)
def test_objects_out_of_view_are_not_visible(bounds, location, behind):
    scene = bpy.context.scene
    add_camera(scene, clip_start=0.5)
    cube = add_mesh(scene, location=location, scale=(0.2, 0.2, 0.2))

    b = bounds.object_bounds(cube, depsgraph(), scene)

    assert not b.visible and b.vertex_count == 8
    if behind:
        assert box_of(b) == (0, 0, 0, 0)
    else:  # Off to a side: the real box, outside the frame.
        expected = reference_box(world_points(cube, CUBE_VERTS), scene)
        assert box_of(b) == pytest.approx(expected, abs=1e-3)
        assert b.x0 >= b.width or b.y0 >= b.height


def test_modifiers_are_applied(bounds):
    scene = bpy.context.scene
    add_camera(scene, location=(0, 0, 12))
    cube = add_mesh(scene, location=(-1, 0, 0))
    alone = bounds.object_bounds(cube, depsgraph(), scene)

    array = cube.modifiers.new("Array", "ARRAY")
    array.count, array.relative_offset_displace = 3, (1.0, 0.0, 0.0)
    arrayed = bounds.object_bounds(cube, depsgraph(), scene)

    long_cube = [(x, y, z) for x in (-0.5, 2.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    expected = reference_box(world_points(cube, long_cube), scene)
    assert box_of(arrayed) == pytest.approx(expected, abs=1e-3)
    assert arrayed.x1 > alone.x1 + 100 and arrayed.vertex_count == 24


def test_curve_gets_the_bounds_of_its_circle(bounds):
    scene = bpy.context.scene
    add_camera(scene, location=(0.5, 0.2, 10))
    curve = bpy.data.curves.new("Circle", "CURVE")
    spline = curve.splines.new("BEZIER")
    spline.bezier_points.add(3)
    spline.use_cyclic_u = True
    k = 0.5523  # handle length of a four-point Bezier circle
    for point, (cx, cy) in zip(spline.bezier_points, [(1, 0), (0, 1), (-1, 0), (0, -1)]):
        point.co = (cx, cy, 0)
        point.handle_left = (cx + k * cy, cy - k * cx, 0)
        point.handle_right = (cx - k * cy, cy + k * cx, 0)
    circle = add_object(scene, curve, location=(0.3, -0.2, 0), scale=(1.5, 1.5, 1.5))

    b = bounds.object_bounds(circle, depsgraph(), scene)

    # Seen face-on, its extremes are the four control points.
    square = [(-1, -1, 0), (1, 1, 0)]
    assert box_of(b) == pytest.approx(reference_box(world_points(circle, square), scene), abs=1e-3)
    assert b.visible and b.vertex_count > 4


@pytest.mark.parametrize("kind", ["FONT", "META"])
def test_text_and_metaballs_get_bounds(bounds, kind):
    scene = bpy.context.scene
    add_camera(scene, location=(0.5, 0.2, 10))
    if kind == "FONT":
        data = bpy.data.curves.new("Text", "FONT")
        data.body = "VR"
    else:
        data = bpy.data.metaballs.new("Meta")
        data.elements.new().radius = 1.0
    obj = add_object(scene, data)

    b = bounds.object_bounds(obj, depsgraph(), scene)

    # The evaluated bounding box projects to the same box for flat text seen face-on, and to a
    # larger one around the ball (its near face is nearer than the silhouette).
    corners = [tuple(c) for c in obj.evaluated_get(depsgraph()).bound_box]
    x0, y0, x1, y1 = reference_box(world_points(obj, corners), scene)
    assert b.visible and b.vertex_count > 8 and b.x1 - b.x0 > 20 and b.y1 - b.y0 > 20
    if kind == "FONT":
        assert box_of(b) == pytest.approx((x0, y0, x1, y1), abs=1e-3)
    else:
        assert x0 < b.x0 < b.x1 < x1 and y0 < b.y0 < b.y1 < y1


def test_edges_read_fast_match_the_edge_api(bounds):
    """The raw `.edge_verts` attribute read gives what mesh.edges says."""
    mesh = add_mesh(bpy.context.scene).data
    slow = np.array([tuple(e.vertices) for e in mesh.edges])
    assert bounds._edges(mesh).tolist() == slow.tolist()


def test_errors_say_what_is_wrong(bounds):
    scene = bpy.context.scene
    cube = add_mesh(scene)
    with pytest.raises(ValueError, match="has no camera"):
        bounds.object_bounds(cube, depsgraph(), scene)
    with pytest.raises(ValueError, match="has no camera"):
        project_points(bounds, np.zeros((1, 3)), scene)

    camera = add_camera(scene)
    empty = add_object(scene, None)
    with pytest.raises(ValueError, match="has no geometry"):
        bounds.object_bounds(empty, depsgraph(), scene)
    with pytest.raises(ValueError, match="not a camera"):
        bounds.object_bounds(cube, depsgraph(), scene, empty)

    camera.data.type = "PANO"
    with pytest.raises(ValueError, match="panoramic cameras are not supported"):
        bounds.camera_projection(scene)


def test_pixel_box_rounds_outwards(bounds):
    b = bounds.ScreenBounds(-2.5, 3.2, 10.0, 70.1, 64, 48, True, 8)
    assert b.pixel_box() == (-3, 3, 10, 71)
    assert b.pixel_box(clamp=True) == (0, 3, 10, 48)


def render_alpha_extent(scene, path):
    """Render with Cycles (film transparent) -> (x0, y0, x1, y1) of the alpha > 0 pixels."""
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device, cycles.samples = "CPU", 1
    cycles.use_denoising = cycles.use_adaptive_sampling = False
    cycles.filter_width = 0.01  # one sample at each pixel centre: a crisp alpha edge
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    alpha = pixels.reshape(h, w, 4)[::-1, :, 3]  # Blender images are stored bottom-up
    ys, xs = np.nonzero(alpha > 0)
    return xs.min(), ys.min(), xs.max() + 1, ys.max() + 1


def make_emissive(obj):
    material = bpy.data.materials.new("Glow")
    if material.node_tree is None:  # Blender 4.x; 5.x materials always have nodes
        material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Emission Color"].default_value = (1, 1, 1, 1)
    bsdf.inputs["Emission Strength"].default_value = 1.0
    obj.data.materials.append(material)


@pytest.mark.parametrize("setup", ["shift-and-pixel-aspect", "ortho", "near-plane-clip"])
def test_bounds_match_a_cycles_render(bounds, tmp_path, setup):
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    if setup == "near-plane-clip":  # The box starts behind the camera; only the clip bounds it.
        add_camera(scene, clip_start=2.0, lens=20.0)
        verts = [(x, y, z) for x in (0.3, 0.8) for y in (-0.6, -0.2) for z in (1.0, -8.0)]
        obj = add_mesh(scene, verts)
    else:
        cam = {"type": "ORTHO", "ortho_scale": 3.0} if setup == "ortho" else {"shift_y": -0.05}
        add_camera(scene, (0, -6, 0), (math.pi / 2, 0, 0), shift_x=0.1, **cam)
        scene.render.pixel_aspect_x = 1.0 if setup == "ortho" else 1.5
        obj = add_mesh(scene, location=(0.1, 0, -0.1), rotation=(0.4, 0.3, 0.7), scale=(1, 1, 0.6))
    scene.camera.scale = (1.3, 0.8, 1.1)  # renders ignore the camera's scale
    make_emissive(obj)

    b = bounds.object_bounds(obj, depsgraph(), scene)
    rendered = render_alpha_extent(scene, tmp_path / "render.png")

    assert 0 < b.x0 and b.x1 < b.width and 0 < b.y0 and b.y1 < b.height  # all inside the frame
    assert np.abs(np.array(rendered) - box_of(b)).max() <= 1.0, (rendered, b)
