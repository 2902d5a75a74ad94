"""operators/node_trees/shading.py: the camera-frame lat-long lookup, material modes, world, detach.

Pictures with known answers (docs/conventions.md): a chrome sphere with a map whose left half (the
plate's left) is red must be red on its left side in the render, also after the camera moves.
Renders are Cycles on the CPU, tiny and without denoising (the denoiser perturbs flat colours);
one EEVEE render is marked slow (software GL here). Every render is read back from a 32-bit
EXR, so pixel values are scene-linear.
"""

import importlib
import math

import numpy as np
import pytest
from shots import node_tree_signature, render_exr  # noqa: E402

bpy = pytest.importorskip("bpy")
from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Matrix, Vector  # noqa: E402

EEVEE = "BLENDER_EEVEE_NEXT" if bpy.app.version < (5, 0, 0) else "BLENDER_EEVEE"
VR_KINDS = ("material", "world", "reflection", "lookup", "latlong")


@pytest.fixture
def shading(addon):
    return importlib.import_module(f"{addon.__name__}.operators.node_trees.shading")


@pytest.fixture
def world(addon):
    return importlib.import_module(f"{addon.__name__}.operators.node_trees.world")


@pytest.fixture
def reflection_nodes(addon):
    return importlib.import_module(f"{addon.__name__}.operators.node_trees.reflection_nodes")


# --- scene helpers ----------------------------------------------------------------------------


def new_material(name, color=(0.8, 0.8, 0.8, 1.0), metallic=0.0):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = color
    bsdf.inputs["Metallic"].default_value = metallic
    mat.diffuse_color = color
    return mat


def add_camera(scene, location=(0.0, -4.0, 0.0), look_at=(0.0, 0.0, 0.0), roll=0.0, lens=50):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.lens = lens
    scene.collection.objects.link(cam)
    scene.camera = cam
    aim(cam, location, look_at, roll)
    return cam


def aim(cam, location, look_at=(0.0, 0.0, 0.0), roll=0.0):
    """Put the camera at ``location`` looking at ``look_at``, rolled by ``roll`` radians."""
    forward = Vector(look_at) - Vector(location)
    rotation = forward.to_track_quat("-Z", "Y").to_matrix() @ Matrix.Rotation(roll, 3, "Z")
    cam.matrix_world = Matrix.Translation(location) @ rotation.to_4x4()
    bpy.context.view_layer.update()


def add_sphere(name="Sphere", location=(0.0, 0.0, 0.0), radius=1.0, mesh=None):
    if mesh is None:
        bpy.ops.mesh.primitive_uv_sphere_add(
            segments=64, ring_count=32, radius=radius, location=location
        )
        obj = bpy.context.object
        obj.name = name
        bpy.ops.object.shade_smooth()
        return obj
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def map_image(name, rgb):
    """A float image from ``rgb``: (H, W, 3) float32, scene-linear, TOP row first (the map
    convention); Blender stores the bottom row first, hence the flip."""
    h, w, _ = rgb.shape
    image = bpy.data.images.new(name, w, h, float_buffer=True, alpha=True)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    image.pixels.foreach_set(rgba[::-1].ravel())
    return image


