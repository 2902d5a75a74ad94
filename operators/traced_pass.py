"""The ray-traced pass: the default look's objects seeing each other in one Cycles render.

The paper's passes (interreflect.py) rebuild each object's map from the previous composite,
which shows a neighbour as the camera saw it. Against a path-traced truth that brings Camera
View + Ground nothing (docs/scenes3d.md, Inter-reflections). In this pass, instead, every
reflective object is a real mirror for one render (of the look's colour: the strength in
Replace, the base colour times it in Modulate), and whatever a mirror's ray meets that is
not another object is read by the default's own lookup: the map along the ray, the ground where
the ray meets it read on the plate, darkened by every reflective object's contact shadow. The
lookup needs the ray's origin, which a world shader does not know; so it sits on a dome (a
sphere far around the scene, seen by glossy rays only) whose shader recovers the origin from
the hit point and the ray's length:

    origin = Position + Incoming * Ray Length,   direction = -Incoming

The ground is a plane at the ground's height with the same lookup (seen by glossy rays only):
the ground point is its shading point, where Cycles' Ambient Occlusion measures the sky the
objects' real shapes hide (their contact shadow, times the artist's strength). The material's
model, an ellipsoid in each object's bounding box, taken here with world-aligned boxes for
every object at once, turned the ground under and beside a torus nearly black where the real
ring hides little sky: its own rays meet it after bouncing off the torus itself (issue 41).

Blind to each other, the mirrors render the one-pass look (the dome reproduces the material's
lookup, the plane its ground with the real shapes' contact shadow); seeing each other, Cycles
adds every level of inter-reflection up to the scene's glossy bounces in one render.

It applies to Camera View + Ground in the Replace and Modulate looks under Cycles
(`applies`): Mix shades with the object's own surface (its mirror would need the material's
Fresnel mix) and the other methods' maps are each object's own (the paper's segmentation), so
they keep the paper's passes. Everything here is temporary:
the dome, the ground plane, their materials and the mirror materials are made for the render
and deleted after it, and every slot, visibility flag and bounce count put back (`traced`),
also on errors or Esc. While it renders, other glossy objects inside the reflective objects'
render border see the dome where they would see the world (and the plane where they would see
the ground), and what the mirrors show is indirect light to Cycles: the scene's Clamp
Indirect, when set, applies to it (a plate brighter than that shows dimmer in the mirrors than
in pass 1).
"""

import contextlib
import math

import bpy
from mathutils import Vector

from ..virtual_reflections import methods
from ..virtual_reflections.methods import WHOLE_SURFACE_LOOKS
from .node_trees import ground_nodes, reflection_nodes, shading
from .node_trees.nodes import math_node, new_node, vector_math_node, view_ray
from .scene import floor
from .scene.images import CREATED

DOME = "VR Traced Dome"
GROUND_PLANE = "VR Traced Ground"
MIRROR = "VR Traced Mirror"
AO_SAMPLES = 16  # Ambient Occlusion rays per shading of the ground plane
AO_REACH = 8.0  # the contact shadow's reach: this x the largest object's bounding radius
MIN_RADIUS = 1000.0  # m: the dome's radius at least, and 20 x the farthest object's distance
MIN_GLOSSY_BOUNCES = 4  # raised to this for the render when the scene has fewer
LOOKS = WHOLE_SURFACE_LOOKS  # the map is the whole surface: a mirror of its colour
# the dome is seen by glossy rays only: no camera, lighting, shadows, transmission or volumes
DOME_HIDDEN_FROM = (
    "visible_camera",
    "visible_diffuse",
    "visible_shadow",
    "visible_transmission",
    "visible_volume_scatter",
)


def applies(scene, objects) -> bool:
    """True when the ray-traced pass replaces the paper's passes for ``objects``: Cycles,
    Camera View + Ground, every object in the Replace or Modulate look with the ground read
    per point."""
    method = scene.virtual_reflections.method
    if scene.render.engine != "CYCLES" or not methods.reads_ground(method):
        return False
    return bool(objects) and all(
        shading.mode_of(obj) in LOOKS and _ground_node(_group(obj)) is not None for obj in objects
    )


def _group(obj):
    record = shading.record_of(obj)
    return record.get("group") if record is not None else None


