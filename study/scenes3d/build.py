"""A `Scene3D` description as a Blender scene (bpy): dome, textured ground, neighbours, camera
and subject; and the worlds the baselines light the subject with.

Works on bpy 4.2+ and 5.x: node trees are switched on only where a datablock has none (5.x
always has one and deprecates `use_nodes`); Cycles only.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import pathlib
import sys

import bpy
import numpy as np

from .. import polyhaven
from .scenes import ASPECT, SENSOR_MM, Scene3D

bmesh = importlib.import_module("bmesh")  # importable only once bpy is

ROOT = pathlib.Path(__file__).resolve().parents[2]


def build_scenes():
    """sample_scenes/build_scenes.py (not a package), imported once under a private name."""
    name = "vr_scenes3d_build_scenes"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            name, ROOT / "sample_scenes" / "build_scenes.py"
        )
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def hdri_path(name: str) -> pathlib.Path:
    """A scene's dome: one of Blender's bundled HDRIs, or a Poly Haven one (`polyhaven.PREFIX`)."""
    if name.startswith(polyhaven.PREFIX):
        return polyhaven.path(name)
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    return pathlib.Path(folder) / f"{name}.exr"


def _node_tree(datablock):
    if datablock.node_tree is None:  # 4.x; 5.x datablocks always have nodes
        datablock.use_nodes = True
    return datablock.node_tree


# --- worlds -------------------------------------------------------------------------------------


def _new_world(name):
    world = bpy.data.worlds.new(name)
    tree = _node_tree(world)
    tree.nodes.clear()
    background = tree.nodes.new("ShaderNodeBackground")
    output = tree.nodes.new("ShaderNodeOutputWorld")
    tree.links.new(background.outputs["Background"], output.inputs["Surface"])
    return world, tree, background


def _mapped_environment(tree, background, image, rotations):
    """An Environment Texture of ``image`` looked up along the view direction turned by the
    Euler rotations ``rotations`` (radians, applied in order, each its own Mapping node)."""
    coords = tree.nodes.new("ShaderNodeTexCoord")
    socket = coords.outputs["Generated"]  # for a world: the view direction, world frame
    for rotation in rotations:
        mapping = tree.nodes.new("ShaderNodeMapping")
        mapping.vector_type = "VECTOR"
        mapping.inputs["Rotation"].default_value = rotation
        tree.links.new(socket, mapping.inputs["Vector"])
        socket = mapping.outputs["Vector"]
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    env.interpolation = "Linear"
    tree.links.new(socket, env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    return env


def dome_world(spec: Scene3D):
    """The HDRI at infinity, turned by the scene's rotation about +Z."""
    world, tree, background = _new_world(f"Dome {spec.hdri}")
    image = bpy.data.images.load(str(hdri_path(spec.hdri)), check_existing=True)
    _mapped_environment(tree, background, image, [(0.0, 0.0, math.radians(spec.hdri_rotation_deg))])
    return world


def mean_world(colour):
    world, _, background = _new_world("Plate Mean")
    background.inputs["Color"].default_value = (*map(float, colour), 1.0)
    world.cycles.sampling_method = "NONE"
    return world


def stretched_world(plate_image, spec: Scene3D):
    """The plate stretched over the whole sphere (360 x 180 degrees), its centre toward the
    camera's view direction, upright. Blender's equirectangular lookup puts u = 0.5 (the
    plate's centre column) on +X and v = 0.5 on the horizon; the view direction (heading +Y,
    pitched down) is turned onto +X by Rz(-90 deg), then Ry(-pitch)."""
    world, tree, background = _new_world("Plate Stretched")
    _mapped_environment(
        tree,
        background,
        plate_image,
        [(0.0, 0.0, -math.pi / 2), (0.0, -math.radians(spec.pitch_deg), 0.0)],
    )
    return world


# --- geometry -----------------------------------------------------------------------------------


def _object(scene, name, bm):
    return build_scenes().bmesh_object(scene, name, bm)


def _box(scene, name, size):
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    for v in bm.verts:
        v.co.x *= size[0]
        v.co.y *= size[1]
        v.co.z = (v.co.z + 0.5) * size[2]
    return _object(scene, name, bm)


def _torus(scene, name, size, segments=96, rings=32):
    """A ring standing on its rim (axis along Y), outer diameter ``size``."""
    outer = size / 2
    r = 0.3 * outer
    big = outer - r
    u = np.linspace(0, 2 * math.pi, segments, endpoint=False)[:, None]
    v = np.linspace(0, 2 * math.pi, rings, endpoint=False)[None, :]
    x = (big + r * np.cos(v)) * np.cos(u)
    z = (big + r * np.cos(v)) * np.sin(u) + outer
    y = r * np.sin(v) + 0 * u
    verts = np.stack([x, y, z], -1).reshape(-1, 3)
    faces = [
        (
            i * rings + j,
            ((i + 1) % segments) * rings + j,
            ((i + 1) % segments) * rings + (j + 1) % rings,
            i * rings + (j + 1) % rings,
        )
        for i in range(segments)
        for j in range(rings)
    ]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts.tolist(), [], faces)
    mesh.update()
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def _suzanne(scene, name, size):
    bm = bmesh.new()
    bmesh.ops.create_monkey(bm)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True, smooth=0.5)
    co = np.array([v.co for v in bm.verts])
    scale = size / float((co.max(0) - co.min(0)).max())
    for v in bm.verts:
        v.co = v.co * scale
    low = min(v.co.z for v in bm.verts)
    for v in bm.verts:
        v.co.z -= low
    for face in bm.faces:
        face.smooth = True
    return _object(scene, name, bm)