def halves_map(name, left, right, w=128, h=64):
    rgb = np.empty((h, w, 3), np.float32)
    rgb[:, : w // 2] = left
    rgb[:, w // 2 :] = right
    return map_image(name, rgb)


def top_bottom_map(name, top, bottom, w=128, h=64):
    rgb = np.empty((h, w, 3), np.float32)
    rgb[: h // 2] = top
    rgb[h // 2 :] = bottom
    return map_image(name, rgb)


def render(scene, tmp_path, engine="CYCLES", size=(64, 64), samples=4):
    """Render and return (H, W, 3) float32 scene-linear, TOP row first."""
    r = scene.render
    r.engine = engine
    r.resolution_x, r.resolution_y = size
    r.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    if engine == "CYCLES":
        scene.cycles.device = "CPU"
        scene.cycles.samples = samples
        scene.cycles.use_denoising = False
    else:
        scene.eevee.taa_render_samples = samples
    path = tmp_path / f"render_{len(list(tmp_path.glob('render_*.exr')))}.exr"
    return render_exr(scene, path)[..., :3].copy()


def projected_centre(scene, obj, size):
    """The object's origin in render pixels (x right, y down)."""
    ndc = world_to_camera_view(scene, scene.camera, obj.matrix_world.translation)
    return ndc.x * size[0], (1.0 - ndc.y) * size[1]


def sides(pixels, centre, axis, band=3.0):
    """Masks of lit pixels before / after the centre along ``axis`` (1: x, 0: y), leaving out a
    band around the centre line where the two halves of the map meet."""
    h, w, _ = pixels.shape
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    coord, c = (xs, centre[0]) if axis == 1 else (ys, centre[1])
    lit = pixels.sum(axis=2) > 0.2
    return lit & (coord < c - band), lit & (coord > c + band)


def dominant(pixels, mask, channel_weights):
    """Fraction of masked pixels whose colour is closer in hue to ``channel_weights``."""
    rgb = pixels[mask]
    target = np.asarray(channel_weights, np.float32)
    score = rgb @ target - rgb @ (1.0 - target)
    return float((score > 0).mean()) if len(rgb) else 0.0


RED, BLUE = (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
GREEN, MAGENTA = (0.0, 1.0, 0.0), (1.0, 0.0, 1.0)


def assert_left_red_right_blue(scene, sphere, pixels, size, radius=None):
    """Left of the sphere's projected centre red, right of it blue; only pixels within
    ``radius`` (world units, the sphere's) of the centre when other objects are in view."""
    centre = projected_centre(scene, sphere, size)
    left, right = sides(pixels, centre, axis=1)
    if radius is not None:
        side = scene.camera.matrix_world.to_3x3() @ Vector((radius, 0.0, 0.0))
        edge = world_to_camera_view(scene, scene.camera, sphere.matrix_world.translation + side)
        r_px = abs(edge.x * size[0] - centre[0]) + 1.0
        ys, xs = np.mgrid[0 : size[1], 0 : size[0]] + 0.5
        near = np.hypot(xs - centre[0], ys - centre[1]) < r_px
        left, right = left & near, right & near
    assert left.sum() > 100 and right.sum() > 100
    assert dominant(pixels, left, RED) > 0.97
    assert dominant(pixels, right, BLUE) > 0.97


# --- the lookup -------------------------------------------------------------------------------


def test_lookup_group_matches_the_lat_long_convention(reflection_nodes, clean_file, tmp_path):
    """Render the group's UV output for known camera-frame directions (tiny emissive planes
    parented to a tilted, rolled camera) and compare with docs/conventions.md's formula."""
    scene = clean_file.scene
    cam = add_camera(scene, location=(1.0, -3.0, 2.0), look_at=(0.2, 0.5, -0.3), roll=0.4)
    group = reflection_nodes.ensure_lookup_group()
    assert reflection_nodes.ensure_lookup_group() == group  # reused
    # Product camera frame -> Blender camera-local: rotate 180 degrees about Y.
    to_local = Matrix.Rotation(math.pi, 3, "Y")
    directions = {
        "forward": (0.0, 0.0, 1.0),
        "plate_left": (1.0, 0.0, 0.0),
        "plate_right": (-1.0, 0.0, 0.2),
        "up": (0.3, 0.9, 0.2),
        "down_back": (0.2, -0.5, -0.6),
        "oblique": (-0.4, 0.3, 0.8),
    }
    size = (3 * 16, 2 * 16)
    probes = {}
    for i, (name, d) in enumerate(directions.items()):
        mesh = bpy.data.meshes.new(name)
        s = 0.3
        mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
        obj = bpy.data.objects.new(name, mesh)
        scene.collection.objects.link(obj)
        obj.parent = cam
        obj.location = ((i % 3 - 1) * 0.9, (0.5 - i // 3) * 0.9, -4.0)
        mat = bpy.data.materials.new(name)
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        tree = mat.node_tree
        tree.nodes.clear()
        lookup = tree.nodes.new("ShaderNodeGroup")
        lookup.node_tree = group
        world_dir = cam.matrix_world.to_3x3() @ (to_local @ Vector(d))
        lookup.inputs["Vector"].default_value = world_dir
        emission = tree.nodes.new("ShaderNodeEmission")
        out = tree.nodes.new("ShaderNodeOutputMaterial")
        tree.links.new(lookup.outputs["UV"], emission.inputs["Color"])
        tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
        mesh.materials.append(mat)
        probes[name] = obj
    cam.data.sensor_fit = "HORIZONTAL"
    bpy.context.view_layer.update()
    pixels = render(scene, tmp_path, size=size, samples=1)

    for name, d in directions.items():
        x, y, z = Vector(d).normalized()
        lon, lat = math.atan2(x, z), math.asin(y)
        expected_u = 0.5 - lon / (2 * math.pi)  # = (px + .5) / W
        expected_v = 0.5 + lat / math.pi  # = 1 - (py + .5) / H, v up
        px, py = projected_centre(scene, probes[name], size)
        u, v, _ = pixels[int(py), int(px)]
        assert (u, v) == pytest.approx((expected_u, expected_v), abs=1e-3), name


def test_equirect_output_agrees_with_uv(reflection_nodes, clean_file, tmp_path):
    """The Environment Texture path (used for sampling) lands on the same map pixel as UV: a
    map storing each pixel centre's (u, v) read back through 'Equirect' returns the UV."""
    scene = clean_file.scene
    add_camera(scene, location=(0.5, -4.0, 1.0), roll=-0.3)
    w, h = 256, 128
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    coords = np.stack([xs / w, 1.0 - ys / h, np.zeros_like(xs)], axis=-1).astype(np.float32)
    image = map_image("coords", coords)
    sphere = add_sphere()
    mat = bpy.data.materials.new("probe")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    lookup = tree.nodes.new("ShaderNodeGroup")
    lookup.node_tree = reflection_nodes.ensure_lookup_group()
    tree.links.new(geometry.outputs["Normal"], lookup.inputs["Vector"])
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    env.interpolation = "Closest"
    tree.links.new(lookup.outputs["Equirect"], env.inputs["Vector"])
    diff = tree.nodes.new("ShaderNodeVectorMath")
    diff.operation = "SUBTRACT"
    tree.links.new(env.outputs["Color"], diff.inputs[0])
    tree.links.new(lookup.outputs["UV"], diff.inputs[1])
    absolute = tree.nodes.new("ShaderNodeVectorMath")
    absolute.operation = "ABSOLUTE"
    tree.links.new(diff.outputs["Vector"], absolute.inputs[0])
    emission = tree.nodes.new("ShaderNodeEmission")
    # Lit marker in blue so the sphere is distinguishable from the black background.
    add = tree.nodes.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    add.inputs[1].default_value = (0.0, 0.0, 1.0)
    tree.links.new(absolute.outputs["Vector"], add.inputs[0])
    tree.links.new(add.outputs["Vector"], emission.inputs["Color"])
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    sphere.data.materials.append(mat)
    pixels = render(scene, tmp_path, size=(48, 48), samples=1)
    inside = pixels[..., 2] > 0.99
    assert inside.sum() > 300
    # Closest sampling: at most half a pixel off; the back seam wraps u by 1 (at most a few).
    du, dv = pixels[inside, 0], pixels[inside, 1]
    assert np.mean((du < 0.5 / w + 1e-3) | (du > 1 - 1e-3)) > 0.99
    assert np.mean(dv < 0.5 / h + 1e-3) > 0.99


# --- chrome sphere pictures (REPLACE) ---------------------------------------------------------


def test_chrome_sphere_left_half_red_right_half_blue(shading, clean_file, tmp_path):
    scene = clean_file.scene
    add_camera(scene)
    sphere = add_sphere()
    shading.attach(sphere, halves_map("map", RED, BLUE), "REPLACE")
    size = (64, 64)
    assert_left_red_right_blue(scene, sphere, render(scene, tmp_path, size=size), size)


def test_lookup_follows_the_camera_without_rebuilding(shading, clean_file, tmp_path):
    """Attach once, then move, tilt and roll the camera: still the plate's left is red."""
    scene = clean_file.scene
    cam = add_camera(scene)
    sphere = add_sphere(location=(0.5, 1.0, 0.3))
    shading.attach(sphere, halves_map("map", RED, BLUE), "REPLACE")
    size = (64, 64)
    poses = [
        ((3.0, -2.0, 2.5), 0.0),
        ((-2.5, 3.5, -1.0), 0.6),
        ((0.5, 1.0, 5.0), -1.2),  # looking straight down
    ]
    for location, roll in poses:
        aim(cam, location, sphere.location, roll)
        assert_left_red_right_blue(scene, sphere, render(scene, tmp_path, size=size), size)


def test_chrome_sphere_top_half_green_bottom_half_magenta(shading, clean_file, tmp_path):
    scene = clean_file.scene
    cam = add_camera(scene)
    sphere = add_sphere()
    shading.attach(sphere, top_bottom_map("map", GREEN, MAGENTA), "REPLACE")
    size = (64, 64)
    for location, roll in [((0.0, -4.0, 0.0), 0.0), ((-3.0, 2.0, 2.0), 0.8)]:
        aim(cam, location, (0.0, 0.0, 0.0), roll)
        pixels = render(scene, tmp_path, size=size)
        top, bottom = sides(pixels, projected_centre(scene, sphere, size), axis=0)
        assert top.sum() > 100 and bottom.sum() > 100
        assert dominant(pixels, top, GREEN) > 0.97
        assert dominant(pixels, bottom, MAGENTA) > 0.97


def halves_and_seam(shading, scene, tmp_path, engine):
    """One render, two chrome spheres: the red/blue one on the camera axis, and one whose map
    is green behind the camera (|lon| > 90 degrees, around the back seam u = 0/1) with a
    magenta front. The second sphere's middle reflects the back: it must be green throughout,
    without the line a mip-mapped lookup draws where u jumps from 1 to 0."""
    add_camera(scene, location=(4.0, -6.0, 2.0), roll=0.5)
    halves = add_sphere("Halves")
    shading.attach(halves, halves_map("halves", RED, BLUE), "REPLACE")
    cam = scene.camera.matrix_world.to_3x3()
    seam = add_sphere("Seam", location=cam @ Vector((1.6, 1.2, 0.0)), radius=0.7)
    rgb = np.empty((64, 128, 3), np.float32)
    rgb[:] = GREEN
    rgb[:, 32:96] = MAGENTA
    shading.attach(seam, map_image("seam", rgb), "REPLACE")
    size = (96, 96)
    pixels = render(scene, tmp_path, engine=engine, size=size, samples=1)
    assert np.isfinite(pixels).all()
    assert_left_red_right_blue(scene, halves, pixels, size, radius=1.0)

    cx, cy = projected_centre(scene, seam, size)
    ys, xs = np.mgrid[0 : size[1], 0 : size[0]] + 0.5
    disk = np.hypot(xs - cx, ys - cy) < 5.0  # the sphere's radius is ~ 12 px
    assert (pixels[disk].sum(axis=1) > 0.2).all()
    greens = pixels[disk]
    assert np.all(greens[:, 1] > 0.95) and np.all(greens[:, [0, 2]] < 0.05)


def test_back_seam_has_no_line(shading, clean_file, tmp_path):
    halves_and_seam(shading, clean_file.scene, tmp_path, "CYCLES")


@pytest.mark.slow
def test_eevee_agrees_halves_and_seam(shading, clean_file, tmp_path):
    """EEVEE agrees with Cycles on Vector Transform's camera space, and its Environment Texture
    lookup has no seam line (an Image Texture with mipmaps has one)."""
    halves_and_seam(shading, clean_file.scene, tmp_path, EEVEE)


# --- modes, restoring, leaving nothing behind -------------------------------------------------


def object_state(shading, obj):
    return [
        (link, getattr(data, "name", None), getattr(object_level, "name", None))
        for link, data, object_level in shading.slot_states(obj)
    ]


def snapshot(shading, scene, objects):
    """Everything attach/detach may touch, in comparable form."""
    return {
        "materials": {
            m.name: (
                node_tree_signature(m.node_tree),
                tuple(m.diffuse_color),
                sorted(m.keys()),
            )
            for m in bpy.data.materials
        },
        "objects": {obj.name: object_state(shading, obj) for obj in objects},
        "meshes": {
            me.name: [getattr(m, "name", None) for m in me.materials] for me in bpy.data.meshes
        },
        "world": (
            scene.world.name if scene.world else None,
            node_tree_signature(scene.world.node_tree) if scene.world else None,
        ),
        "ids": {
            kind: sorted(i.name for i in getattr(bpy.data, kind) if i.name != "Render Result")
            for kind in ("materials", "node_groups", "worlds", "meshes", "objects", "images")
        },
        "keys": {obj.name: sorted(obj.keys()) for obj in objects}
        | {"scene": sorted(k for k in scene.keys() if k != "cycles")},
    }


def vr_leftovers():
    return [
        id_data.name
        for coll in (bpy.data.materials, bpy.data.node_groups, bpy.data.worlds)
        for id_data in coll
        if id_data.get("vr_created") in VR_KINDS
    ]


def user_scene(scene):
    """A sphere with two slots: a Principled material with a linked base colour (via an RGB
    node) on the data, and an object-level material on the second; plus a user world."""
    add_camera(scene)
    sphere = add_sphere()
    painted = new_material("Painted", color=(0.2, 0.5, 0.8, 1.0))
    rgb = painted.node_tree.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.9, 0.3, 0.1, 1.0)
    bsdf = painted.node_tree.nodes["Principled BSDF"]
    painted.node_tree.links.new(rgb.outputs[0], bsdf.inputs["Base Color"])
    sphere.data.materials.append(painted)
    sphere.data.materials.append(new_material("Shared Data"))
    sphere.material_slots[1].link = "OBJECT"
    sphere.material_slots[1].material = new_material("Object Level", color=(1, 1, 0, 1))
    for poly in sphere.data.polygons:
        poly.material_index = int(poly.center.x > 0)
    world = bpy.data.worlds.new("Studio")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.1, 0.2, 0.3, 1.0)
    scene.world = world
    return sphere


@pytest.mark.parametrize("mode", ["REPLACE", "MODULATE", "MIX", "WORLD"])
def test_attach_renders_and_detach_restores_exactly(shading, world, clean_file, tmp_path, mode):
    scene = clean_file.scene
    sphere = user_scene(scene)
    image = halves_map("map", RED, BLUE)
    before = snapshot(shading, scene, [sphere])

    shading.attach(sphere, image, mode, strength=1.0, ior=1.45)
    assert shading.is_attached(sphere)
    during = snapshot(shading, scene, [sphere])
    for name, signature in before["materials"].items():
        assert during["materials"][name] == signature, f"{name} was modified"
    if mode == "WORLD":
        assert scene.world.name == world.WORLD_NAME
        assert during["objects"] == before["objects"]
    else:
        assert all(link == "OBJECT" for link, _, _ in during["objects"][sphere.name])
        assert during["meshes"] == before["meshes"]
        assert during["world"] == before["world"]
        copies = [m for _, _, m in during["objects"][sphere.name]]
        assert copies == [f"Painted [VR {sphere.name}]", f"Object Level [VR {sphere.name}]"]
        assert any(g.startswith(f"VR Reflection {mode}") for g in during["ids"]["node_groups"])

    pixels = render(scene, tmp_path, size=(32, 32), samples=4)
    assert np.isfinite(pixels).all()
    centre = pixels[12:20, 12:20]
    assert centre.max() > 0.05  # the sphere shows something

    shading.detach(sphere)
    assert not shading.is_attached(sphere)
    assert snapshot(shading, scene, [sphere]) == before
    assert vr_leftovers() == []


def test_modulate_multiplies_the_base_colour(shading, clean_file, tmp_path):
    """GL modulate: a white map returns the material's colour, from the Base Color default
    value on one slot and from the node linked into Base Color on the other."""
    scene = clean_file.scene
    add_camera(scene)
    sphere = add_sphere()
    sphere.data.materials.append(new_material("Plain", color=(0.2, 0.5, 0.8, 1.0)))
    linked = new_material("Linked")
    rgb = linked.node_tree.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.9, 0.3, 0.1, 1.0)
    bsdf = linked.node_tree.nodes["Principled BSDF"]
    linked.node_tree.links.new(rgb.outputs[0], bsdf.inputs["Base Color"])
    sphere.data.materials.append(linked)
    for poly in sphere.data.polygons:
        poly.material_index = int(poly.center.x > 0)
    white = halves_map("white", (1.0, 1.0, 1.0), (1.0, 1.0, 1.0))
    shading.attach(sphere, white, "MODULATE", strength=1.0)
    size = (64, 64)
    pixels = render(scene, tmp_path, size=size)
    # Screen-left is world -X (camera looks along +Y): slot 0 there, slot 1 on the right.
    assert pixels[32, 20] == pytest.approx((0.2, 0.5, 0.8), abs=2e-3)
    assert pixels[32, 44] == pytest.approx((0.9, 0.3, 0.1), abs=2e-3)


def test_mix_is_the_original_surface_at_zero_strength(shading, clean_file, tmp_path):
    scene = clean_file.scene
    add_camera(scene)
    sphere = add_sphere()
    sphere.data.materials.append(new_material("Glow"))
    tree = sphere.data.materials[0].node_tree
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (0.3, 0.6, 0.2, 1.0)
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    image = halves_map("map", RED, BLUE)
    size = (64, 64)
    original = render(scene, tmp_path, size=size)
    shading.attach(sphere, image, "MIX", strength=0.0)
    assert render(scene, tmp_path, size=size) == pytest.approx(original, abs=1e-4)
    shading.attach(sphere, image, "MIX", strength=1.0, ior=1.45)  # attaching again re-attaches
    mixed = render(scene, tmp_path, size=size)
    # Fresnel: little reflection facing the camera, mostly reflection at grazing angles.
    assert mixed[32, 32] == pytest.approx(original[32, 32], abs=0.05)
    assert np.abs(mixed - original).max() > 0.2
    shading.detach(sphere)
    assert vr_leftovers() == []


def test_object_without_material_gets_one_and_loses_it_again(shading, clean_file, tmp_path):
    scene = clean_file.scene
    add_camera(scene)
    sphere = add_sphere()
    other = add_sphere("Other", location=(3.0, 0.0, 0.0), mesh=sphere.data)
    image = halves_map("map", RED, BLUE)
    before = snapshot(shading, scene, [sphere, other])
    shading.attach(sphere, image, "REPLACE")
    assert [s.link for s in sphere.material_slots] == ["OBJECT"]
    assert sphere.material_slots[0].material.get("vr_created") == "material"
    assert other.material_slots[0].material is None  # the data's new slot stays empty
    size = (64, 64)
    assert_left_red_right_blue(scene, sphere, render(scene, tmp_path, size=size), size)
    shading.detach(sphere)
    assert len(sphere.material_slots) == len(other.material_slots) == 0
    assert snapshot(shading, scene, [sphere, other]) == before
    assert vr_leftovers() == []


def test_shared_mesh_only_the_target_changes(shading, clean_file):
    scene = clean_file.scene
    add_camera(scene)
    target = add_sphere("Target")
    target.data.materials.append(new_material("Paint"))
    bystander = add_sphere("Bystander", location=(3.0, 0.0, 0.0), mesh=target.data)
    image = halves_map("map", RED, BLUE)
    before = snapshot(shading, scene, [target, bystander])
    shading.attach(target, image, "MODULATE")
    during = snapshot(shading, scene, [target, bystander])
    assert during["objects"]["Bystander"] == before["objects"]["Bystander"]
    assert during["meshes"] == before["meshes"]
    assert during["materials"]["Paint"] == before["materials"]["Paint"]
    assert target.material_slots[0].material.name == "Paint [VR Target]"
    assert bystander.material_slots[0].material.name == "Paint"
    shading.detach(target)
    assert snapshot(shading, scene, [target, bystander]) == before
    assert vr_leftovers() == []


def test_world_follows_the_camera_and_restores(world, clean_file, tmp_path):
    """The VR World's background is the map along the view direction in the scene camera's
    frame (drivers, not Vector Transform): the front half of a quadrant map fills the render's
    quadrants for any camera pose, set before or after attaching."""
    scene = clean_file.scene
    cam = add_camera(scene, lens=20)
    user_world = bpy.data.worlds.new("Studio")
    scene.world = user_world
    h, w = 64, 128
    rgb = np.zeros((h, w, 3), np.float32)
    rgb[: h // 2, : w // 2] = RED
    rgb[: h // 2, w // 2 :] = BLUE
    rgb[h // 2 :, : w // 2] = GREEN
    rgb[h // 2 :, w // 2 :] = MAGENTA
    rgb[:, : w // 4] = rgb[:, 3 * w // 4 :] = (0.0, 1.0, 1.0)  # behind the camera: never seen
    world.attach_world(scene, map_image("quadrants", rgb), strength=1.0)
    assert scene.world.name == world.WORLD_NAME
    size = (32, 32)
    for location, roll in [((0.0, -4.0, 0.0), 0.0), ((2.0, 3.0, 1.0), 0.7)]:
        aim(cam, location, (0.3, -0.2, 0.5), roll)
        pixels = render(scene, tmp_path, size=size, samples=1)
        for (ys, xs), colour in [
            ((slice(2, 13), slice(2, 13)), RED),
            ((slice(2, 13), slice(19, 30)), BLUE),
            ((slice(19, 30), slice(2, 13)), GREEN),
            ((slice(19, 30), slice(19, 30)), MAGENTA),
        ]:
            assert pixels[ys, xs].reshape(-1, 3) == pytest.approx(
                np.broadcast_to(colour, (11 * 11, 3)), abs=1e-3
            )
    world.detach_world(scene)
    assert scene.world == user_world
    assert vr_leftovers() == []
    assert world.WORLD_NAME not in bpy.data.worlds


def test_objects_in_world_mode_share_one_world(shading, clean_file):
    scene = clean_file.scene
    add_camera(scene)
    user_world = bpy.data.worlds.new("Studio")
    scene.world = user_world
    first, second = add_sphere("First"), add_sphere("Second", location=(3.0, 0.0, 0.0))
    image_a, image_b = halves_map("a", RED, BLUE), halves_map("b", GREEN, MAGENTA)
    shading.attach(first, image_a, "WORLD")
    world = scene.world
    shading.attach(second, image_b, "WORLD", strength=2.0)
    assert scene.world == world and len(bpy.data.worlds) == 2  # Studio + one VR World
    assert world.node_tree.nodes["VR Environment"].image == image_b
    shading.detach(first)
    assert scene.world == world  # still used by the second object
    shading.detach(second)
    assert scene.world == user_world
    assert vr_leftovers() == []


# --- refusals ---------------------------------------------------------------------------------


def test_linked_data_is_refused_before_anything_changes(shading, clean_file, tmp_path):
    library = tmp_path / "library.blend"
    lib_mesh = bpy.data.meshes.new("LibMesh")
    lib_mat = new_material("LibMat")
    lib_mesh.materials.append(lib_mat)
    lib_obj = bpy.data.objects.new("LibObj", lib_mesh)
    bare_mesh = bpy.data.meshes.new("BareMesh")
    bpy.data.libraries.write(str(library), {lib_obj, lib_mesh, lib_mat, bare_mesh})
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    with bpy.data.libraries.load(str(library), link=True) as (data_from, data_to):
        data_to.objects = ["LibObj"]
        data_to.materials = ["LibMat"]
        data_to.meshes = ["BareMesh"]
    linked_obj = data_to.objects[0]
    scene.collection.objects.link(linked_obj)
    local_with_linked_mat = add_sphere("LocalLinkedMat")
    local_with_linked_mat.data.materials.append(data_to.materials[0])
    local_with_linked_mesh = add_sphere("LocalLinkedMesh", mesh=data_to.meshes[0])
    image = halves_map("map", RED, BLUE)
    objects = [linked_obj, local_with_linked_mat, local_with_linked_mesh]
    before = snapshot(shading, scene, objects[1:])
    for obj, words in [
        (linked_obj, "object 'LibObj' is linked .*Object > Library Override > Make"),
        (local_with_linked_mesh, "data 'BareMesh'"),
    ]:
        with pytest.raises(ValueError, match=words):
            shading.attach(obj, image, "REPLACE")
        assert not shading.is_attached(obj)
    assert snapshot(shading, scene, objects[1:]) == before
    assert vr_leftovers() == []
    # A linked material is copied onto the object, never edited (issue 40: a library
    # override's materials are the library's); detach gives the slot back.
    lib_mat = data_to.materials[0]
    colour = tuple(lib_mat.diffuse_color)
    shading.attach(local_with_linked_mat, image, "REPLACE")
    slot = local_with_linked_mat.material_slots[0]
    assert slot.link == "OBJECT" and slot.material.library is None
    assert lib_mat.library is not None and tuple(lib_mat.diffuse_color) == colour
    shading.detach(local_with_linked_mat)
    assert snapshot(shading, scene, objects[1:]) == before
    assert vr_leftovers() == []


def test_bad_arguments(shading, clean_file):
    sphere = add_sphere()
    image = halves_map("map", RED, BLUE)
    with pytest.raises(ValueError, match="mode"):
        shading.attach(sphere, image, "ADD")
    with pytest.raises(TypeError):
        shading.attach(sphere, "map", "REPLACE")
    empty = bpy.data.objects.new("Empty", None)
    clean_file.scene.collection.objects.link(empty)
    with pytest.raises(ValueError, match="cannot hold materials"):
        shading.attach(empty, image, "REPLACE")
    shading.detach(sphere)  # detaching what was never attached is a no-op
    assert vr_leftovers() == []


def test_node_tree_signature_sees_changes(shading, clean_file):
    mat = new_material("M")
    sig = node_tree_signature(mat.node_tree)
    assert node_tree_signature(mat.copy().node_tree) == sig
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.123
    changed = node_tree_signature(mat.node_tree)
    assert changed != sig
    link = mat.node_tree.nodes["Material Output"].inputs["Surface"].links[0]
    mat.node_tree.links.remove(link)
    assert node_tree_signature(mat.node_tree) != changed
