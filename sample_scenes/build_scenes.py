"""The paper's examples (§4) as Blender scenes over a sample plate, quick to render.

    .venv/bin/python sample_scenes/build_scenes.py [--scene spheres|fig10|car|all]
        [--plate courtyard|city|sunset|PATH] [--out DIR] [--scale 50] [--samples 16]

writes ``DIR/<scene>_<plate>.blend`` (default DIR: ``out/scenes``); the plate is referenced
by a relative path. From a script, `build` puts a scene into the current file:

    built = build_scenes.build("spheres", "courtyard")   # -> Built(scene, camera, objects, ...)

Scenes (the objects stand on the plate's ground, each marked to reflect the plate):

- ``spheres``: a chrome sphere (Fig. 10 b), combine REPLACE; the main sample.
- ``fig10``: a cube, a sphere and a teapot-like lathe body with a handle and a spout
  (Fig. 10 a-c: the more curved the surface, the more convincing the reflection), REPLACE.
- ``car``: a low car-like body in red paint with glass, tyres and hub caps (Fig. 7),
  combine MODULATE (the paint colour times the map).

The camera is the plate's (its ``.json``: Euler XYZ rotation, lens and sensor width, sensor
fit, plate size), so the render lines up with the plate pixel for pixel. Objects are placed
where a plate pixel sees the ground: a ray through the pixel meets the plane ``z = -height``
(the camera is at the origin; heights were read off each plate, below). An optional Cycles
shadow catcher under them is the ground. The world is a vertical gradient between the
plate's mean colours below and above the horizon: what lights the objects and their contact
shadows when there are no reflections, never what the chrome reflects (that is the point of
the comparison).

Render settings are small on purpose: Cycles on the CPU, 16 samples, OpenImageDenoise when
the build has it, a few light bounces, the plate's size at ``scale`` percent, the "Standard"
view transform (so the composite's background is the plate's own pixels) and a transparent
film to composite over the plate.

bpy only (no add-on needed); when the Virtual Reflections add-on is registered, the scene's
plate and combine mode are set and the objects are marked for it.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import pathlib
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Euler, Matrix, Vector

bmesh = importlib.import_module("bmesh")  # importable only once bpy is

HERE = pathlib.Path(__file__).resolve().parent
PLATES_DIR = HERE / "plates"
PLATES = ("courtyard", "city", "sunset")
SCENES = ("spheres", "fig10", "car")
COMBINE = {"spheres": "REPLACE", "fig10": "REPLACE", "car": "MODULATE"}

# Camera height above the ground (m), read off each plate: courtyard from the wheelie bin
# (~1.07 m tall, base 11.9° and top 2.6° below the horizon), sunset from the people (heads on
# the horizon), city from the painted arrow's width (~0.5 m); other plates get DEFAULT_HEIGHT.
CAMERA_HEIGHT = {"courtyard": 1.35, "city": 1.6, "sunset": 1.7}
DEFAULT_HEIGHT = 1.6

# Where each object stands: (name, plate x, plate y of its ground contact, as fractions of the
# plate's size (origin top-left, y down), yaw in degrees relative to the camera's heading).
LAYOUTS = {
    "spheres": (("Chrome Sphere", 0.5, 0.8, 0.0),),
    "fig10": (
        ("Cube", 0.2, 0.8, 35.0),
        ("Sphere", 0.5, 0.82, 0.0),
        ("Teapot", 0.8, 0.8, -30.0),
    ),
    "car": (("Car", 0.5, 0.70, 215.0),),
}
# Plate-specific places where the default would stand behind something the plate has in
# front of it (sunset: the mooring bollard at the bottom centre).
LAYOUT_OVERRIDES = {
    ("spheres", "sunset"): (("Chrome Sphere", 0.36, 0.68, 0.0),),
    ("fig10", "sunset"): (
        ("Cube", 0.1, 0.72, 35.0),
        ("Sphere", 0.36, 0.64, 0.0),
        ("Teapot", 0.27, 0.88, -30.0),
    ),
    ("car", "sunset"): (("Car", 0.25, 0.66, 215.0),),
}


@dataclass
class Built:
    """What `build` made. ``objects``: the objects that get reflections (not the ground)."""

    scene: object
    camera: object
    objects: list
    ground: object | None
    plate_image: object
    plate_path: str
    combine: str
    camera_json: dict = field(repr=False, default_factory=dict)


# --- plates -------------------------------------------------------------------------------------


def plate_files(plate) -> tuple[pathlib.Path, pathlib.Path]:
    """(image, json) of a plate: a sample plate's name (its linear .exr) or an image path
    with a .json of the same stem beside it. Raises ValueError naming what is missing."""
    plate = str(plate)
    if plate in PLATES:
        image = PLATES_DIR / f"{plate}.exr"
    else:
        image = pathlib.Path(plate).expanduser().resolve()
    info = image.with_suffix(".json")
    if not image.is_file():
        raise ValueError(f"plate image not found: {image}")
    if not info.is_file():
        raise ValueError(f"plate camera not found: {info} (the plate's .json)")
    return image, info


def plate_height(plate) -> float:
    return CAMERA_HEIGHT.get(pathlib.Path(str(plate)).stem, DEFAULT_HEIGHT)


def load_plate_image(path):
    image = bpy.data.images.load(str(path), check_existing=True)
    if image.size[0] == 0:
        raise ValueError(f"Blender cannot read the plate {path}")
    return image


def mean_colours(image, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean scene-linear colour of the plate above and below the row at ``horizon`` (a
    fraction of its height, y down).

    Float images are scene-linear as Blender loaded them; byte images hold sRGB codes / 255
    (decoded here). Returns two (3,) float arrays, sky and ground."""
    w, h = image.size
    buf = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(buf)
    rgb = buf.reshape(h, w, image.channels)[::-1, :, :3]  # Blender rows are bottom-up
    if not image.is_float:
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    row = int(min(max(horizon * h, 1), h - 1))
    sky, ground = rgb[:row].mean(axis=(0, 1)), rgb[row:].mean(axis=(0, 1))
    return np.nan_to_num(sky), np.nan_to_num(ground)