def _ground_node(group):
    """The ground lookup node of a reflection group (None: no ground per point)."""
    if group is None:
        return None
    for node in group.nodes:
        tree = getattr(node, "node_tree", None)
        if node.bl_idname == "ShaderNodeGroup" and tree is not None:
            if tree.get(CREATED) == "ground":
                return node
    return None


def _ground_of(group):
    """The GroundLookup ``group`` was built with, read off its nodes."""
    lookup = _ground_node(group)
    plate = next(n for n in group.nodes if n.bl_idname == "ShaderNodeTexImage")
    frames = None
    if plate.image is not None and plate.image.source in ("SEQUENCE", "MOVIE"):
        user = plate.image_user
        frames = (user.frame_duration, user.frame_start, user.frame_offset, user.use_cyclic)
    value = lookup.inputs
    strength = group.nodes.get(ground_nodes.SHADOW_NODE)
    return ground_nodes.GroundLookup(
        plate.image,
        value["Height"].default_value,
        tuple(value["Focal"].default_value)[:2],
        tuple(value["Centre"].default_value)[:2],
        value["Aspect"].default_value,
        frames,
        strength.outputs[0].default_value if strength is not None else 1.0,
    )


def holds_out(obj) -> bool:
    """True when ``obj`` is a holdout in Cycles: flagged, or every material's Cycles output a
    Holdout shader."""
    if getattr(obj, "is_holdout", False):
        return True
    materials = [slot.material for slot in getattr(obj, "material_slots", ())]
    if not materials or None in materials:
        return False
    for material in materials:
        tree = material.node_tree
        output = tree.get_output_node("CYCLES") if tree is not None else None
        links = output.inputs["Surface"].links if output is not None else ()
        if not links or links[0].from_node.type != "HOLDOUT":
            return False
    return True


def _world_box(obj, origin):
    """(centre, half size) of ``obj``'s world-space bounding box (axis-aligned), the centre
    relative to ``origin``."""
    corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
    low = [min(c[i] for c in corners) for i in range(3)]
    high = [max(c[i] for c in corners) for i in range(3)]
    centre = tuple((a + b) / 2 - o for a, b, o in zip(low, high, origin))
    return centre, tuple((b - a) / 2 for a, b in zip(low, high))


def _dome_material(image, ground, boxes, occlusion=None, name=DOME):
    """Emission of the default's lookup along each ray that meets the dome, from its origin.
    ``boxes``: (centre, half size) of every reflective object in the dome's space, whose
    ellipsoids darken the ground (the material's model); or, with ``occlusion`` (metres), the
    ground darkened by the share of its sky the scene's real surfaces hide within that
    distance (Cycles' Ambient Occlusion at the shading point: the material of the ground
    plane, whose shading point is the ground point)."""
    material = bpy.data.materials.new(name)
    material[CREATED] = "traced dome" if name == DOME else "traced ground"
    if material.node_tree is None:  # 4.x; 5.x materials always have their tree
        material.use_nodes = True
    if hasattr(material, "cycles") and hasattr(material.cycles, "emission_sampling"):
        material.cycles.emission_sampling = "NONE"  # lights nothing: it is only seen
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    geometry, view = view_ray(nodes, links)  # the ray's direction: -Incoming
    path = new_node(nodes, "ShaderNodeLightPath", "Light Path", (-900, 0))
    back = vector_math_node(
        nodes, links, "SCALE", "Back To The Origin", (-700, 0),
        geometry.outputs["Incoming"], path.outputs["Ray Length"],
    )  # fmt: skip
    origin = vector_math_node(
        nodes, links, "ADD", "Ray Origin", (-500, 0), geometry.outputs["Position"], back
    )
    direction = view.outputs["Vector"]
    colour = reflection_nodes.env_lookup(nodes, links, direction, image, (-300, 300))
    sky = None
    if occlusion is not None:
        sky = _sky_left(nodes, links, occlusion, ground.shadow)
        boxes = ()
    total = ground_nodes.mix_ground(
        nodes, links, origin, direction, colour, ground, (0, 600), boxes, sky
    )
    emission = new_node(nodes, "ShaderNodeEmission", "Dome Emission", (800, 300))
    links.new(total, emission.inputs["Color"])
    output = new_node(nodes, "ShaderNodeOutputMaterial", "Output", (1000, 300))
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    return material


