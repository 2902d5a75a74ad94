"""Put an environment map on objects and the world, and take it off again (paper §3.1).

The map is a float32 scene-linear Blender image in the product's lat-long convention in the
CAMERA frame (docs/conventions.md): +Z the viewing direction, +Y up, +X the plate's LEFT; pixel
centre (x + .5, y + .5) of W x H (top row first) looks along
lon = -2π((x + .5)/W - .5), lat = -π((y + .5)/H - .5),
d = (sin lon cos lat, sin lat, cos lon cos lat).

The lookup happens in the node tree, with the camera's transform applied at render time, so a
moving or animated camera never needs a rebuilt map:

    world direction --Vector Transform (World -> Camera)-->  renderer camera space  ("VR Camera
    renderer camera space (x right, y up, z forward) --flip x--> product camera frame  LatLong")
    product frame --atan2--> UV (u right, v UP from the bottom row)                  ("VR LatLong")
                  --(Z, X, Y)--> vector for an Environment Texture (equirectangular)

Vector Transform's "Camera" space is the same in Cycles and EEVEE (x right, y up, z FORWARD,
i.e. Blender's camera-local frame with z negated): measured by rendering Vector Transform
outputs in both engines, and EEVEE's GLSL applies `invert_z` on purpose to match Cycles.
It is the camera of the view being rendered, though, and EEVEE renders the WORLD for its light
probes with the probes' own views: a world using Vector Transform shows the right background
but scrambles what glossy materials reflect. So the world reaches renderer camera space with
drivers on ``scene.camera.matrix_world`` instead (see `attach_world`), then uses "VR LatLong".

Sampling goes through an Environment Texture node fed with the product frame permuted into
Blender's equirectangular convention, not through an Image Texture fed with the UV: EEVEE
samples an Image Texture with mipmaps, and the jump of u from 1 to 0 at the back seam (the
direction toward the camera, i.e. the middle of every chrome sphere) picks the coarsest mip
and draws a line; EEVEE's Environment Texture samples without mipmaps for exactly that reason.
Both nodes wrap horizontally, so Cycles shows no seam either way.

Nothing here edits a user's material or world: `attach` assigns object-level copies
(`slot.link = 'OBJECT'`), `attach_world` assigns a new world, and what was there before is
recorded on the object / scene so `detach` / `detach_world` restore it exactly and delete only
what this module created (flagged with the custom property `CREATED`).
"""

import math

import bpy

from .ground_nodes import mix_ground, occluder
from .images import CREATED
from .nodes import find_or_new_group, math_node, new_node

LOOKUP_GROUP = "VR Camera LatLong"
LATLONG_GROUP = "VR LatLong"
REFLECTION_GROUP = "VR Reflection"
BOX_INPUTS = ("Box Centre", "Box Half Size")  # the reflection group's, with the ground
WORLD_NAME = "VR World"
MODES = ("REPLACE", "MODULATE", "MIX", "WORLD")
REFLECTABLE = {"MESH", "CURVE", "SURFACE", "FONT", "META", "CURVES"}  # object types with a surface
ENVIRONMENT_NODE = "VR Environment"  # the world's map node

RECORD = "vr_shading"  # on objects: what attach() replaced
WORLD_RECORD = "vr_world"  # on scenes: what attach_world() replaced

_USE_NODES_DEPRECATED = bpy.app.version >= (5, 0, 0)


# --- the camera-frame lat-long lookup --------------------------------------------------------