# --- camera and ground --------------------------------------------------------------------------


def add_plate_camera(scene, camera_json: dict):
    """The camera that sees the plate (as tests/blender/test_plate_camera.py sets it up)."""
    data = bpy.data.cameras.new("Plate Camera")
    data.type = "PERSP"
    data.sensor_fit = camera_json.get("sensor_fit", "HORIZONTAL")
    data.sensor_width = camera_json.get("sensor_width_mm", 36.0)
    if "lens_mm" in camera_json:
        data.lens = camera_json["lens_mm"]
    else:
        hfov = math.radians(camera_json["hfov_deg"])
        data.lens = data.sensor_width / 2 / math.tan(hfov / 2)
    data.shift_x = data.shift_y = 0.0
    data.clip_start, data.clip_end = 0.05, 500.0
    camera = bpy.data.objects.new("Plate Camera", data)
    scene.collection.objects.link(camera)
    camera.location = camera_json.get("camera_location", (0.0, 0.0, 0.0))
    camera.rotation_mode = camera_json.get("rotation_mode", "XYZ")
    camera.rotation_euler = camera_json["camera_rotation_euler"]
    scene.camera = camera
    return camera


def _camera_matrix(camera_json: dict) -> Matrix:
    euler = Euler(camera_json["camera_rotation_euler"], camera_json.get("rotation_mode", "XYZ"))
    location = Vector(camera_json.get("camera_location", (0.0, 0.0, 0.0)))
    return Matrix.Translation(location) @ euler.to_matrix().to_4x4()


def _half_frame(camera_json: dict) -> tuple[float, float]:
    """Half the frame's width and height on the plane one unit in front of the camera."""
    w, h = camera_json["width"], camera_json["height"]
    half = camera_json.get("sensor_width_mm", 36.0) / 2 / camera_json["lens_mm"]
    fit = camera_json.get("sensor_fit", "HORIZONTAL")
    if fit == "VERTICAL" or (fit == "AUTO" and h > w):
        return half * w / h, half
    return half, half * h / w


def pixel_ray(camera_json: dict, fx: float, fy: float) -> tuple[Vector, Vector]:
    """(origin, direction) in world space of the ray through plate position
    (fx * W, fy * H) (fractions of the plate, origin top-left, y down)."""
    half_w, half_h = _half_frame(camera_json)
    local = Vector(((2 * fx - 1) * half_w, (1 - 2 * fy) * half_h, -1.0))  # camera looks down -Z
    matrix = _camera_matrix(camera_json)
    return matrix.to_translation(), (matrix.to_3x3() @ local).normalized()