def _sky_left(nodes, links, distance, strength):
    """1 - k (1 - AO): the share of the shading point's sky the surfaces within ``distance``
    leave (Cycles' Ambient Occlusion, cosine weighted: an exact sphere's form factor as the
    material's model, but of the real shapes: a torus's hole lets the sky through), the
    hidden share times the contact shadow's strength k."""
    ao = new_node(nodes, "ShaderNodeAmbientOcclusion", "Contact Shadow (AO)", (-300, 900))
    ao.samples = AO_SAMPLES
    ao.inputs["Distance"].default_value = distance
    hidden = math_node(nodes, links, "SUBTRACT", "Sky Hidden", (-100, 900), 1.0, ao.outputs["AO"])
    hidden = math_node(nodes, links, "MULTIPLY", "Hidden x Strength", (50, 900), hidden, strength)
    return math_node(nodes, links, "SUBTRACT", "Sky Left", (200, 900), 1.0, hidden)


def _plane_mesh(half, height):
    """A square mesh of half size ``half`` at Z = ``height`` about the origin, facing up."""
    mesh = bpy.data.meshes.new(GROUND_PLANE)
    corners = [(-half, -half, height), (half, -half, height), (half, half, height),
               (-half, half, height)]  # fmt: skip
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.update()
    return mesh


def _sphere_mesh(radius):
    """A UV sphere mesh (64 x 32) of ``radius`` about its origin."""
    import bmesh  # Blender's own module, importable once bpy is

    mesh = bpy.data.meshes.new(DOME)
    bm = bmesh.new()
    try:
        bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=radius)
        bm.to_mesh(mesh)
    finally:
        bm.free()
    return mesh


def _input(socket):
    """What feeds ``socket``: the linked output, else its value (a colour without alpha)."""
    if socket.is_linked:
        return socket.links[0].from_socket
    value = socket.default_value
    return tuple(value)[:3] if hasattr(value, "__len__") else value


def _mirror_of(material):
    """A copy of ``material`` (a copy `shading.attach` made) with each reflection group node
    replaced by a perfect mirror of the look's colour: the strength (Replace), the base colour
    times the strength (Modulate). The map, then, is what the mirror meets on the dome."""
    mirror = material.copy()
    mirror.name = f"{MIRROR} [{material.name}]"
    mirror[CREATED] = "traced mirror"
    nodes, links = mirror.node_tree.nodes, mirror.node_tree.links
    for node in list(nodes):
        tree = getattr(node, "node_tree", None)
        if node.bl_idname != "ShaderNodeGroup" or tree is None or tree.get("vr_mode") not in LOOKS:
            continue
        x, y = node.location
        base = _input(node.inputs["Base Color"]) if "Base Color" in node.inputs else (1.0,) * 3
        colour = vector_math_node(
            nodes, links, "SCALE", "Mirror Colour", (x, y - 200), base,
            _input(node.inputs["Strength"]),
        )  # fmt: skip
        glossy = new_node(nodes, "ShaderNodeBsdfGlossy", "Mirror", (x + 200, y))
        glossy.inputs["Roughness"].default_value = 0.0
        links.new(colour, glossy.inputs["Color"])
        for link in list(node.outputs["Shader"].links):
            links.new(glossy.outputs["BSDF"], link.to_socket)
        nodes.remove(node)
    return mirror


@contextlib.contextmanager
def traced(scene, objects):
    """While inside: ``objects`` (with Generate's Replace or Modulate look, `applies`) are
    mirrors of the look's colour (`_mirror_of`), a dome around the scene gives every ray that
    meets nothing else the default's lookup, a plane at the ground gives it the ground, the
    scene's ground (`floor.ground_of`: the chosen object, or the floor under the objects),
    shadow catchers and holdouts are hidden from glossy and shadow rays (the dome and the
    plane read what the plate shows; the plane's Ambient Occlusion would meet them), and the
    glossy bounces
    are at least MIN_GLOSSY_BOUNCES. Everything is put back and what was made deleted on
    leaving."""
    group = _group(objects[0])
    image = shading.map_of(objects[0])
    ground = _ground_of(group)
    centre = scene.camera.matrix_world.translation.copy()
    far = max(
        (obj.matrix_world @ Vector(c) - centre).length for obj in objects for c in obj.bound_box
    )
    # before the plane below is made, which would be the floor under the objects
    ground_object = floor.ground_of(scene, bpy.context.evaluated_depsgraph_get(), objects)
    made = []  # datablocks to delete, last made first
    slots = []  # (slot, material) to put back
    flags = []  # (owner, attribute, value) to put back
    try:
        dome = _add_dome(scene, image, ground, objects, centre, far, made)
        _add_ground_plane(scene, image, ground, objects, centre, far, made)
        _mirror_materials(objects, made, slots)
        _hide_what_stands_for_the_plate(scene, objects, ground_object, flags)
        cycles = scene.cycles
        for attr in ("glossy_bounces", "max_bounces"):
            value = getattr(cycles, attr)
            if value < MIN_GLOSSY_BOUNCES:
                flags.append((cycles, attr, value))
                setattr(cycles, attr, MIN_GLOSSY_BOUNCES)
        yield dome
    finally:
        for slot, material in reversed(slots):
            slot.material = material
        for owner, attr, value in reversed(flags):
            setattr(owner, attr, value)
        for block in reversed(made):  # the dome object before its mesh and material
            if isinstance(block, bpy.types.Object):
                bpy.data.objects.remove(block)
            elif isinstance(block, bpy.types.Mesh):
                bpy.data.meshes.remove(block)
            else:
                bpy.data.materials.remove(block)