def ensure_latlong_group():
    """The shader node group "VR LatLong": a renderer camera-space direction to the lookup.

    Input ``Camera Vector``: a direction in Vector Transform's camera space (x right, y up,
    z forward; any length). Outputs as in `ensure_lookup_group`.
    """
    group = find_or_new_group(LATLONG_GROUP, "latlong")
    if group.nodes:
        return group
    iface = group.interface
    iface.new_socket("Camera Vector", in_out="INPUT", socket_type="NodeSocketVector")
    iface.new_socket("UV", in_out="OUTPUT", socket_type="NodeSocketVector")
    iface.new_socket("Equirect", in_out="OUTPUT", socket_type="NodeSocketVector")

    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-800, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (700, 0))

    # Product camera frame: +X is the plate's left, so flip x (docs/conventions.md).
    flip = new_node(nodes, "ShaderNodeVectorMath", "To Product Frame", (-600, 0))
    flip.operation = "MULTIPLY"
    flip.inputs[1].default_value = (-1.0, 1.0, 1.0)
    links.new(g_in.outputs["Camera Vector"], flip.inputs[0])

    xyz = new_node(nodes, "ShaderNodeSeparateXYZ", "Product XYZ", (-400, 0))
    links.new(flip.outputs["Vector"], xyz.inputs["Vector"])
    x, y, z = xyz.outputs["X"], xyz.outputs["Y"], xyz.outputs["Z"]

    # lon = atan2(X, Z); lat = atan2(Y, |(X, Z)|) -- no normalisation and no asin domain edge.
    lon = math_node(nodes, links, "ARCTAN2", "Longitude", (-200, 150), x, z)
    xz = new_node(nodes, "ShaderNodeCombineXYZ", "XZ", (-200, -50))
    links.new(x, xz.inputs["X"])
    links.new(z, xz.inputs["Z"])
    xz_len = new_node(nodes, "ShaderNodeVectorMath", "XZ Length", (0, -50))
    xz_len.operation = "LENGTH"
    links.new(xz.outputs["Vector"], xz_len.inputs[0])
    lat = math_node(nodes, links, "ARCTAN2", "Latitude", (200, -50), y, xz_len.outputs["Value"])

    # u = 0.5 - lon / 2π (map x grows to the right); v = 0.5 + lat / π (v grows upward).
    u = math_node(nodes, links, "MULTIPLY_ADD", "U", (200, 150), lon, -0.5 / math.pi, 0.5)
    v = math_node(nodes, links, "MULTIPLY_ADD", "V", (400, -50), lat, 1.0 / math.pi, 0.5)
    uv = new_node(nodes, "ShaderNodeCombineXYZ", "UV", (550, 100))
    links.new(u, uv.inputs["X"])
    links.new(v, uv.inputs["Y"])
    links.new(uv.outputs["Vector"], g_out.inputs["UV"])

    # Blender's equirectangular: u = 0.5 - atan2(d.y, d.x)/2π, v = 0.5 + atan2(d.z, |d.xy|)/π,
    # so d = (Z, X, Y) of the product frame gives the same (u, v) as above.
    env = new_node(nodes, "ShaderNodeCombineXYZ", "Equirect", (-200, -250))
    links.new(z, env.inputs["X"])
    links.new(x, env.inputs["Y"])
    links.new(y, env.inputs["Z"])
    links.new(env.outputs["Vector"], g_out.inputs["Equirect"])
    return group


def ensure_lookup_group():
    """The shader node group "VR Camera LatLong": a world-space direction to the map lookup.

    Input ``Vector``: a world-space direction (any length).
    Output ``UV``: (u, v, 0) for an Image Texture of the map; u = (x + .5)/W, v UP from the
    bottom row (v = 1 - (y + .5)/H).
    Output ``Equirect``: the same direction in the product's camera frame permuted to
    (Z, X, Y), which Blender's Environment Texture (equirectangular) turns into the same
    (u, v); the material and world groups use it because it is seam-free in EEVEE.

    The camera is the render camera through Vector Transform (World -> Camera), so it follows
    a moving camera in both engines. Reused when present (found by its flag, so a user's group
    of the same name is left alone).
    """
    group = find_or_new_group(LOOKUP_GROUP, "lookup")
    if group.nodes:
        return group
    iface = group.interface
    iface.new_socket("Vector", in_out="INPUT", socket_type="NodeSocketVector")
    iface.new_socket("UV", in_out="OUTPUT", socket_type="NodeSocketVector")
    iface.new_socket("Equirect", in_out="OUTPUT", socket_type="NodeSocketVector")

    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-600, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (200, 0))
    # Renderer camera space: x right, y up, z forward (measured the same in Cycles and EEVEE).
    to_cam = new_node(nodes, "ShaderNodeVectorTransform", "World to Camera", (-400, 0))
    to_cam.vector_type = "VECTOR"
    to_cam.convert_from = "WORLD"
    to_cam.convert_to = "CAMERA"
    links.new(g_in.outputs["Vector"], to_cam.inputs["Vector"])
    latlong = new_node(nodes, "ShaderNodeGroup", "VR LatLong", (-200, 0))
    latlong.node_tree = ensure_latlong_group()
    links.new(to_cam.outputs["Vector"], latlong.inputs["Camera Vector"])
    links.new(latlong.outputs["UV"], g_out.inputs["UV"])
    links.new(latlong.outputs["Equirect"], g_out.inputs["Equirect"])
    return group