def make_shape(scene, name, shape, size, material):
    """A sphere, torus, Suzanne or the car, ``size`` across, standing on z = 0 at the origin."""
    b = build_scenes()
    if shape == "sphere":
        obj = b.make_sphere(scene, name, size / 2)
    elif shape == "torus":
        obj = _torus(scene, name, size)
    elif shape == "suzanne":
        obj = _suzanne(scene, name, size)
    elif shape == "car":
        obj = b.make_car(scene, name, [material] * 4)
        obj.scale = (size / 4.1,) * 3
    else:
        raise ValueError(f"unknown shape {shape!r}")
    if not obj.data.materials:
        obj.data.materials.append(material)
    return obj


def make_subject(scene, spec: Scene3D, material):
    obj = make_shape(scene, "Subject", spec.shape, spec.size, material)
    sx, sy = spec.subject_xy
    obj.location = (sx, sy, spec.lift)
    obj.rotation_euler = (0.0, 0.0, math.radians(spec.subject_yaw_deg))
    return obj


def add_companions(scene, spec: Scene3D, material) -> list:
    """The other mirror objects of an inter-reflection case ("Mirror 2", "Mirror 3", ...), with
    the subject's material."""
    objects = []
    for i, c in enumerate(spec.companions):
        obj = make_shape(scene, f"Mirror {i + 2}", c.shape, c.size, material)
        obj.location = (c.x, c.y, spec.lift)
        obj.rotation_euler = (0.0, 0.0, math.radians(c.yaw_deg))
        objects.append(obj)
    return objects


def ground_material(spec: Scene3D):
    material = bpy.data.materials.new("Ground")
    tree = _node_tree(material)
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Roughness"].default_value = 0.85
    coords = tree.nodes.new("ShaderNodeTexCoord")
    a, b = ((*c, 1.0) for c in spec.ground_colours)
    if spec.ground == "checker":
        tex = tree.nodes.new("ShaderNodeTexChecker")
        tex.inputs["Color1"].default_value, tex.inputs["Color2"].default_value = a, b
        tex.inputs["Scale"].default_value = spec.ground_scale
        colour = tex.outputs["Color"]
    elif spec.ground == "brick":
        tex = tree.nodes.new("ShaderNodeTexBrick")
        tex.inputs["Color1"].default_value, tex.inputs["Color2"].default_value = a, b
        tex.inputs["Mortar"].default_value = (0.6, 0.6, 0.58, 1.0)
        tex.inputs["Scale"].default_value = spec.ground_scale
        colour = tex.outputs["Color"]
    else:
        tex = tree.nodes.new("ShaderNodeTexNoise")
        tex.inputs["Scale"].default_value = spec.ground_scale
        tex.inputs["Detail"].default_value = 6.0
        ramp = tree.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position, ramp.color_ramp.elements[1].position = 0.35, 0.65
        ramp.color_ramp.elements[0].color, ramp.color_ramp.elements[1].color = b, a
        tree.links.new(tex.outputs["Fac"], ramp.inputs["Fac"])
        colour = ramp.outputs["Color"]
    tree.links.new(coords.outputs["Object"], tex.inputs["Vector"])
    tree.links.new(colour, bsdf.inputs["Base Color"])
    return material


def add_ground(scene, spec: Scene3D, half=150.0):
    bm = bmesh.new()
    verts = [
        bm.verts.new((x, y, 0.0))
        for x, y in ((-half, -half), (half, -half), (half, half), (-half, half))
    ]
    bm.faces.new(verts)
    ground = _object(scene, "Ground", bm)
    ground.data.materials.append(ground_material(spec))
    return ground


def add_camera(scene, spec: Scene3D):
    data = bpy.data.cameras.new("Camera")
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = SENSOR_MM
    data.lens = spec.lens_mm
    data.clip_start, data.clip_end = 0.05, 1000.0
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    camera.location = (0.0, 0.0, spec.camera_height)
    camera.rotation_euler = (math.radians(90.0 - spec.pitch_deg), 0.0, 0.0)
    scene.camera = camera
    return camera


def subject_material(name="Subject", roughness=0.0):
    material = build_scenes().principled(name, (1.0, 1.0, 1.0), metallic=1.0, roughness=roughness)
    return material


def set_roughness(material, roughness):
    bsdf = next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Roughness"].default_value = roughness
    material.roughness = roughness


def build(spec: Scene3D, width: int, samples: int):
    """The scene into the current (empty) file. Returns (scene, camera, subject, others,
    dome world, subject material)."""
    scene = bpy.context.scene
    b = build_scenes()
    b.quick_render_settings(scene, width, round(width / ASPECT), scale=100, samples=samples)
    scene.cycles.diffuse_bounces = 2
    scene.cycles.glossy_bounces = 3
    scene.cycles.max_bounces = 4
    camera = add_camera(scene, spec)
    others = [add_ground(scene, spec)]
    for i, n in enumerate(spec.neighbours):
        box = _box(scene, f"Neighbour {i} ({n.role})", n.size)
        box.location = (n.x, n.y, 0.0)
        box.rotation_euler = (0.0, 0.0, math.radians(n.yaw_deg))
        box.data.materials.append(b.principled(f"Neighbour {i}", n.colour, roughness=0.6))
        others.append(box)
    material = subject_material()
    subject = make_subject(scene, spec, material)
    world = dome_world(spec)
    scene.world = world
    scene.frame_set(1)
    return scene, camera, subject, others, world, material