def _add_dome(scene, image, ground, objects, centre, far, made):
    """The dome about ``centre`` (far beyond the ``far``-thest object corner), linked to the
    scene and seen by glossy rays only: every ray that meets nothing else reads the default's
    lookup there. What it makes is appended to ``made``."""
    material = _dome_material(image, ground, [_world_box(o, centre) for o in objects])
    made.append(material)
    mesh = _sphere_mesh(max(MIN_RADIUS, 20.0 * far))
    made.append(mesh)
    mesh.materials.append(material)
    dome = bpy.data.objects.new(DOME, mesh)
    made.append(dome)
    dome.location = centre
    scene.collection.objects.link(dome)
    for attr in DOME_HIDDEN_FROM:
        setattr(dome, attr, False)
    return dome


def _add_ground_plane(scene, image, ground, objects, centre, far, made):
    """The ground, as a plane the mirrors' rays meet (seen by glossy rays only): its shading
    point is the ground point, where Cycles measures the sky the objects really hide. What it
    makes is appended to ``made``."""
    reach = max(math.sqrt(sum(h * h for h in _world_box(o, centre)[1])) for o in objects)
    plane_material = _dome_material(
        image, ground, (), occlusion=AO_REACH * reach, name=GROUND_PLANE
    )
    made.append(plane_material)
    plane_mesh = _plane_mesh(max(MIN_RADIUS, 20.0 * far), ground.height)
    made.append(plane_mesh)
    plane_mesh.materials.append(plane_material)
    plane = bpy.data.objects.new(GROUND_PLANE, plane_mesh)
    made.append(plane)
    plane.location = (centre.x, centre.y, 0.0)
    scene.collection.objects.link(plane)
    for attr in DOME_HIDDEN_FROM:
        setattr(plane, attr, False)


def _mirror_materials(objects, made, slots):
    """Each material copy of ``objects`` swapped for its mirror (`_mirror_of`, one per copy,
    appended to ``made``); each (slot, material) to put back appended to ``slots``."""
    mirrors = {}  # each material copy of the objects -> its mirror
    for obj in objects:
        for slot in obj.material_slots:
            if slot.material is None:
                continue
            if slot.material.name not in mirrors:
                mirrors[slot.material.name] = _mirror_of(slot.material)
                made.append(mirrors[slot.material.name])
            slots.append((slot, slot.material))
            slot.material = mirrors[slot.material.name]


def _hide_what_stands_for_the_plate(scene, objects, ground_object, flags):
    """The scene's ground (``ground_object``), shadow catchers and holdouts hidden from glossy
    and shadow rays; each (object, attribute, value) to put back appended to ``flags``."""
    ours = set(objects)
    for obj in scene.objects:
        if obj in ours:
            continue
        # The ground and shadow catchers would hide the plate's ground from the mirrors
        # and, standing where the plane is, from its Ambient Occlusion (shadow rays); a
        # holdout ends every ray that meets it (black): all stand for what the plate shows.
        ground_like = obj == ground_object or getattr(obj, "is_shadow_catcher", False)
        if ground_like or holds_out(obj):
            for attr in ("visible_glossy", "visible_shadow"):
                if getattr(obj, attr):
                    flags.append((obj, attr, True))
                    setattr(obj, attr, False)