def _env_lookup(nodes, links, direction, image, location):
    """Lookup group + Environment Texture of ``image`` along the world ``direction`` socket."""
    x, y = location
    lookup = new_node(nodes, "ShaderNodeGroup", "VR Camera LatLong", (x, y))
    lookup.node_tree = ensure_lookup_group()
    links.new(direction, lookup.inputs["Vector"])
    tex = new_node(nodes, "ShaderNodeTexEnvironment", "VR Environment", (x + 200, y))
    tex.image = image
    tex.interpolation = "Linear"
    tex.projection = "EQUIRECTANGULAR"
    links.new(lookup.outputs["Equirect"], tex.inputs["Vector"])
    return tex.outputs["Color"]


# --- per-mode reflection groups ---------------------------------------------------------------


def _ensure_reflection_group(mode, image, ground=None):
    """The group "VR Reflection <mode> [<image>]": a shader from the map along the reflection.

    Inputs by mode: REPLACE ``Strength``; MODULATE ``Base Color``, ``Strength``;
    MIX ``Shader`` (the material's own surface), ``Strength``, ``IOR``. Output ``Shader``.
    With ``ground`` (a ground_nodes.GroundLookup) the ground is looked up per shading point
    and mixed over the map (Camera View + Ground). Reused when a group made by this module for
    the same mode, image and ground exists.
    """
    signature = ground.signature() if ground is not None else ""
    for group in bpy.data.node_groups:
        if (
            group.get(CREATED) == "reflection"
            and group.get("vr_mode") == mode
            and group.library is None
            and _group_image(group) == image
            and group.get("vr_ground", "") == signature
        ):
            return group
    group = bpy.data.node_groups.new(f"{REFLECTION_GROUP} {mode} [{image.name}]", "ShaderNodeTree")
    group[CREATED] = "reflection"
    group["vr_mode"] = mode
    group["vr_ground"] = signature

    iface = group.interface
    if mode == "MIX":
        iface.new_socket("Shader", in_out="INPUT", socket_type="NodeSocketShader")
    if mode == "MODULATE":
        base = iface.new_socket("Base Color", in_out="INPUT", socket_type="NodeSocketColor")
        base.default_value = (0.8, 0.8, 0.8, 1.0)
    strength = iface.new_socket("Strength", in_out="INPUT", socket_type="NodeSocketFloat")
    strength.default_value, strength.min_value = 1.0, 0.0
    if mode == "MIX":
        ior = iface.new_socket("IOR", in_out="INPUT", socket_type="NodeSocketFloat")
        ior.default_value, ior.min_value, ior.max_value = 1.45, 1.0, 100.0
    if ground is not None:
        # The shaded object's bounding box (its own space): its contact shadow on the ground.
        for name in BOX_INPUTS:
            iface.new_socket(name, in_out="INPUT", socket_type="NodeSocketVector")
    iface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")

    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-900, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (600, 0))

    # The mirror direction: the camera ray (-Incoming) reflected about the shading normal.
    geometry = new_node(nodes, "ShaderNodeNewGeometry", "Geometry", (-900, 300))
    view = new_node(nodes, "ShaderNodeVectorMath", "View Ray", (-700, 300))
    view.operation = "SCALE"
    view.inputs["Scale"].default_value = -1.0
    links.new(geometry.outputs["Incoming"], view.inputs[0])
    reflect = new_node(nodes, "ShaderNodeVectorMath", "Reflection", (-500, 300))
    reflect.operation = "REFLECT"
    links.new(view.outputs["Vector"], reflect.inputs[0])
    links.new(geometry.outputs["Normal"], reflect.inputs[1])
    env = _env_lookup(nodes, links, reflect.outputs["Vector"], image, (-300, 300))
    if ground is not None:
        position = geometry.outputs["Position"]
        box = tuple(g_in.outputs[name] for name in BOX_INPUTS)
        env = mix_ground(
            nodes, links, position, reflect.outputs["Vector"], env, ground, (0, 600), box
        )

    emission = new_node(nodes, "ShaderNodeEmission", "Reflection Emission", (200, 200))
    if mode == "MODULATE":
        # GL_MODULATE (§3.1): material colour times the map.
        tint = new_node(nodes, "ShaderNodeVectorMath", "Modulate", (50, 200))
        tint.operation = "MULTIPLY"
        links.new(env, tint.inputs[0])
        links.new(g_in.outputs["Base Color"], tint.inputs[1])
        links.new(tint.outputs["Vector"], emission.inputs["Color"])
    else:
        links.new(env, emission.inputs["Color"])

    if mode == "MIX":
        emission.inputs["Strength"].default_value = 1.0
        fresnel = new_node(nodes, "ShaderNodeFresnel", "Fresnel", (-100, -100))
        links.new(g_in.outputs["IOR"], fresnel.inputs["IOR"])
        factor = math_node(
            nodes, links, "MULTIPLY", "Reflection Weight", (100, -100), fresnel.outputs[0], 1.0
        )
        factor.node.use_clamp = True
        links.new(g_in.outputs["Strength"], factor.node.inputs[1])
        mix = new_node(nodes, "ShaderNodeMixShader", "Mix", (400, 0))
        links.new(factor, mix.inputs["Fac"])
        links.new(g_in.outputs["Shader"], mix.inputs[1])
        links.new(emission.outputs["Emission"], mix.inputs[2])
        links.new(mix.outputs["Shader"], g_out.inputs["Shader"])
    else:
        # GL_REPLACE / GL_MODULATE: the reflection is the whole surface.
        links.new(g_in.outputs["Strength"], emission.inputs["Strength"])
        links.new(emission.outputs["Emission"], g_out.inputs["Shader"])
    return group


