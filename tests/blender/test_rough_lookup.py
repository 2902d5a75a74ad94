"""The Mix look of a rough surface reads its pre-filtered map at the centre of the GGX lobe
(virtual_reflections/ggx_lobe.py dominant_shift, operators/node_trees/reflection_nodes.py),
not along the mirror direction: seen at a grazing angle, the lobe of a rough floor leans toward the
floor's normal, away from the horizon.

A level camera 1 m above a rough floor (roughness 0.5); after Generate the floor's map is
replaced by a map whose value is 0.5 + 0.5 x the sine of the elevation (the camera is level,
so the camera frame's elevation is the world's), and Cycles renders the floor: each pixel
must show the map at the lobe's centre for its own view angle, which at 70-85 degrees off the
normal lies 20-40 degrees above the mirror direction.
"""

import math

import bpy
import numpy as np
from shots import addon_part, camera_rays, ground_plate, render_transparent

W, H = 96, 64
ROUGHNESS = 0.5


def elevation_map(width):
    """(width / 2, width, 3): 0.5 + 0.5 sin(elevation), top row the zenith."""
    h = width // 2
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    value = (0.5 + 0.5 * np.sin(lat)).astype(np.float32)
    return np.repeat(np.repeat(value[:, None, None], width, 1), 3, 2)


def rough_metal(roughness):
    """A Principled BSDF material of ``roughness`` (metallic as the add-on reads it)."""
    mat = bpy.data.materials.new("Rough Metal")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = roughness
    return mat


def camera(scene, location, pitch_deg):
    """The scene's camera at ``location``, looking along +Y ``pitch_deg`` below level."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = location
    cam.rotation_euler = (math.radians(90.0 - pitch_deg), 0.0, 0.0)
    cam.data.lens = 35.0
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    return cam


def grey_plate(scene):
    return ground_plate(scene, 0.0, lambda x, y: np.full(x.shape + (3,), 0.3), 0.6)


def floor_shot(tmp_path):
    """Render the rough floor in the Mix look with the elevation map: (H, W) red channel, and
    the scene."""
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=60.0, location=(0.0, 20.0, 0.0))
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(rough_metal(ROUGHNESS))
    camera(scene, (0.0, 0.0, 1.0), 0.0)  # level, looking along +Y
    settings = scene.virtual_reflections
    settings.method = "GROUND"
    settings.combine = "MIX"
    settings.strength, settings.ior = 3.0, 4.0  # the map is the whole reflection (3 x F >= 1)
    settings.resolution = "512"
    settings.plate_image = grey_plate(scene)
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [floor]
    )
    assert report.done == ["Floor"], report.warnings
    image = addon_part("operators.node_trees.shading").map_of(floor)
    addon_part("operators.scene.images").write_pixels(image, elevation_map(image.size[0]))

    return render_transparent(scene, tmp_path / "floor.exr", samples=8)[..., 0], scene


def expected(scene):
    """Per pixel: (the floor is seen, view angle off the normal in degrees, the map's value
    along the mirror direction, at the lobe's centre)."""
    origin, d = camera_rays(scene, W, H)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    seen = d[..., 2] < -1e-3
    view = np.degrees(np.arccos(np.clip(-d[..., 2], -1, 1)))
    mirror = d * np.array((1.0, 1.0, -1.0))
    a, b, c = addon_part("virtual_reflections.ggx_lobe").dominant_shift(ROUGHNESS)
    x = 1.0 - np.cos(np.radians(view))
    t = np.clip(x * (a + x * (b + x * c)), 0.0, 1.0)[..., None]
    centre = mirror + t * (np.array((0.0, 0.0, 1.0)) - mirror)
    centre /= np.linalg.norm(centre, axis=-1, keepdims=True)
    return seen, view, 0.5 + 0.5 * mirror[..., 2], 0.5 + 0.5 * centre[..., 2]


def test_a_rough_floor_at_a_grazing_angle_reads_the_lobe_centre(addon, tmp_path):
    red, scene = floor_shot(tmp_path)
    seen, view, along_mirror, at_centre = expected(scene)
    # Pixels whose footprint lies well inside one view angle: not the rows at the horizon.
    rows = seen & (view > 70.0) & (view < 86.0)
    assert rows.sum() > 200
    error = np.abs(red - at_centre)[rows]
    assert np.median(error) < 0.01 and error.max() < 0.04, (np.median(error), error.max())
    # ... which the mirror direction would miss by far more.
    assert np.median(np.abs(red - along_mirror)[rows]) > 0.08


def test_a_mirror_floor_keeps_the_mirror_direction(addon):
    """A mirror's map is not pre-filtered and its group has no lobe-centre nodes; a rough
    one's has, with the shift of its roughness (and reuses no mirror's group)."""
    shading = addon_part("operators.node_trees.shading")
    groups = {}
    for roughness in (0.0, ROUGHNESS):
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 5.0, 0.5))
        ball = bpy.context.active_object
        ball.data.materials.append(rough_metal(roughness))
        camera(scene, (0.0, 0.0, 1.5), 10.0)
        settings = scene.virtual_reflections
        settings.combine = "MIX"
        settings.plate_image = grey_plate(scene)
        report = addon_part("operators.generate").generate(
            scene, bpy.context.evaluated_depsgraph_get(), [ball]
        )
        assert report.done == [ball.name], report.warnings
        group = ball[shading.RECORD]["group"]
        groups[roughness] = (group.get("vr_shift"), "Lobe Centre" in group.nodes)
    assert groups[0.0] == ("", False)
    a, b, c = addon_part("virtual_reflections.ggx_lobe").dominant_shift(ROUGHNESS)
    assert groups[ROUGHNESS][1]
    assert [float(v) for v in groups[ROUGHNESS][0].split(",")] == [
        float(f"{v:.6g}") for v in (a, b, c)
    ]
