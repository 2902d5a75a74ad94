"""The node groups a reflection is made of (shading.py puts them on materials, world.py on a
world): "VR Camera LatLong" (world direction -> the product's camera-frame lat-long, through
Vector Transform), "VR LatLong" (camera frame -> Environment Texture vector) and one
"VR Reflection" group per combine mode and map (with the ground read per shading point when the
method has one). See shading.py for the frames and why an Environment Texture samples the map.

Groups are ours by the ``images.CREATED`` flag (nodes.py), shared while their inputs match, and
removed by `remove_unused_groups` once nothing uses them.
"""

import math

import bpy

from ..scene.images import CREATED
from .ground_nodes import mix_ground
from .nodes import find_or_new_group, math_node, new_node, vector_math_node, view_ray

LOOKUP_GROUP = "VR Camera LatLong"


LATLONG_GROUP = "VR LatLong"


REFLECTION_GROUP = "VR Reflection"


BOX_INPUTS = ("Box Centre", "Box Half Size")  # the reflection group's, with the ground


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


def env_lookup(nodes, links, direction, image, location):
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


def ensure_reflection_group(mode, image, ground=None, shift=None):
    """The group "VR Reflection <mode> [<image>]": a shader from the map along the reflection.

    Inputs by mode: REPLACE ``Strength``; MODULATE ``Base Color``, ``Strength``;
    MIX ``Shader`` (the material's own surface), ``Strength``, ``IOR``. Output ``Shader``.
    With ``ground`` (a ground_nodes.GroundLookup) the ground is looked up per shading point
    and mixed over the map (Camera View + Ground). With ``shift`` (ggx_lobe.dominant_shift of
    the roughness a Mix look's map is pre-filtered for) the map is read at the centre of the
    rough lobe rather than along the mirror direction (`_lobe_centre`). Reused when a group
    made by this module for the same mode, image, ground and shift exists.
    """
    signature = ground.signature() if ground is not None else ""
    shifted = ",".join(f"{v:.6g}" for v in shift) if shift is not None else ""
    for group in bpy.data.node_groups:
        if (
            group.get(CREATED) == "reflection"
            and group.get("vr_mode") == mode
            and group.library is None
            and _group_image(group) == image
            and group.get("vr_ground", "") == signature
            and group.get("vr_shift", "") == shifted
        ):
            return group
    group = bpy.data.node_groups.new(f"{REFLECTION_GROUP} {mode} [{image.name}]", "ShaderNodeTree")
    group[CREATED] = "reflection"
    group["vr_mode"] = mode
    group["vr_ground"] = signature
    group["vr_shift"] = shifted
    _reflection_sockets(group.interface, mode, ground is not None)
    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-900, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (600, 0))
    env = _map_colour(nodes, links, g_in, image, ground, shift)
    _reflection_shader(nodes, links, g_in, g_out, env, mode)
    return group


def _reflection_sockets(iface, mode, boxed):
    """The group's inputs for ``mode`` (and, ``boxed``, the shaded object's bounding box for
    its contact shadow on the ground) and its Shader output."""
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
    if boxed:
        # The shaded object's bounding box (its own space): its contact shadow on the ground.
        for name in BOX_INPUTS:
            iface.new_socket(name, in_out="INPUT", socket_type="NodeSocketVector")
    iface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")


def _map_colour(nodes, links, g_in, image, ground, shift):
    """The map's colour along the mirror direction (the lobe's centre with ``shift``), the
    ground looked up per shading point mixed over it with ``ground``: its output socket."""
    # The mirror direction: the camera ray (-Incoming) reflected about the shading normal.
    geometry, view = view_ray(nodes, links)
    reflect = new_node(nodes, "ShaderNodeVectorMath", "Reflection", (-500, 300))
    reflect.operation = "REFLECT"
    links.new(view.outputs["Vector"], reflect.inputs[0])
    links.new(geometry.outputs["Normal"], reflect.inputs[1])
    direction = reflect.outputs["Vector"]
    if shift is not None:
        direction = _lobe_centre(nodes, links, geometry, direction, shift)
    env = env_lookup(nodes, links, direction, image, (-300, 300))
    if ground is not None:
        position = geometry.outputs["Position"]
        box = tuple(g_in.outputs[name] for name in BOX_INPUTS)
        env = mix_ground(nodes, links, position, direction, env, ground, (0, 600), (box,))
    return env


def _reflection_shader(nodes, links, g_in, g_out, env, mode):
    """The shader of ``mode`` from the map's colour ``env``, linked to the group's output:
    an emission of it (times Base Color in MODULATE) as the whole surface, or in MIX over the
    material's own shader by Fresnel times Strength."""
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


def _lobe_centre(nodes, links, geometry, mirror, shift):
    """normalize(R + t (N - R)), t = x (a + x (b + x c)) clamped to 0..1 and x = 1 - N.I: the
    centre of a rough lobe for the view (ggx_lobe.dominant_shift); R the ``mirror`` socket."""
    a, b, c = shift
    normal, incoming = geometry.outputs["Normal"], geometry.outputs["Incoming"]
    facing = vector_math_node(nodes, links, "DOT_PRODUCT", "N.I", (-700, 700), normal, incoming)
    x = math_node(nodes, links, "SUBTRACT", "1 - N.I", (-550, 700), 1.0, facing)
    t = math_node(nodes, links, "MULTIPLY_ADD", "Shift (c x + b)", (-400, 700), x, c, b)
    t = math_node(nodes, links, "MULTIPLY_ADD", "Shift (.. x + a)", (-250, 700), x, t, a)
    t = math_node(nodes, links, "MULTIPLY", "Shift", (-100, 700), x, t)
    t.node.use_clamp = True
    toward = vector_math_node(nodes, links, "SUBTRACT", "N - R", (-550, 550), normal, mirror)
    toward = vector_math_node(nodes, links, "SCALE", "Toward Normal", (-400, 550), toward, t)
    moved = vector_math_node(nodes, links, "ADD", "R Shifted", (-250, 550), mirror, toward)
    return vector_math_node(nodes, links, "NORMALIZE", "Lobe Centre", (-100, 550), moved)


def _group_image(group):
    for node in group.nodes:
        if node.bl_idname == "ShaderNodeTexEnvironment":
            return node.image
    return None


def remove_unused_groups(*groups):
    """Delete our reflection groups without users, then the lookup groups nothing uses."""
    for group in groups:
        if group is not None and group.get(CREATED) == "reflection" and group.users == 0:
            bpy.data.node_groups.remove(group)
    # Outer before inner: the inner one is used by the outer.
    for kind in ("lookup", "latlong", "ground", "ground occlusion"):
        for group in list(bpy.data.node_groups):
            if group.get(CREATED) == kind and group.users == 0:
                bpy.data.node_groups.remove(group)