def _group_image(group):
    for node in group.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment":
            return node.image
    return None


# --- materials --------------------------------------------------------------------------------


def is_attached(obj):
    """True when `attach` put a map on ``obj`` (and `detach` has not taken it off)."""
    return RECORD in obj.keys()


def mode_of(obj) -> str | None:
    """The combine mode of ``obj``'s reflection ("REPLACE", ..., "WORLD"), or None."""
    record = obj.get(RECORD) if obj is not None else None
    return record.get("mode") if record is not None else None


def map_of(obj):
    """The map image ``obj`` reflects (its own, or in World mode the world's), or None."""
    record = obj.get(RECORD) if obj is not None else None
    if record is None:
        return None
    image = record.get("image")
    if image is None and record.get("mode") == "WORLD":  # recorded before maps were kept here
        world = record.get("world")
        node = world.node_tree.nodes.get(ENVIRONMENT_NODE) if world is not None else None
        image = node.image if node is not None else None
    return image if isinstance(image, bpy.types.Image) else None


def reflecting(scene, names=None) -> dict:
    """{map image: [objects]}: the objects of ``scene`` with a reflection attached, by the map
    they reflect (World mode: one shared map for all its objects). With ``names``, only maps
    of which at least one object is named there."""
    found = {}
    for obj in scene.objects:
        if obj.type not in REFLECTABLE:
            continue
        image = map_of(obj)
        if image is not None:
            found.setdefault(image, []).append(obj)
    if names is not None:
        found = {k: v for k, v in found.items() if any(o.name in names for o in v)}
    return found


