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
drivers on ``scene.camera.matrix_world`` instead (world.py), then uses "VR LatLong".

Sampling goes through an Environment Texture node fed with the product frame permuted into
Blender's equirectangular convention, not through an Image Texture fed with the UV: EEVEE
samples an Image Texture with mipmaps, and the jump of u from 1 to 0 at the back seam (the
direction toward the camera, i.e. the middle of every chrome sphere) picks the coarsest mip
and draws a line; EEVEE's Environment Texture samples without mipmaps for exactly that reason.
Both nodes wrap horizontally, so Cycles shows no seam either way.

Nothing here edits a user's material or world: `attach` assigns object-level copies
(`slot.link = 'OBJECT'`), `attach_world` (world.py) assigns a new world, and what was there
before is recorded on the object / scene so `detach` / `detach_world` restore it exactly and
delete only what the add-on created (flagged with the custom property `CREATED`). A material
linked from a library is copied the same way, so a library override (how shots bring assets
in: a local object whose materials are the library's) takes a map; its record is kept in its
scene too (`record_of`), since Blender drops a custom property added on an override when the
file opens.
"""

import bpy

from ...virtual_reflections.methods import COMBINE_NAMES, WHOLE_SURFACE_LOOKS
from ..scene import app_handlers
from ..scene.images import CREATED, check_local
from .ground_nodes import occluder
from .nodes import USE_NODES_DEPRECATED, new_node
from .reflection_nodes import BOX_INPUTS, ensure_reflection_group, remove_unused_groups
from .world import ENVIRONMENT_NODE, WORLD_RECORD, attach_world, detach_world

MODES = COMBINE_NAMES  # the looks (virtual_reflections/methods.py)


REFLECTABLE = {"MESH", "CURVE", "SURFACE", "FONT", "META", "CURVES"}  # object types with a surface


RECORD = "vr_shading"  # on objects: what attach() replaced
OVERRIDE_RECORDS = "vr_override_shading"  # on a scene: [{"object", "record"}] of overrides


def record_of(obj):
    """What `attach` replaced on ``obj`` (an ID property group), or None. A library override
    keeps it in its scene as well: Blender re-makes an override from its library when the
    file opens and keeps only the properties the library has, so a custom property added on
    the override is gone then (its material slots are kept)."""
    if obj is None:
        return None
    record = obj.get(RECORD)
    if record is not None or obj.override_library is None:
        return record
    for scene in bpy.data.scenes:
        for entry in scene.get(OVERRIDE_RECORDS, ()):
            if entry.get("object") == obj:
                return entry.get("record")
    return None


def _set_record(obj, record: dict):
    obj[RECORD] = record
    if obj.override_library is not None:
        _drop_override_record(obj)
        try:
            scene = _scene_of(obj)
        except ValueError:  # in no scene: kept on the object for this session only
            return
        entries = [e.to_dict() for e in scene.get(OVERRIDE_RECORDS, ())]
        scene[OVERRIDE_RECORDS] = [*entries, {"object": obj, "record": record}]


def _drop_record(obj):
    if RECORD in obj.keys():
        del obj[RECORD]
    _drop_override_record(obj)


def _drop_override_record(obj):
    """``obj``'s entry out of every scene's OVERRIDE_RECORDS (and those of deleted objects)."""
    for scene in bpy.data.scenes:
        entries = scene.get(OVERRIDE_RECORDS)
        if entries is None:
            continue
        kept = [e.to_dict() for e in entries if e.get("object") not in (obj, None)]
        if kept:
            scene[OVERRIDE_RECORDS] = kept
        else:
            del scene[OVERRIDE_RECORDS]


def is_attached(obj):
    """True when `attach` put a map on ``obj`` (and `detach` has not taken it off)."""
    return record_of(obj) is not None


def mode_of(obj) -> str | None:
    """The combine mode of ``obj``'s reflection ("REPLACE", ..., "WORLD"), or None."""
    record = record_of(obj)
    return record.get("mode") if record is not None else None


def map_of(obj):
    """The map image ``obj`` reflects (its own, or in World mode the world's), or None."""
    record = record_of(obj)
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


def attach(obj, image, mode, strength=1.0, ior=1.45, ground=None, shift=None):
    """Put ``image`` (a camera-frame lat-long map) on every material slot of ``obj``.

    mode: 'REPLACE' (emission of the map, §3.1's GL replace), 'MODULATE' (map times the
    material's base colour, GL modulate), 'MIX' (the material's own surface mixed with the map,
    factor strength x Fresnel(ior)), or 'WORLD' (`attach_world` on the object's scene; the
    materials are left alone). ground: a ground_nodes.GroundLookup for the first three: the
    ground the object stands on is read from the plate per shading point (Camera View +
    Ground). shift: for a map pre-filtered for a rough surface, where the lobe's centre lies
    (ggx_lobe.dominant_shift), read instead of the mirror direction.

    Each slot gets an object-level copy of its material (`slot.link = 'OBJECT'`), so the
    original material and a mesh shared with other objects are untouched. An object without
    slots gets one empty slot on its data (harmless to other users of the data, removed again
    by `detach`). A material linked from a library is copied the same way, never edited, so a
    library override (a local object whose materials may be linked) takes a map too.
    Attaching again first detaches. Raises ValueError, before changing anything, for a linked
    object (saying to make it a library override), an object without slots whose data is
    linked, or an object that cannot hold materials.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, not {mode!r}")
    if not isinstance(image, bpy.types.Image):
        raise TypeError(f"image must be a bpy.types.Image, not {type(image).__name__}")
    if obj.library is not None:
        raise ValueError(linked_object(obj))
    check_local(obj, f"object {obj.name!r}")
    if mode == "WORLD":
        scene = _scene_of(obj)
        check_local(scene, f"scene {scene.name!r}")
        if is_attached(obj):
            detach(obj)
        world = attach_world(scene, image, strength)
        _set_record(obj, {"mode": "WORLD", "scene": scene, "world": world, "image": image})
        return

    if obj.data is None or not hasattr(obj.data, "materials"):
        raise ValueError(f"object {obj.name!r} ({obj.type}) cannot hold materials")
    if not obj.material_slots:
        check_local(obj.data, f"{obj.type.lower()} data {obj.data.name!r} of {obj.name!r}")

    old_group = None
    if is_attached(obj):
        old_group = record_of(obj).get("group")
        detach(obj, tidy=False)  # its groups may serve again: tidied below

    added_slot = not obj.material_slots
    if added_slot:
        obj.data.materials.append(None)
    previous = [(link, object_mat) for link, _, object_mat in slot_states(obj)]
    group = ensure_reflection_group(mode, image, ground, shift)
    copies = {}  # original material (or None for an empty slot) -> our copy
    for slot in obj.material_slots:
        source = slot.material
        key = source.name if source is not None else None
        if key not in copies:
            copies[key] = _material_copy(obj, source, mode, group, strength, ior)
        slot.link = "OBJECT"
        slot.material = copies[key]

    record = {
        "mode": mode,
        "image": image,
        "added_slot": added_slot,
        "slots": [_state_record(link, mat) for link, mat in previous],
        "copies": list(copies.values()),
        "group": group,
    }
    _set_record(obj, record)
    remove_unused_groups(old_group)


def linked_object(obj) -> str:
    """One line for an object linked from a library (read-only): what to do instead. A library
    override of it is local, and its linked materials are copied, never edited."""
    return (
        f"object {obj.name!r} is linked from {obj.library.filepath} (read-only): make it a "
        "library override (Object > Library Override > Make) and generate again"
    )


def detach(obj, tidy=True):
    """Undo `attach`: restore every slot's link and object-level material, then delete the
    copies, and (``tidy``) the reflection and lookup groups this module made once nothing uses
    them."""
    record = record_of(obj)
    if record is None:
        return
    check_local(obj, f"object {obj.name!r}")
    record = record.to_dict()  # a copy: the record is deleted below
    mode = record.get("mode")
    if mode == "WORLD":
        scene, world = record.get("scene"), record.get("world")
        _drop_record(obj)
        # The scene's world goes when no other object in WORLD mode still shares it.
        scene_record = scene.get(WORLD_RECORD) if scene is not None else None
        if scene_record is not None and scene_record.get("world") == world:
            sharing = any(
                (record_of(other) or {}).get("world") == world for other in bpy.data.objects
            )
            if not sharing:
                detach_world(scene)
        return

    slots = [(state["link"], state.get("material")) for state in record.get("slots", [])]
    copies = list(record.get("copies", []))
    group = record.get("group")
    added_slot = bool(record.get("added_slot"))
    _drop_record(obj)

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
        remove_unused_groups(group)


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
        if not USE_NODES_DEPRECATED:
            copy.use_nodes = True
        fallback = tuple(copy.diffuse_color)
    else:
        copy = source.copy()
        copy.name = f"{source.name} [VR {obj.name}]"
        fallback = tuple(source.diffuse_color)
        if not USE_NODES_DEPRECATED and not copy.use_nodes:
            _nodes_from_settings(copy)
    copy[CREATED] = "material"
    _wire(copy.node_tree, mode, group, strength, ior, fallback, occluder(obj))
    if mode in WHOLE_SURFACE_LOOKS and hasattr(copy, "cycles"):
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
        tree = mat.node_tree if (USE_NODES_DEPRECATED or mat.use_nodes) else None
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


# --- library overrides across save and open ----------------------------------------------------
# An override's own settings (Reflect the Plate, its screen bounds) are not kept either:
# Blender 5.x records the settings' pointer as a whole and cannot apply it when the file
# opens. So they travel in the override's record in its scene too.


@bpy.app.handlers.persistent
def _keep_override_settings(*_args):
    for scene in bpy.data.scenes:
        for entry in scene.get(OVERRIDE_RECORDS, ()):
            obj = entry.get("object")
            if obj is not None:
                settings = obj.virtual_reflections
                entry["settings"] = {
                    "enabled": settings.enabled,
                    "bounds": list(settings.bounds),
                }


@bpy.app.handlers.persistent
def _restore_override_settings(*_args):
    for scene in bpy.data.scenes:
        for entry in scene.get(OVERRIDE_RECORDS, ()):
            obj, kept = entry.get("object"), entry.get("settings")
            if obj is not None and kept is not None and obj.is_editable:
                obj.virtual_reflections.enabled = bool(kept.get("enabled", False))
                obj.virtual_reflections.bounds = tuple(kept.get("bounds", (0.0,) * 4))


_HANDLERS = (("save_pre", _keep_override_settings), ("load_post", _restore_override_settings))


def register():
    app_handlers.add(_HANDLERS)


def unregister():
    app_handlers.remove(_HANDLERS)
