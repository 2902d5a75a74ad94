"""Camera View + Ground in the Replace look: the material reads the ground per shading point.

A mirror ball (radius 0.5, smooth) stands on the ground Z = 0, 5 m in front of the camera.
The plate is made analytically for the Blender camera: the ground a checker of 0.5 m squares,
red and blue, the sky green. Rendered in Cycles, each of the ball's pixels must show the
colour of the ground point its own reflected ray meets (traced here analytically from the
sphere) — also where the ray from the ball's CENTRE in the same direction meets a square of
the other colour, which is what a map seen from the centre shows (parallax near the contact).
"""

import math

import bpy
import numpy as np
import pytest
from shots import addon_part, camera_rays, ground_plate, render_exr, render_transparent

W, H = 240, 135
RED, BLUE, SKY = np.array((0.9, 0.05, 0.05)), np.array((0.05, 0.05, 0.9)), (0.1, 0.8, 0.1)
CENTRE, RADIUS, SQUARE = np.array((0.0, 0.0, 0.5)), 0.5, 0.5


def red_at(x, y):
    return (np.floor(x / SQUARE) + np.floor(y / SQUARE)) % 2 == 0


def make_shot(combine="REPLACE", method="GROUND", colour=None, **frame):
    bpy.ops.mesh.primitive_uv_sphere_add(
        segments=96, ring_count=48, radius=RADIUS, location=tuple(CENTRE)
    )
    return make_shot_on(
        bpy.context.scene, bpy.context.active_object, combine, method, colour, **frame
    )


def checker(x, y):
    return np.where(red_at(x, y)[..., None], RED, BLUE)