def ground_point(camera_json: dict, fx: float, fy: float, height: float) -> Vector:
    """Where the ray through plate position (fx, fy) meets the ground ``z = camera z - height``.
    Raises ValueError for a position at or above the horizon."""
    origin, direction = pixel_ray(camera_json, fx, fy)
    if direction.z > -1e-3:
        raise ValueError(f"plate position ({fx:.2f}, {fy:.2f}) is not on the ground")
    return origin + direction * (-height / direction.z)


def horizon_row(camera_json: dict) -> float:
    """Where the horizon crosses the plate's centre column, as a fraction of its height (y
    down; outside 0..1 when the camera looks steeply up or down)."""
    _, forward = pixel_ray(camera_json, 0.5, 0.5)
    pitch = math.asin(max(-1.0, min(1.0, forward.z)))  # negative: looking down
    return 0.5 + math.tan(pitch) / (2 * _half_frame(camera_json)[1])


def camera_heading(camera_json: dict) -> float:
    """The camera's viewing direction on the ground plane, radians from world +X."""
    forward = _camera_matrix(camera_json).to_3x3() @ Vector((0.0, 0.0, -1.0))
    return math.atan2(forward.y, forward.x)


# --- meshes -------------------------------------------------------------------------------------


def _mesh_object(scene, name, vertices, faces, *, smooth=True):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(vertices, dtype=float).tolist(), [], [list(f) for f in faces])
    mesh.update()
    mesh.validate()
    if smooth:
        mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def bmesh_object(scene, name, bm):
    """A mesh object from a bmesh (freed), linked into ``scene``."""
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def _catmull_rom(points, samples_per_segment=8):
    """A smooth curve through (N, D) points (closed ends held): (M, D) samples."""
    p = np.asarray(points, dtype=float)
    p = np.concatenate([p[:1], p, p[-1:]])
    t = np.linspace(0.0, 1.0, samples_per_segment, endpoint=False)[:, None]
    out = []
    for i in range(1, len(p) - 2):
        p0, p1, p2, p3 = p[i - 1], p[i], p[i + 1], p[i + 2]
        out.append(
            0.5
            * (
                2 * p1
                + (-p0 + p2) * t
                + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3
            )
        )
    out.append(p[-2:-1])
    return np.concatenate(out)


def lathe(profile, segments=64):
    """Surface of revolution about +Z of an (N, 2) profile of (radius, z), top to bottom or
    bottom to top; rows with radius 0 become single pole vertices. Returns (vertices, faces)."""
    profile = np.asarray(profile, dtype=float)
    angles = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    vertices, rows = [], []
    for r, z in profile:
        start = len(vertices)
        if r <= 1e-9:
            vertices.append((0.0, 0.0, z))
            rows.append([start] * segments)
        else:
            vertices.extend(zip(r * np.cos(angles), r * np.sin(angles), np.full(segments, z)))
            rows.append(list(range(start, start + segments)))
    faces = []
    for a, b in zip(rows[:-1], rows[1:]):
        for j in range(segments):
            k = (j + 1) % segments
            quad = [a[j], a[k], b[k], b[j]]
            unique = list(dict.fromkeys(quad))  # a pole row turns quads into triangles
            if len(unique) >= 3:
                faces.append(unique)
    return np.array(vertices), faces


def sweep(path, radii, segments=24):
    """A tube of circular cross-sections (``radii``, (N,)) along an (N, 3) path, with frames
    carried along the path (no twist). Ends open. Returns (vertices, faces)."""
    path = np.asarray(path, dtype=float)
    tangents = np.gradient(path, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    normal = np.cross(tangents[0], (0.0, 0.0, 1.0))
    if np.linalg.norm(normal) < 1e-6:
        normal = np.cross(tangents[0], (1.0, 0.0, 0.0))
    normal /= np.linalg.norm(normal)
    angles = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    vertices = []
    for i, (point, tangent) in enumerate(zip(path, tangents)):
        if i:  # parallel transport: remove the part of the last normal along the new tangent
            normal = normal - tangent * np.dot(normal, tangent)
            normal /= np.linalg.norm(normal)
        binormal = np.cross(tangent, normal)
        ring = np.cos(angles)[:, None] * normal + np.sin(angles)[:, None] * binormal
        vertices.append(point + radii[i] * ring)
    faces = [
        [i * segments + j, i * segments + (j + 1) % segments]
        + [(i + 1) * segments + (j + 1) % segments, (i + 1) * segments + j]
        for i in range(len(path) - 1)
        for j in range(segments)
    ]
    return np.concatenate(vertices), faces


def _join(parts):
    """[(vertices, faces)] -> one (vertices, faces)."""
    vertices, faces, offset = [], [], 0
    for v, f in parts:
        vertices.append(np.asarray(v, dtype=float))
        faces.extend([[i + offset for i in face] for face in f])
        offset += len(v)
    return np.concatenate(vertices), faces


def make_sphere(scene, name, radius):
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=radius)
    bmesh.ops.translate(bm, verts=bm.verts, vec=(0.0, 0.0, radius))  # stands on z = 0
    for face in bm.faces:
        face.smooth = True
    return bmesh_object(scene, name, bm)