def attach(obj, image, mode, strength=1.0, ior=1.45, ground=None):
    """Put ``image`` (a camera-frame lat-long map) on every material slot of ``obj``.

    mode: 'REPLACE' (emission of the map, §3.1's GL replace), 'MODULATE' (map times the
    material's base colour, GL modulate), 'MIX' (the material's own surface mixed with the map,
    factor strength x Fresnel(ior)), or 'WORLD' (`attach_world` on the object's scene; the
    materials are left alone). ground: a ground_nodes.GroundLookup for the first three: the
    ground the object stands on is read from the plate per shading point (Camera View +
    Ground).

    Each slot gets an object-level copy of its material (`slot.link = 'OBJECT'`), so the
    original material and a mesh shared with other objects are untouched. An object without
    slots gets one empty slot on its data (harmless to other users of the data, removed again
    by `detach`). Attaching again first detaches. Raises ValueError, before changing anything,
    for linked (library) data or an object that cannot hold materials.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")
    if not isinstance(image, bpy.types.Image):
        raise TypeError(f"image must be a bpy.types.Image, not {type(image).__name__}")
    _check_local(obj, f"object {obj.name!r}")
    if mode == "WORLD":
        scene = _scene_of(obj)
        _check_local(scene, f"scene {scene.name!r}")
        if is_attached(obj):
            detach(obj)
        world = attach_world(scene, image, strength)
        obj[RECORD] = {"mode": "WORLD", "scene": scene, "world": world, "image": image}
        return

    if obj.data is None or not hasattr(obj.data, "materials"):
        raise ValueError(f"object {obj.name!r} ({obj.type}) cannot hold materials")
    if not obj.material_slots:
        _check_local(obj.data, f"{obj.type.lower()} data {obj.data.name!r} of {obj.name!r}")
    for _, data_mat, object_mat in slot_states(obj):
        for mat in (data_mat, object_mat):
            if mat is not None:
                _check_local(mat, f"material {mat.name!r} on {obj.name!r}")

    old_group = None
    if is_attached(obj):
        old_group = obj[RECORD].get("group")
        detach(obj, tidy=False)  # its groups may serve again: tidied below

    added_slot = not obj.material_slots
    if added_slot:
        obj.data.materials.append(None)
    previous = [(link, object_mat) for link, _, object_mat in slot_states(obj)]
    group = _ensure_reflection_group(mode, image, ground)
    copies = {}  # original material (or None for an empty slot) -> our copy
    for slot in obj.material_slots:
        source = slot.material
        key = source.name if source is not None else None
        if key not in copies:
            copies[key] = _material_copy(obj, source, mode, group, strength, ior)
        slot.link = "OBJECT"
        slot.material = copies[key]

    obj[RECORD] = {
        "mode": mode,
        "image": image,
        "added_slot": added_slot,
        "slots": [_state_record(link, mat) for link, mat in previous],
        "copies": list(copies.values()),
        "group": group,
    }
    _remove_unused_groups(old_group)


def detach(obj, tidy=True):
    """Undo `attach`: restore every slot's link and object-level material, then delete the
    copies, and (``tidy``) the reflection and lookup groups this module made once nothing uses
    them."""
    record = obj.get(RECORD)
    if record is None:
        return
    _check_local(obj, f"object {obj.name!r}")
    mode = record.get("mode")
    if mode == "WORLD":
        scene, world = record.get("scene"), record.get("world")
        del obj[RECORD]
        # The scene's world goes when no other object in WORLD mode still shares it.
        scene_record = scene.get(WORLD_RECORD) if scene is not None else None
        if scene_record is not None and scene_record.get("world") == world:
            sharing = any(
                other.get(RECORD) is not None and other[RECORD].get("world") == world
                for other in bpy.data.objects
            )
            if not sharing:
                detach_world(scene)
        return

    slots = [(state["link"], state.get("material")) for state in record.get("slots", [])]
    copies = list(record.get("copies", []))
    group = record.get("group")
    added_slot = bool(record.get("added_slot"))
    del obj[RECORD]

    for slot, (link, object_mat) in zip(obj.material_slots, slots):
        slot.link = "OBJECT"
        slot.material = object_mat
        slot.link = link
    if added_slot and len(obj.data.materials) == 1 and obj.data.materials[0] is None:
        obj.data.materials.clear()  # pop() leaves the objects' slot count behind

    for copy in copies:
        if copy is not None and copy.get(CREATED) == "material" and copy.users == 0:
            bpy.data.materials.remove(copy)
    if tidy:
        _remove_unused_groups(group)


def _check_local(id_data, what):
    if id_data.library is not None or not id_data.is_editable:
        library = id_data.library.filepath if id_data.library is not None else "a library"
        raise ValueError(f"{what} is linked from {library} and read-only; make it local first")


def _scene_of(obj):
    scene = bpy.context.scene
    if scene is not None and obj.name in scene.objects:
        return scene
    if obj.users_scene:
        return obj.users_scene[0]
    raise ValueError(f"object {obj.name!r} is in no scene; cannot attach a world to it")


def slot_states(obj):
    """[(slot.link, data-level material, object-level material)] per material slot; None for
    an empty pointer. Blender exposes the pointer the slot does not use only through
    ``slot.material`` after switching ``slot.link``, so this switches and switches back."""
    states = []
    for slot in obj.material_slots:
        link = slot.link
        levels = {}
        for level in ("DATA", "OBJECT"):
            if slot.link != level:
                slot.link = level
            levels[level] = slot.material
        if slot.link != link:
            slot.link = link
        states.append((link, levels["DATA"], levels["OBJECT"]))
    return states


def _state_record(link, mat):
    state = {"link": link}
    if mat is not None:
        state["material"] = mat
    return state


def _material_copy(obj, source, mode, group, strength, ior):
    """An object-level copy of ``source`` (or a new material) with the reflection group wired."""
    if source is None:
        copy = bpy.data.materials.new(f"VR [{obj.name}]")
        if not _USE_NODES_DEPRECATED:
            copy.use_nodes = True
        fallback = tuple(copy.diffuse_color)
    else:
        copy = source.copy()
        copy.name = f"{source.name} [VR {obj.name}]"
        fallback = tuple(source.diffuse_color)
        if not _USE_NODES_DEPRECATED and not copy.use_nodes:
            _nodes_from_settings(copy)
    copy[CREATED] = "material"
    _wire(copy.node_tree, mode, group, strength, ior, fallback, occluder(obj))
    if mode in ("REPLACE", "MODULATE") and hasattr(copy, "cycles"):
        # The emission is the reflection, not a light: don't let Cycles sample it as one
        # (light sampling of map-textured emission made renders 2-3x slower).
        copy.cycles.emission_sampling = "NONE"
    return copy


def _nodes_from_settings(mat):
    """Blender < 5: a material without nodes renders from its viewport settings; give the copy
    the equivalent Principled BSDF so MODULATE and MIX have a surface to work with."""
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    bsdf = new_node(tree.nodes, "ShaderNodeBsdfPrincipled", "Principled BSDF", (-300, 0))
    bsdf.inputs["Base Color"].default_value = tuple(mat.diffuse_color)
    bsdf.inputs["Metallic"].default_value = mat.metallic
    bsdf.inputs["Roughness"].default_value = mat.roughness
    out = new_node(tree.nodes, "ShaderNodeOutputMaterial", "Material Output", (0, 0))
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])


def _wire(tree, mode, group, strength, ior, fallback_color, box):
    """Insert a group node between each active Material Output and what fed its Surface.
    box: the object's (centre, half size), for a group that reads the ground."""
    nodes, links = tree.nodes, tree.links
    outputs = [n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial" and n.is_active_output]
    if not outputs:
        outputs = [new_node(nodes, "ShaderNodeOutputMaterial", "Material Output", (300, 0))]
    for i, out in enumerate(outputs):
        surface = out.inputs["Surface"]
        source = surface.links[0].from_socket if surface.is_linked else None
        name = f"VR Reflection{'' if i == 0 else f' {i}'}"
        node = new_node(nodes, "ShaderNodeGroup", name, (0, 0))
        node.node_tree = group
        node.location = (out.location.x, out.location.y + 250)
        node.inputs["Strength"].default_value = strength
        if BOX_INPUTS[0] in node.inputs:
            for name, value in zip(BOX_INPUTS, box):
                node.inputs[name].default_value = value
        if mode == "MIX":
            node.inputs["IOR"].default_value = ior
            if source is not None:
                links.new(source, node.inputs["Shader"])
        if mode == "MODULATE":
            base = _base_color(source)
            if isinstance(base, bpy.types.NodeSocket):
                links.new(base, node.inputs["Base Color"])
            else:
                node.inputs["Base Color"].default_value = base if base else fallback_color
        links.new(node.outputs["Shader"], surface)


GLOSSY_NODES = ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")


def roughness(obj) -> float:
    """The roughness of ``obj``'s surface, for pre-filtering its map (Replace, Modulate, Mix):
    the first material slot's Principled or Glossy BSDF "Roughness" when not linked (a linked
    one, a texture, counts as 0.5), else the material's viewport roughness; 0 without a
    material. The copies `attach` made keep the original's nodes, so this reads the same
    before and after."""
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None:
            continue
        tree = mat.node_tree if (_USE_NODES_DEPRECATED or mat.use_nodes) else None
        for node in tree.nodes if tree is not None else ():
            if node.bl_idname in GLOSSY_NODES and "Roughness" in node.inputs:
                socket = node.inputs["Roughness"]
                return 0.5 if socket.is_linked else float(socket.default_value)
        return float(mat.roughness)
    return 0.0


def _base_color(shader_socket):
    """The material colour feeding a shader: the linked source socket or the default value of
    the first upstream 'Base Color' input (Principled BSDF), else of the shader's own 'Color'
    input; None when there is neither."""
    if shader_socket is None:
        return None
    first = shader_socket.node
    seen, queue = set(), [first]
    while queue:
        node = queue.pop(0)
        if node.as_pointer() in seen:
            continue
        seen.add(node.as_pointer())
        socket = node.inputs.get("Base Color")
        if socket is not None:
            return _socket_value(socket)
        for inp in node.inputs:
            if inp.type == "SHADER" and inp.is_linked:
                queue.append(inp.links[0].from_node)
    socket = first.inputs.get("Color")
    if socket is not None and socket.type == "RGBA":
        return _socket_value(socket)
    return None


def _socket_value(socket):
    if socket.is_linked:
        return socket.links[0].from_socket
    return tuple(socket.default_value)


def _remove_unused_groups(*groups):
    """Delete our reflection groups without users, then the lookup groups nothing uses."""
    for group in groups:
        if group is not None and group.get(CREATED) == "reflection" and group.users == 0:
            bpy.data.node_groups.remove(group)
    # Outer before inner: the inner one is used by the outer.
    for kind in ("lookup", "latlong", "ground", "ground occlusion"):
        for group in list(bpy.data.node_groups):
            if group.get(CREATED) == kind and group.users == 0:
                bpy.data.node_groups.remove(group)


# --- world ------------------------------------------------------------------------------------


def attach_world(scene, image, strength=1.0):
    """Give ``scene`` a NEW world "VR World" whose background is ``image`` looked up along the
    view direction in the frame of the scene's camera, so every glossy material reflects the
    plate, aligned with the camera. The previous world is recorded; `detach_world` restores it.
    When the scene already has its VR World, that world gets the new image and strength (so
    several objects in WORLD mode share one world). Returns the world.

    The world does not use Vector Transform: EEVEE evaluates the world for its light probes
    with the probes' own views as "camera", which scrambles what materials reflect. Instead
    drivers read ``scene.camera.matrix_world`` (following animation and camera switches) and
    the direction is projected on the camera's axes, then goes through the same "VR LatLong"
    group as the materials.
    """
    if not isinstance(image, bpy.types.Image):
        raise TypeError(f"image must be a bpy.types.Image, not {type(image).__name__}")
    _check_local(scene, f"scene {scene.name!r}")
    record = scene.get(WORLD_RECORD)
    if record is not None:
        world = record.get("world")
        if world is not None and scene.world == world:
            world.node_tree.nodes[ENVIRONMENT_NODE].image = image
            world.node_tree.nodes["Background"].inputs["Strength"].default_value = strength
            return world
        detach_world(scene)  # the user assigned another world meanwhile: start over
    previous = scene.world

    world = bpy.data.worlds.new(WORLD_NAME)
    world[CREATED] = "world"
    if not _USE_NODES_DEPRECATED:
        world.use_nodes = True
    tree = world.node_tree
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    # In a world shader the camera (or reflected) ray travels along -Incoming.
    geometry = new_node(nodes, "ShaderNodeNewGeometry", "Geometry", (-900, 300))
    view = new_node(nodes, "ShaderNodeVectorMath", "View Ray", (-700, 300))
    view.operation = "SCALE"
    view.inputs["Scale"].default_value = -1.0
    links.new(geometry.outputs["Incoming"], view.inputs[0])

    # Vector Transform's camera space from the scene camera's axes: x right, y up, z forward.
    camera = new_node(nodes, "ShaderNodeCombineXYZ", "Camera Space", (-200, 0))
    for i, (axis, sign) in enumerate((("X", 1.0), ("Y", 1.0), ("Z", -1.0))):
        column = new_node(nodes, "ShaderNodeCombineXYZ", f"Scene Camera {axis}", (-900, -200 * i))
        for row in range(3):
            _drive(column.inputs[row], scene, f"camera.matrix_world[{i}][{row}]")
        unit = new_node(nodes, "ShaderNodeVectorMath", f"Camera {axis} Unit", (-700, -200 * i))
        unit.operation = "NORMALIZE"  # the camera object may be scaled
        links.new(column.outputs["Vector"], unit.inputs[0])
        dot = new_node(nodes, "ShaderNodeVectorMath", f"Along Camera {axis}", (-500, -200 * i))
        dot.operation = "DOT_PRODUCT"
        links.new(view.outputs["Vector"], dot.inputs[0])
        links.new(unit.outputs["Vector"], dot.inputs[1])
        component = math_node(
            nodes, links, "MULTIPLY", f"Camera {axis}", (-350, -200 * i), dot.outputs["Value"], sign
        )
        links.new(component, camera.inputs[i])

    latlong = new_node(nodes, "ShaderNodeGroup", "VR LatLong", (0, 0))
    latlong.node_tree = ensure_latlong_group()
    links.new(camera.outputs["Vector"], latlong.inputs["Camera Vector"])
    tex = new_node(nodes, "ShaderNodeTexEnvironment", ENVIRONMENT_NODE, (200, 0))
    tex.image = image
    tex.interpolation = "Linear"
    links.new(latlong.outputs["Equirect"], tex.inputs["Vector"])
    background = new_node(nodes, "ShaderNodeBackground", "Background", (500, 0))
    background.inputs["Strength"].default_value = strength
    links.new(tex.outputs["Color"], background.inputs["Color"])
    out = new_node(nodes, "ShaderNodeOutputWorld", "World Output", (700, 0))
    links.new(background.outputs["Background"], out.inputs["Surface"])

    record = {"world": world}
    if previous is not None:
        record["previous"] = previous
    scene[WORLD_RECORD] = record
    scene.world = world
    return world


def _drive(socket, scene, data_path):
    """Drive ``socket``'s value by a property path on ``scene`` (no Python expression, so it
    runs with auto-run scripts disabled). RNA indexes matrix_world column first: [col][row]."""
    driver = socket.driver_add("default_value").driver
    driver.type = "SUM"
    var = driver.variables.new()
    var.name = "value"
    var.type = "SINGLE_PROP"
    var.targets[0].id_type = "SCENE"
    var.targets[0].id = scene
    var.targets[0].data_path = data_path


def detach_world(scene):
    """Undo `attach_world`: restore the previous world and delete "VR World"."""
    record = scene.get(WORLD_RECORD)
    if record is None:
        return
    world = record.get("world")
    previous = record.get("previous")
    del scene[WORLD_RECORD]
    if scene.world == world:
        scene.world = previous
    in_use = any(other.world == world for other in bpy.data.scenes)
    if world is not None and world.get(CREATED) == "world" and not in_use:
        bpy.data.worlds.remove(world)  # also clears objects' WORLD records pointing at it
    _remove_unused_groups()