def make_shot_on(
    scene,
    ball,
    combine="REPLACE",
    method="GROUND",
    colour=None,
    size=(W, H),
    camera=(),
    roll_deg=0.0,
    pixel_aspect=(1.0, 1.0),
    plate_size=None,
):
    """Camera, plate (the ground ``colour(x, y)``, by default the checker) and Generate for
    ``ball`` (a sphere at CENTRE). The frame: the render ``size``, the camera data's
    ``camera`` settings (name, value pairs), its roll, the ``pixel_aspect`` and the plate's
    size (by default the render's)."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.3, -4.0, 1.6)
    cam.rotation_euler = (math.radians(90 - 14), 0.0, math.radians(roll_deg))
    cam.data.lens = 35.0
    for name, value in camera:
        setattr(cam.data, name, value)
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = pixel_aspect
    ball.name = "Ball"
    bpy.context.view_layer.objects.active = ball
    bpy.ops.object.shade_smooth()
    settings = scene.virtual_reflections
    settings.method = method
    settings.combine = combine
    settings.resolution = "512"
    settings.plate_image = ground_plate(scene, 0.0, colour or checker, SKY, size=plate_size)
    report = addon_part("operators.generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), [ball]
    )
    assert report.done == ["Ball"], report.warnings
    return scene, ball, report


def render(scene, tmp_path):
    """(H, W, 4) float32 linear RGBA, top row first: Cycles, the film transparent."""
    return render_transparent(scene, tmp_path / "ball.exr")


def traced(scene):
    """Per pixel of the render: (hit the ball, the ground point of the reflected ray from the
    surface, the ground point of the same direction from the ball's centre, the ray goes
    down)."""
    origin, d = camera_rays(scene, scene.render.resolution_x, scene.render.resolution_y)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    oc = origin - CENTRE
    b = d @ oc
    disc = b * b - (oc @ oc - RADIUS**2)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0.0))
    p = origin + t[..., None] * d
    n = (p - CENTRE) / RADIUS
    r = d - 2.0 * (d * n).sum(-1, keepdims=True) * n
    down = r[..., 2] < -1e-3
    safe = np.where(down, r[..., 2], -1.0)
    surface = p + (-p[..., 2] / safe)[..., None] * r
    centre = CENTRE + (-CENTRE[2] / safe)[..., None] * r
    return hit, surface, centre, down


def confident(points):
    """Ground points at least 3 cm from a checker edge (their colour is unambiguous)."""
    frac = np.mod(points[..., :2], SQUARE)
    return (np.minimum(frac, SQUARE - frac) > 0.03).all(-1)


def reflected_ground(rgba, scene):
    """The ball's pixels well inside its silhouette (no edge pixels) that reflect the ground
    nearby (on the plate: within 3 m of the ball) in an unambiguous colour, the colour they
    must show (red) and the one they do, with the traced points (`traced`)."""
    hit, surface, centre, down = traced(scene)
    inside = rgba[..., 3] > 0.999
    near = np.linalg.norm(surface[..., :2], axis=-1) < 3.0
    chosen = hit & inside & down & near & confident(surface)
    expected = red_at(surface[..., 0], surface[..., 1])
    return chosen, expected, rgba[..., 0] > rgba[..., 2], centre


def test_each_point_of_a_mirror_reflects_its_own_ground_point(addon, tmp_path):
    scene, _, _ = make_shot()
    rgba = render(scene, tmp_path)
    chosen, expected, red_seen, centre = reflected_ground(rgba, scene)
    assert chosen.sum() > 150, chosen.sum()
    agree = (red_seen == expected)[chosen].mean()
    assert agree > 0.9, agree
    # Where the object's centre would see the other colour, the render follows the surface.
    parallax = chosen & confident(centre) & (red_at(centre[..., 0], centre[..., 1]) != expected)
    assert parallax.sum() > 30, parallax.sum()
    assert (red_seen == expected)[parallax].mean() > 0.8


@pytest.mark.slow
def test_eevee_reads_the_ground_per_point_as_cycles_does(addon, tmp_path):
    """The same ball in EEVEE (software GL): its material's ground lookup is the same node
    tree, so the same pixels show their own ground point's colour (89 % of them where Cycles
    has 92 %), the parallax pixels included."""
    scene, _, _ = make_shot()
    scene.render.engine = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"
    scene.render.film_transparent = True
    scene.eevee.taa_render_samples = 4
    scene.view_settings.view_transform = "Standard"
    rgba = render_exr(scene, tmp_path / "eevee.exr")
    chosen, expected, red_seen, centre = reflected_ground(rgba, scene)
    assert chosen.sum() > 150, chosen.sum()
    agree = (red_seen == expected)[chosen].mean()
    parallax = chosen & confident(centre) & (red_at(centre[..., 0], centre[..., 1]) != expected)
    assert agree > 0.85, agree
    assert (red_seen == expected)[parallax].mean() > 0.8


# Frames other than a centred landscape lens: each moves the ground point a pixel sees, so a
# projection that ignored it would read the other colour of the checker on many pixels.
FRAMES = {
    "shifted lens": dict(camera=(("shift_x", 0.12), ("shift_y", -0.08))),
    "portrait": dict(size=(136, 240)),
    "portrait, horizontal fit": dict(size=(136, 240), camera=(("sensor_fit", "HORIZONTAL"),)),
    "vertical fit": dict(camera=(("sensor_fit", "VERTICAL"), ("sensor_height", 18.0))),
    "non-square pixels": dict(pixel_aspect=(1.0, 1.5)),
    "rolled camera": dict(roll_deg=8.0),
    "plate twice the render": dict(plate_size=(2 * W, 2 * H)),
}


@pytest.mark.parametrize("frame", list(FRAMES))
def test_the_ground_is_placed_for_every_frame_of_the_camera(addon, tmp_path, frame):
    scene, _, report = make_shot(**FRAMES[frame])
    assert not report.warnings, report.warnings
    rgba = render(scene, tmp_path)
    chosen, expected, red_seen, _ = reflected_ground(rgba, scene)
    assert chosen.sum() > 150, chosen.sum()
    agree = (red_seen == expected)[chosen].mean()
    assert agree > 0.85, agree


def test_the_map_seen_from_the_centre_gets_the_contact_wrong(addon, tmp_path):
    """The World look (the map alone, seen from the centre) on the same pixels: where the
    centre sees the other colour, a mirror lit by that map shows it, so the test above can
    fail without the per-point lookup."""
    scene, ball, _ = make_shot(combine="WORLD")
    mirror = bpy.data.materials.new("Mirror")
    if bpy.app.version < (5, 0, 0):
        mirror.use_nodes = True
    bsdf = mirror.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    ball.data.materials.append(mirror)
    rgba = render(scene, tmp_path)
    chosen, expected, red_seen, centre = reflected_ground(rgba, scene)
    parallax = chosen & confident(centre) & (red_at(centre[..., 0], centre[..., 1]) != expected)
    assert parallax.sum() > 30, parallax.sum()
    assert (red_seen == expected)[parallax].mean() < 0.5


GREY = 0.5


def grey_ground(strength=None):
    """A shot on a plain GREY ground (the panel's Contact Shadow ``strength``, None: as is)."""
    bpy.ops.mesh.primitive_uv_sphere_add(
        segments=96, ring_count=48, radius=RADIUS, location=tuple(CENTRE)
    )
    scene, ball = bpy.context.scene, bpy.context.active_object
    if strength is not None:
        scene.virtual_reflections.contact_shadow = strength
    make_shot_on(scene, ball, colour=lambda x, y: np.full((*np.shape(x), 3), GREY))
    return scene, ball


def ground_seen(scene, tmp_path):
    """Per pixel of the render: (what it shows of the grey ground, 1 where lit as the plate,
    the share F of an even sky the ball hides from the ground point it reflects, traced
    analytically, and the pixels well inside the ball that reflect the ground)."""
    rgba = render(scene, tmp_path)
    hit, surface, _, down = traced(scene)
    to_centre = CENTRE - surface
    d = np.linalg.norm(to_centre, axis=-1)
    hidden = np.clip((RADIUS / d) ** 2 * np.maximum(to_centre[..., 2], 0) / d, 0, 1)
    return rgba[..., :3].mean(-1) / GREY, hidden, hit & (rgba[..., 3] > 0.999) & down


def test_the_ground_around_the_object_is_darkened_by_the_sky_it_hides(addon, tmp_path):
    """The plate was shot without the ball; in the render the ball hides part of the sky from
    the ground around it. On a plain grey ground each pixel reflecting the ground must show
    grey x (1 - F), F = (r / d)^2 cos: the share of an even sky a sphere of radius r hides
    from a ground point at distance d, at angle acos(cos) from straight up."""
    scene, _ = grey_ground()
    seen, hidden, ground = ground_seen(scene, tmp_path)
    near, far = ground & (hidden > 0.25), ground & (hidden < 0.02)
    assert near.sum() > 40 and far.sum() > 40, (near.sum(), far.sum())
    assert np.abs(seen[near] - (1 - hidden[near])).mean() < 0.05
    assert seen[near].mean() < 0.7  # a real darkening, not a rounding
    assert np.abs(seen[far] - 1).mean() < 0.03


@pytest.mark.parametrize("strength", [0.5, 0.0])
def test_the_contact_shadow_follows_the_artists_strength(addon, tmp_path, strength):
    """Contact Shadow k (the panel's, --contact-shadow): each pixel reflecting the plain grey
    ground shows grey x (1 - k F); 0 leaves the plate's ground as it is (a plate that already
    shows the object's shadow). The strength is held in the material and read back by the
    ray-traced pass."""
    scene, ball = grey_ground(strength)
    group = ball.get(addon_part("operators.node_trees.shading").RECORD)["group"]
    held = group.nodes[addon_part("operators.node_trees.ground_nodes").SHADOW_NODE]
    assert held.outputs[0].default_value == pytest.approx(strength)
    seen, hidden, ground = ground_seen(scene, tmp_path)
    near = ground & (hidden > 0.25)
    assert near.sum() > 40, near.sum()
    assert np.abs(seen[near] - (1 - strength * hidden[near])).mean() < 0.05


def test_the_replace_map_is_the_same_for_every_pose(addon):
    """In the Replace look the map holds no ground (the material reads it): its Params, the
    lookup table's key, do not change when the ball moves; in the World look they do."""
    scene, ball, _ = make_shot()
    pipeline = addon_part("operators.pipeline")
    plate = addon_part("operators.scene.plate")

    def params():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        view = pipeline.view(scene, plate.pixels(scene)[0].shape, depsgraph)
        box = (0.0, 0.0, 1.0, 1.0)  # the Params do not depend on it
        return pipeline.reflect_request(view, scene, depsgraph, [ball], box, 256).params

    for combine, moves in (("REPLACE", False), ("WORLD", True)):
        scene.virtual_reflections.combine = combine
        ball.location.x = 0.0
        bpy.context.view_layer.update()
        before = params()
        ball.location.x = 0.4
        bpy.context.view_layer.update()
        assert (params() != before) == moves, combine
        assert before.up is not None  # the world's horizon in both


def test_removing_takes_the_ground_group_away(addon):
    make_shot()
    assert any(g.name.startswith("VR Ground") for g in bpy.data.node_groups)
    addon_part("operators.generate").remove_all()
    created = addon_part("operators.scene.images").CREATED
    assert not [g.name for g in bpy.data.node_groups if g.get(created)]


def test_a_rough_surface_gets_a_blurred_map_with_the_ground_in_it(addon):
    """The Mix look (Glossy) on a rough material (0.35): the map is pre-filtered (smoother
    than the mirror's) and holds the ground seen from the centre, and no sharp per-point
    lookup is wired; a mirror material gets the per-point lookup."""
    shading = addon_part("operators.node_trees.shading")
    maps = {}
    for roughness in (0.0, 0.35):
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        mat = bpy.data.materials.new("Metal")
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = roughness
        bpy.ops.mesh.primitive_uv_sphere_add(radius=RADIUS, location=tuple(CENTRE))
        bpy.context.active_object.data.materials.append(mat)
        scene, ball, _ = make_shot_on(scene, bpy.context.active_object, combine="MIX")
        assert shading.roughness(ball) == pytest.approx(roughness)
        image = shading.map_of(ball)
        maps[roughness] = addon_part("operators.scene.images").read_pixels(image)[..., :3].copy()
        grounds = [
            n for m in ball.material_slots for g in bpy.data.node_groups
            if g.get("vr_mode") == "MIX" for n in g.nodes if n.name == "VR Ground"
        ]  # fmt: skip
        assert bool(grounds) == (roughness == 0.0)
    # Neighbouring texels differ less in the pre-filtered map.
    sharp, rough = (np.abs(np.diff(maps[r], axis=1)).mean() for r in (0.0, 0.35))
    assert rough < 0.5 * sharp, (rough, sharp)
    # The ground seen from the centre is in the rough map: below the ball toward the camera
    # (between ball and camera, where Camera View alone has only a fill) the checker shows:
    # red and blue both present in the lower half.
    lower = maps[0.35][maps[0.35].shape[0] * 5 // 8 :]
    assert (lower[..., 0] > lower[..., 2] + 0.1).any() and (
        lower[..., 2] > lower[..., 0] + 0.1
    ).any()