def make_cube(scene, name, size):
    """A cube with slightly rounded edges, flat faces (planar faces show the map's structure)."""
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size)
    bmesh.ops.bevel(
        bm,
        geom=list(bm.edges) + list(bm.verts),
        offset=0.04 * size,
        segments=3,
        profile=0.5,
        affect="EDGES",
    )
    bmesh.ops.translate(bm, verts=bm.verts, vec=(0.0, 0.0, size / 2))
    for face in bm.faces:  # smooth only the rounded edges
        face.smooth = face.calc_area() < 0.5 * size * size
    return bmesh_object(scene, name, bm)


def make_teapot(scene, name, height):
    """A teapot-like body: a lathe profile (foot, belly, shoulder, lid, knob), a handle swept
    along an arc and a curved, tapering spout. Curved everywhere, as in Fig. 10 c."""
    s = height / 1.0  # the profile below is 1 unit tall
    profile = [  # (radius, z), bottom to top
        (0.0, 0.0),
        (0.42, 0.0),
        (0.50, 0.02),
        (0.62, 0.12),
        (0.70, 0.30),
        (0.69, 0.45),
        (0.60, 0.60),
        (0.46, 0.68),
        (0.40, 0.70),
        (0.40, 0.72),
        (0.36, 0.76),
        (0.24, 0.83),
        (0.10, 0.86),
        (0.08, 0.88),
        (0.12, 0.94),
        (0.08, 0.99),
        (0.0, 1.0),
    ]
    smooth = _catmull_rom(profile, samples_per_segment=6)
    smooth = np.maximum(smooth, 0.0)  # the spline overshoots a little at the foot
    body = lathe(smooth * s, segments=64)

    # handle: a C-shaped arc on the -X side, its ends buried in the body
    t = np.linspace(-0.62 * math.pi, 0.62 * math.pi, 40)
    handle_path = np.stack(
        [-0.62 - 0.26 * np.cos(t), np.zeros_like(t), 0.40 + 0.22 * np.sin(t)], axis=1
    )
    handle = sweep(handle_path * s, np.full(len(t), 0.045 * s), segments=20)

    # spout: from inside the belly up and out along +X, narrowing, its tip flared slightly
    control = [(0.45, 0.0, 0.25), (0.78, 0.0, 0.38), (0.95, 0.0, 0.62), (1.08, 0.0, 0.78)]
    spout_path = _catmull_rom(control, samples_per_segment=12)
    u = np.linspace(0.0, 1.0, len(spout_path))
    radii = (0.12 - 0.08 * u + 0.02 * np.clip((u - 0.9) / 0.1, 0, 1)) * s
    spout = sweep(spout_path * s, radii, segments=24)
    vertices, faces = _join([body, handle, spout])
    return _mesh_object(scene, name, vertices, faces)


def _bevelled_box(bm, size, centre, bevel, segments, material, top_scale=(1.0, 1.0)):
    """Add a box (size (x, y, z), centred at ``centre``) with rounded edges to ``bm``; its top
    face scaled by ``top_scale`` (a cabin's sloping windows). Returns its new faces."""
    before = set(bm.faces)
    result = bmesh.ops.create_cube(bm, size=1.0)
    verts = result["verts"]
    for v in verts:
        v.co = Vector((v.co.x * size[0], v.co.y * size[1], v.co.z * size[2]))
        if v.co.z > 0:
            v.co.x *= top_scale[0]
            v.co.y *= top_scale[1]
        v.co += Vector(centre)
    edges = list({e for v in verts for e in v.link_edges})
    bmesh.ops.bevel(
        bm, geom=edges + verts, offset=bevel, segments=segments, profile=0.5, affect="EDGES"
    )
    new = [f for f in bm.faces if f not in before]
    for face in new:
        face.material_index = material
        face.smooth = True
    return new


def _cylinder_y(bm, radius, width, centre, material, segments=32):
    """Add a cylinder along Y (a wheel) to ``bm``."""
    before = set(bm.faces)
    matrix = Matrix.Translation(centre) @ Matrix.Rotation(math.pi / 2, 4, "X")
    bmesh.ops.create_cone(
        bm,
        cap_ends=True,
        segments=segments,
        radius1=radius,
        radius2=radius,
        depth=width,
        matrix=matrix,
    )
    for face in set(bm.faces) - before:
        face.material_index = material
        face.smooth = len(face.verts) == 4  # the tread smooth, the caps flat


def make_car(scene, name, materials):
    """A low car-like body (Fig. 7): bevelled boxes for body and cabin, four wheels with hub
    caps. Local frame: +X forward, +Y left, z = 0 the ground. ``materials``: paint, glass,
    tyre, chrome."""
    paint, glass, tyre, chrome = range(4)
    length, width = 4.1, 1.76
    bm = bmesh.new()
    _bevelled_box(bm, (length, width, 0.62), (0.0, 0.0, 0.62), 0.16, 4, paint)
    _bevelled_box(bm, (2.1, 1.56, 0.50), (-0.25, 0.0, 1.14), 0.1, 3, glass, top_scale=(0.72, 0.9))
    for x in (1.3, -1.3):
        for side in (1.0, -1.0):
            y = side * (width / 2 - 0.08)
            _cylinder_y(bm, 0.33, 0.24, Vector((x, y, 0.33)), tyre)
            _cylinder_y(bm, 0.19, 0.03, Vector((x, y + side * 0.12, 0.33)), chrome, 24)
    obj = bmesh_object(scene, name, bm)
    for material in materials:
        obj.data.materials.append(material)
    return obj


# --- materials and world ------------------------------------------------------------------------


def principled(name, colour, metallic=0.0, roughness=0.5, coat=0.0):
    material = bpy.data.materials.new(name)
    if material.node_tree is None:  # 4.x; 5.x materials always have nodes
        material.use_nodes = True
    bsdf = next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Roughness"].default_value = roughness
    if coat and "Coat Weight" in bsdf.inputs:
        bsdf.inputs["Coat Weight"].default_value = coat
    material.diffuse_color = (*colour, 1.0)
    material.metallic, material.roughness = metallic, roughness
    # The reflection modes turn the surface into an emission (a copy of this material keeps
    # this setting): not sampled as a light, which would cost a light tree per render.
    material.cycles.emission_sampling = "NONE"
    return material


def gradient_world(scene, sky, ground, strength=1.0):
    """World: ``ground`` below the horizon blending into ``sky`` above (scene-linear)."""
    world = bpy.data.worlds.new("Plate Light")
    if world.node_tree is None:
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    coords = nodes.new("ShaderNodeTexCoord")  # Generated: the view direction, world frame
    xyz = nodes.new("ShaderNodeSeparateXYZ")
    blend = nodes.new("ShaderNodeMapRange")
    blend.inputs["From Min"].default_value = -0.15
    blend.inputs["From Max"].default_value = 0.6
    ramp = nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (*ground, 1.0)
    ramp.color_ramp.elements[1].color = (*sky, 1.0)
    background = nodes.new("ShaderNodeBackground")
    background.inputs["Strength"].default_value = strength
    output = nodes.new("ShaderNodeOutputWorld")
    links.new(coords.outputs["Generated"], xyz.inputs["Vector"])
    links.new(xyz.outputs["Z"], blend.inputs["Value"])
    links.new(blend.outputs["Result"], ramp.inputs["Fac"])
    links.new(ramp.outputs["Color"], background.inputs["Color"])
    links.new(background.outputs["Background"], output.inputs["Surface"])
    world.cycles.sampling_method = "NONE"  # smooth: no importance map to build (~1 s a render)
    scene.world = world
    return world


def add_ground(scene, centre, size=30.0):
    """A shadow-catcher plane on the ground: only the objects' shadows reach the composite."""
    half = size / 2
    x, y, z = centre
    vertices = [(x - half, y - half, z), (x + half, y - half, z)]
    vertices += [(x + half, y + half, z), (x - half, y + half, z)]
    ground = _mesh_object(scene, "Ground (Shadow Catcher)", vertices, [(0, 1, 2, 3)], smooth=False)
    ground.is_shadow_catcher = True
    ground.data.materials.append(principled("Ground", (0.18, 0.18, 0.18), roughness=0.9))
    return ground


# --- render settings ----------------------------------------------------------------------------


def has_oidn() -> bool:
    try:
        import _cycles
    except ImportError:  # pragma: no cover - Cycles is part of every bpy build we support
        return False
    return bool(getattr(_cycles, "with_openimagedenoise", False))


def quick_render_settings(scene, width, height, scale=50, samples=16, denoise=True):
    """Cycles on the CPU, few samples, few bounces: seconds per frame on two cores."""
    render = scene.render
    render.engine = "CYCLES"
    render.resolution_x, render.resolution_y = width, height
    render.resolution_percentage = scale
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.film_transparent = True
    render.use_persistent_data = False
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.preview_samples = min(samples, 16)
    cycles.use_adaptive_sampling = False
    cycles.seed = 0
    cycles.use_denoising = bool(denoise and has_oidn())
    if cycles.use_denoising:
        cycles.denoiser = "OPENIMAGEDENOISE"
        cycles.denoising_prefilter = "FAST"
    cycles.max_bounces = 3
    cycles.diffuse_bounces = 1
    cycles.glossy_bounces = 2  # chrome objects see each other (with one bounce: black)
    cycles.transmission_bounces = 1
    cycles.volume_bounces = 0
    cycles.transparent_max_bounces = 4
    cycles.caustics_reflective = cycles.caustics_refractive = False
    cycles.sample_clamp_indirect = 10.0
    view = scene.view_settings
    view.view_transform = "Standard"  # the composite's background is the plate's own pixels
    view.look = "None"
    view.exposure, view.gamma = 0.0, 1.0


# --- scenes -------------------------------------------------------------------------------------


def _place(obj, camera_json, fx, fy, yaw_deg, height):
    obj.location = ground_point(camera_json, fx, fy, height)
    obj.rotation_euler = (0.0, 0.0, camera_heading(camera_json) + math.radians(yaw_deg))


def _objects_for(kind, scene):
    """{name: object} for a scene kind, at the origin, standing on z = 0."""
    if kind == "spheres":
        chrome = principled("Chrome", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.05)
        sphere = make_sphere(scene, "Chrome Sphere", 0.36)
        sphere.data.materials.append(chrome)
        return {"Chrome Sphere": sphere}
    if kind == "fig10":
        chrome = principled("Chrome", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.05)
        objects = {
            "Cube": make_cube(scene, "Cube", 0.5),
            "Sphere": make_sphere(scene, "Sphere", 0.3),
            "Teapot": make_teapot(scene, "Teapot", 0.5),
        }
        for obj in objects.values():
            obj.data.materials.append(chrome)
        return objects
    if kind == "car":
        materials = (
            principled("Car Paint", (0.72, 0.06, 0.03), metallic=0.2, roughness=0.3, coat=1.0),
            principled("Car Glass", (0.22, 0.25, 0.28), roughness=0.05),
            principled("Car Tyre", (0.03, 0.03, 0.03), roughness=0.8),
            principled("Car Chrome", (0.85, 0.85, 0.85), metallic=1.0, roughness=0.1),
        )
        return {"Car": make_car(scene, "Car", materials)}
    raise ValueError(f"unknown scene {kind!r}; use one of {', '.join(SCENES)}")


def build(
    kind,
    plate="courtyard",
    *,
    scene=None,
    scale=50,
    samples=16,
    ground=True,
    size=None,
    denoise=True,
) -> Built:
    """Build scene ``kind`` ('spheres', 'fig10', 'car') over ``plate`` into ``scene`` (default:
    the current one), which should be empty. ``size`` (width, height) overrides the plate's
    render size (tests render tiny frames); ``ground`` adds the shadow catcher."""
    if kind not in SCENES:
        raise ValueError(f"unknown scene {kind!r}; use one of {', '.join(SCENES)}")
    scene = scene or bpy.context.scene
    image_path, json_path = plate_files(plate)
    camera_json = json.loads(json_path.read_text())
    for key in ("width", "height", "camera_rotation_euler"):
        if key not in camera_json:
            raise ValueError(f"{json_path} has no {key!r}")
    camera_json.setdefault(
        "lens_mm",
        camera_json.get("sensor_width_mm", 36.0)
        / 2
        / math.tan(math.radians(camera_json.get("hfov_deg", 60.0)) / 2),
    )
    height = plate_height(image_path)
    camera = add_plate_camera(scene, camera_json)
    image = load_plate_image(image_path)

    objects = _objects_for(kind, scene)
    layout = LAYOUT_OVERRIDES.get((kind, image_path.stem), LAYOUTS[kind])
    for name, fx, fy, yaw in layout:
        _place(objects[name], camera_json, fx, fy, yaw, height)
    ground_obj = None
    if ground:
        centre = sum((o.location for o in objects.values()), Vector()) / len(objects)
        ground_obj = add_ground(scene, (centre.x, centre.y, -height))

    sky, below = mean_colours(image, horizon_row(camera_json))
    gradient_world(scene, sky, below, strength=1.0)

    width, height_px = size or (camera_json["width"], camera_json["height"])
    quick_render_settings(scene, width, height_px, scale=scale, samples=samples, denoise=denoise)
    scene.frame_set(1)
    _set_up_addon(scene, image, kind, objects.values())
    return Built(
        scene=scene,
        camera=camera,
        objects=list(objects.values()),
        ground=ground_obj,
        plate_image=image,
        plate_path=str(image_path),
        combine=COMBINE[kind],
        camera_json=camera_json,
    )


def _set_up_addon(scene, image, kind, objects):
    """With the add-on registered: the plate, the combine mode, the objects marked."""
    settings = getattr(scene, "virtual_reflections", None)
    if settings is None:
        return
    settings.plate_image = image
    settings.combine = COMBINE[kind]
    for obj in objects:
        obj.virtual_reflections.enabled = True


# --- command line -------------------------------------------------------------------------------


def addon():
    """(package, registered_here): the Virtual Reflections package, registered -- the one
    already imported (an enabled extension, or a test's copy) or this checkout's, imported
    under a private name. Whoever gets ``registered_here`` True unregisters before the process
    ends: the bpy 4.5 module hangs at exit while an operator or panel class is registered."""
    import importlib.util
    import sys

    root = HERE.parent
    init = str(root / "__init__.py")
    module = next(
        (m for m in list(sys.modules.values()) if getattr(m, "__file__", None) == init), None
    )
    if module is None:
        spec = importlib.util.spec_from_file_location(
            "vr_sample_scenes_addon", init, submodule_search_locations=[str(root)]
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module
        spec.loader.exec_module(module)
    if hasattr(bpy.types.Scene, "virtual_reflections"):
        return module, False
    module.register()
    return module, True


def new_file():
    """An empty file (factory settings; extensions and registered add-ons stay)."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    return bpy.context.scene


def parse(argv=None):
    p = argparse.ArgumentParser(
        prog="build_scenes", description=__doc__.splitlines()[0], allow_abbrev=False
    )
    p.add_argument("--scene", choices=(*SCENES, "all"), default="all")
    p.add_argument("--plate", default="courtyard", help="courtyard, city, sunset or an image path")
    p.add_argument("--out", default=str(HERE.parent / "out" / "scenes"), help="output folder")
    p.add_argument("--scale", type=int, default=50, help="resolution percentage")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--no-ground", action="store_true", help="no shadow catcher")
    return p.parse_args(argv)


def main(argv=None):
    args = parse(argv)
    module, registered = addon()
    try:
        os.makedirs(args.out, exist_ok=True)
        kinds = SCENES if args.scene == "all" else (args.scene,)
        for kind in kinds:
            new_file()
            built = build(
                kind, args.plate, scale=args.scale, samples=args.samples, ground=not args.no_ground
            )
            stem = pathlib.Path(built.plate_path).stem
            path = os.path.abspath(os.path.join(args.out, f"{kind}_{stem}.blend"))
            bpy.ops.wm.save_as_mainfile(filepath=path, relative_remap=True)
            print(f"wrote {path}: {', '.join(o.name for o in built.objects)} ({built.combine})")
    finally:
        if registered:
            module.unregister()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
