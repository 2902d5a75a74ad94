"""Set a scene up to render over its plate, and undo it: render size, camera background,
transparent film, and the compositor putting the render over the plate.

The compositor API changed in Blender 5.0, and `setup_from_plate` handles both:

- 4.5: the scene owns an embedded tree, ``scene.node_tree``, switched on by ``scene.use_nodes``;
  the result is the Composite node. Our nodes (named "VR ...") are added to the user's tree and
  the Composite input is routed through our Alpha Over.
- 5.x: the compositor is a node-group datablock (type 'CompositorNodeTree') assigned to
  ``scene.compositing_node_group``; there is no Composite node, the result is the first Image
  input of the active Group Output; ``scene.use_nodes`` is deprecated and ignored. We assign our
  own group "VR Composite"; the user's previous group (if any) is nested in it as a group node
  whose output is the foreground, so their node setup keeps working underneath the plate. Our
  group always has a top-level Render Layers node: Blender renders the scene for the compositor
  only when one is there (nested ones do not count).
  Alpha Over's inputs are named Background / Foreground there (4.5: Image / Image_001).

The plate reaches the compositor's background through a Scale node set to the render size
(Stretch), as Blender's own Setup Tracking Scene does: at a Resolution % other than 100 the
compositor works at the render's size, and an unscaled plate would be cropped to its centre.

Colour management: the composite's background must be the photograph again when saved. The
render's view transform applies to the whole composite, plate included, so a view transform
that tone-maps (AgX, the default since Blender 4.0; Filmic; Khronos PBR Neutral) or a look,
exposure, gamma, curves or white balance repaints the plate (AgX: 17-23 8-bit levels off on
average, less saturated). Setup sets the view to Standard on an sRGB display with none of
those, the one view that gives an sRGB plate's codes back (within 0.15 levels);
`VIEW_SETTINGS` lists what is recorded and restored, and `setup_from_plate` returns what it
changed so the operator can say.

Everything `setup_from_plate` changes is recorded as JSON in ``scene[RECORD]``;
`undo_setup_from_plate` restores it and removes only what setup added.
"""

import contextlib
import json

import bpy

from ..virtual_reflections.frames import sequence_range
from .node_trees.nodes import USE_NODES_DEPRECATED, new_node
from .scene import bounds, camera_match, plate
from .scene.images import CREATED

RECORD = "vr_plate_setup"  # scene custom property: what setup_from_plate changed (JSON)
GROUP_NAME = "VR Composite"  # the compositor node group setup makes (5.x)
GROUND_NAME = "VR Ground"  # the shadow-catcher plane setup makes (images.CREATED = GROUND_KIND)
GROUND_KIND = "ground"
PREFIX = "VR "  # every node this module adds is named with it

_NODE_GROUPS = "compositing_node_group" in bpy.types.Scene.bl_rna.properties  # 5.0+
_API = "compositing_node_group" if _NODE_GROUPS else "node_tree"  # the record's name for it

# The view settings that give an sRGB plate's codes back: (settings, property, value). Only the
# properties this Blender has are touched (white balance is 4.2+).
VIEW_SETTINGS = (
    # The saved file follows the scene's view, not an output override of its own.
    ("render.image_settings", "color_management", "FOLLOW_SCENE"),
    ("display_settings", "display_device", "sRGB"),
    ("view_settings", "view_transform", "Standard"),
    ("view_settings", "look", "None"),
    ("view_settings", "exposure", 0.0),
    ("view_settings", "gamma", 1.0),
    ("view_settings", "use_curve_mapping", False),
    ("view_settings", "use_white_balance", False),
)


# --- scene setup -------------------------------------------------------------------------------


def setup_from_plate(scene, image, ground=False, lens=False, view=True) -> dict:
    """Set `scene` up to render over the plate `image`; returns the record of what changed.

    Render size = the plate's (100 %), pixel aspect 1, transparent film, compositing on; the plate
    shown as the scene camera's background image (an existing entry for it is reused; skipped
    without a camera); the compositor puts the render over the plate (Image -> Alpha Over
    background, the render -> foreground -> output, and a Viewer). Nothing of the user's is
    deleted. Calling it again first undoes the previous setup, so nothing stacks and
    `undo_setup_from_plate` still returns to the state before the first call.

    The scene's colour management is set to give the plate back (`VIEW_SETTINGS`; what changed
    is ``record["view"]``); with ``view`` False (the batch) the view the artist chose is kept.
    With ``ground``, a shadow-catcher plane is put under the scene's
    visible meshes (`add_ground`) unless the scene has a ground already. With ``lens``, the
    camera's focal length is set from the photo's 35 mm-equivalent focal length when its
    metadata has one (scene/camera_match.py). ``record["advice"]`` says how to match the camera
    to the photo, and warns when the camera was framed for another aspect.
    """
    width, height = plate.size(image)
    if RECORD in scene:
        undo_setup_from_plate(scene)
    render = scene.render
    record = {
        "version": 1,
        "api": _API,
        "image": image.name,
        "resolution": [render.resolution_x, render.resolution_y, render.resolution_percentage],
        "pixel_aspect": [render.pixel_aspect_x, render.pixel_aspect_y],
        "film_transparent": render.film_transparent,
        "use_compositing": render.use_compositing,
    }
    render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.film_transparent = True
    render.use_compositing = True
    record["view"] = _neutral_view(scene) if view else {}
    record["camera"] = _show_background(scene.camera, image)
    record["ground"] = add_ground(scene) if ground else None
    record["lens"] = camera_match.match_lens(scene.camera, image, width, height) if lens else None
    framed = (
        record["resolution"][0] * record["pixel_aspect"][0],
        record["resolution"][1] * record["pixel_aspect"][1],
    )
    record["advice"] = camera_match.advice(image, framed, record["lens"]) + eevee_advice(scene)
    record["compositor"] = _setup_compositor(scene, image)
    scene[RECORD] = json.dumps(record)
    return record


def plate_for_batch(scene, image) -> dict:
    """The batch's set-up: a shot the artist Set Up From Plate keeps that set-up (view
    transform, ground, lens, their compositor) and only takes `image` as its plate (camera
    background, the compositor's plate node, the render size); a shot never set up is set up
    without touching its view transform. Returns the record, as `setup_from_plate` does.

    The record keeps what the scene was before the artist's Set Up, so Undo Plate Set-Up in
    a file the batch saved still goes back to that."""
    if RECORD not in scene:
        return setup_from_plate(scene, image, view=False)
    record = json.loads(scene[RECORD])
    if record["api"] != _API:  # set up under the other compositor API: do it again here
        kept = {key: record.get(key) for key in ("ground", "view", "lens")}
        record.update(ground=None, view={}, lens=None)  # the undo below must not touch them
        scene[RECORD] = json.dumps(record)
        record = setup_from_plate(scene, image, view=False)
        record.update(kept)
        scene[RECORD] = json.dumps(record)
        return record
    camera = record["camera"]
    _undo_background(camera, record["image"])
    _undo_compositor(scene, record["compositor"])
    width, height = plate.size(image)
    scene.render.resolution_x, scene.render.resolution_y = width, height
    record["image"] = image.name
    record["camera"] = _show_background(scene.camera, image)
    if camera is not None and record["camera"] is not None:  # what the artist had before
        record["camera"]["show_background_images"] = camera["show_background_images"]
    record["compositor"] = _setup_compositor(scene, image)
    scene[RECORD] = json.dumps(record)
    return record


def undo_setup_from_plate(scene) -> bool:
    """Restore what `setup_from_plate` changed on `scene`; False if there is nothing to undo.

    Removes only what setup added (nodes, the group, the background entry). In 4.5 the scene's
    embedded tree stays once created (it cannot be deleted); with ``use_nodes`` restored it is
    inert. A record written by the other compositor API (a file set up in 4.5, undone in 5.x or
    the reverse) restores everything except the compositor.
    """
    if RECORD not in scene:
        return False
    record = json.loads(scene[RECORD])
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = record["resolution"]
    render.pixel_aspect_x, render.pixel_aspect_y = record["pixel_aspect"]
    render.film_transparent = record["film_transparent"]
    render.use_compositing = record["use_compositing"]
    _undo_view(scene, record.get("view", {}))
    _undo_background(record["camera"], record["image"])
    _remove_ground(record.get("ground"))
    camera_match.undo_lens(record.get("lens"), bpy.data.cameras)
    if record["api"] == _API:
        _undo_compositor(scene, record["compositor"])
    del scene[RECORD]
    return True


def _setup_compositor(scene, image) -> dict:
    """The render over the plate in this Blender's compositor API; returns its record."""
    return _setup_group(scene, image) if _NODE_GROUPS else _setup_tree(scene, image)


def _undo_compositor(scene, record) -> None:
    """Undo `_setup_compositor` (a record of this Blender's API)."""
    if _NODE_GROUPS:
        _undo_group(scene, record)
    else:
        _undo_tree(scene, record)


def _neutral_view(scene):
    """Set the scene's colour management to `VIEW_SETTINGS`; returns {"settings.property":
    previous value} of what it changed (nothing when the file already had them)."""
    wanted = [
        (_owner(scene, o), o, n, v) for o, n, v in VIEW_SETTINGS if hasattr(_owner(scene, o), n)
    ]
    # Read everything first: a new display can change the view transform by itself.
    changed = {f"{o}.{n}": getattr(s, n) for s, o, n, v in wanted if getattr(s, n) != v}
    for settings, _path, name, value in wanted:  # the display first: it decides the views
        setattr(settings, name, value)
    return changed


def _owner(scene, path):
    """The settings struct at dotted ``path`` under ``scene`` ("render.image_settings")."""
    for name in path.split("."):
        scene = getattr(scene, name)
    return scene


def _undo_view(scene, changed):
    """Put back what `_neutral_view` changed, display first; a value this Blender no longer
    offers (a view from another OCIO config) is left as it is."""
    for key, value in changed.items():
        owner, name = key.rsplit(".", 1)
        with contextlib.suppress(TypeError, AttributeError):
            setattr(_owner(scene, owner), name, value)


def view_warning(scene) -> str | None:
    """One line when ``scene`` was set up from a plate and its view no longer gives the plate
    back (the artist changed it since), else None: the panel shows it."""
    if RECORD not in scene:
        return None
    for owner, name, value in VIEW_SETTINGS[:4]:  # output, display, view transform, look
        current = getattr(_owner(scene, owner), name, value)
        if current != value:
            what = name.replace("_", " ").capitalize()
            return f"{what} {current} repaints the plate in the composite ({value} keeps it)"
    return None


def describe_view(changed) -> str:
    """One phrase for the report: what `_neutral_view` changed ('' if nothing), e.g.
    "view transform AgX -> Standard"."""
    labels = {
        "render.image_settings.color_management": "output colour management",
        "view_settings.view_transform": "view transform",
        "display_settings.display_device": "display",
        "view_settings.look": "look",
        "view_settings.exposure": "exposure",
        "view_settings.gamma": "gamma",
        "view_settings.use_curve_mapping": "curves",
        "view_settings.use_white_balance": "white balance",
    }
    new = {f"{owner}.{name}": value for owner, name, value in VIEW_SETTINGS}
    parts = []
    for key, previous in changed.items():
        if isinstance(previous, bool):
            parts.append(f"{labels[key]} off")
        else:
            parts.append(f"{labels[key]} {previous} -> {new[key]}")
    return ", ".join(parts)


def add_ground(scene):
    """A shadow-catcher plane under the scene's visible meshes, so they do not float over the
    photograph: at the lowest point of their bounding boxes (Z = 0 without meshes), 10x their
    extent (at least 20 m) across, flagged ``is_shadow_catcher`` -- the ground
    `floor.ground_height` finds -- and tagged CREATED. Returns its record (the object's
    name), or None when the scene has a ground already (a chosen Ground object or a shadow
    catcher)."""
    if scene.virtual_reflections.ground_object is not None:
        return None
    meshes = [o for o in scene.objects if o.type == "MESH" and o.visible_get()]
    if any(getattr(o, "is_shadow_catcher", False) for o in meshes):
        return None
    depsgraph = bpy.context.evaluated_depsgraph_get()
    if meshes:
        boxes = [bounds.world_box(o, depsgraph) for o in meshes]
        low = [min(b[0][i] for b in boxes) for i in range(3)]
        high = [max(b[1][i] for b in boxes) for i in range(3)]
        centre = ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, low[2])
        size = max(20.0, 10.0 * max(high[0] - low[0], high[1] - low[1]))
    else:
        centre, size = (0.0, 0.0, 0.0), 20.0
    half = size / 2
    mesh = bpy.data.meshes.new(GROUND_NAME)
    mesh.from_pydata([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)],
                     [], [(0, 1, 2, 3)])  # fmt: skip
    mesh[CREATED] = GROUND_KIND
    obj = bpy.data.objects.new(GROUND_NAME, mesh)
    obj[CREATED] = GROUND_KIND
    obj.location = centre
    obj.is_shadow_catcher = True  # Cycles: shows only the shadows cast on it
    obj.data.materials.append(_ground_material())
    scene.collection.objects.link(obj)
    return {"object": obj.name}


def eevee_advice(scene) -> list[str]:
    """A warning for each visible shadow catcher EEVEE would draw as an opaque surface over
    the plate (no Holdout for EEVEE in its materials, as `add_ground`'s ground has) when the
    scene renders in EEVEE; else nothing."""
    if "EEVEE" not in scene.render.engine:
        return []
    return [
        f"Warning: EEVEE draws the shadow catcher '{o.name}' as an opaque surface over the "
        "plate: render in Cycles, or give its material a Holdout output for EEVEE"
        for o in scene.objects
        if getattr(o, "is_shadow_catcher", False) and o.visible_get() and not _holds_out(o)
    ]


def _holds_out(obj) -> bool:
    """True when every material of ``obj`` renders as a Holdout in EEVEE."""
    slots = [s.material for s in getattr(obj, "material_slots", ())]
    if not slots or None in slots:
        return False
    for material in slots:
        output = material.node_tree.get_output_node("EEVEE") if material.node_tree else None
        links = output.inputs["Surface"].links if output is not None else ()
        if not links or links[0].from_node.type != "HOLDOUT":
            return False
    return True


def _ground_material():
    """The ground's material, one output per engine: Cycles, the default grey diffuse (the
    shadow catcher's look in reflections and bounced light, as without a material); EEVEE,
    which has no shadow catcher and would draw an opaque grey floor over the plate, a Holdout
    (transparent film: the plate shows where the ground is, in F12 and Material Preview
    alike, without the contact shadow only Cycles catches). Tagged CREATED."""
    material = bpy.data.materials.new(GROUND_NAME)
    material[CREATED] = GROUND_KIND
    if not USE_NODES_DEPRECATED:
        material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    nodes.clear()
    shaders = (("CYCLES", "ShaderNodeBsdfDiffuse", 0), ("EEVEE", "ShaderNodeHoldout", -200))
    for target, kind, y in shaders:
        name = PREFIX + target.capitalize()
        shader = new_node(nodes, kind, name + " Ground", (0, y))
        output = new_node(nodes, "ShaderNodeOutputMaterial", name + " Output", (250, y))
        output.target = target
        links.new(shader.outputs[0], output.inputs["Surface"])
    return material


def _remove_ground(record):
    obj = bpy.data.objects.get(record["object"]) if record else None
    if obj is None or obj.get(CREATED) != GROUND_KIND:
        return
    mesh = obj.data
    bpy.data.objects.remove(obj)
    if mesh is None or mesh.get(CREATED) != GROUND_KIND or mesh.users:
        return
    materials = [m for m in mesh.materials if m is not None and m.get(CREATED) == GROUND_KIND]
    bpy.data.meshes.remove(mesh)
    for material in materials:
        if material.users == 0:
            bpy.data.materials.remove(material)


def _show_background(camera, image):
    """Show `image` as the camera's background; returns the record (None without a camera)."""
    if camera is None or camera.type != "CAMERA":
        return None
    data = camera.data
    entry = next((b for b in data.background_images if b.image == image), None)
    record = {
        "object": camera.name,
        "data": data.name,
        "show_background_images": data.show_background_images,
        "added": entry is None,
    }
    if entry is None:
        entry = data.background_images.new()
        entry.source = "IMAGE"
        entry.image = image
    else:
        record["entry"] = {"show_background_image": entry.show_background_image}
    entry.show_background_image = True
    data.show_background_images = True
    return record


def _undo_background(record, image_name):
    if record is None:
        return
    data = bpy.data.cameras.get(record["data"])
    if data is None:
        return
    data.show_background_images = record["show_background_images"]
    entries = [b for b in data.background_images if b.image and b.image.name == image_name]
    if not entries:
        return
    if record["added"]:
        entry = entries[-1]  # setup appended it: the last one
        entry.image = None  # removing the entry alone leaves the image's user count raised
        data.background_images.remove(entry)
    else:
        entries[0].show_background_image = record["entry"]["show_background_image"]


def _new_node(tree, kind, name, location):
    node = tree.nodes.new(kind)
    node.name = node.label = PREFIX + name
    node.location = location
    return node


def _plate_node(tree, image, location):
    node = _new_node(tree, "CompositorNodeImage", "Plate", location)
    node.image = image
    if image.source in {"MOVIE", "SEQUENCE"}:  # the whole clip from scene frame 1, refreshed
        count = image.frame_duration
        path = plate.disk_path(image)
        if image.source == "SEQUENCE" and path is not None:
            with contextlib.suppress(ValueError):  # no number in the name: Blender's count
                first, count = sequence_range(path)
                node.frame_offset = first - 1
        node.frame_duration = max(count, 1)
        node.use_auto_refresh = True
    return node


def _render_size(tree, plate, location):
    """A Scale node fed by `plate` stretching it to the render size (resolution x %), as
    Setup Tracking Scene does: without it any Resolution % but 100 crops the plate.

    Its filter must not read past the plate's edge, which is transparent: a bilinear scale
    to 200 % made the outer pixels 0.75 opaque (0.56 in the corners), the colour faded with
    them. 5.x: bilinear, the edge extended. 4.5 has no extension mode: nearest, which reads
    only pixels of the plate (exact at 200 %; a 50 % preview takes one pixel of four)."""
    scale = _new_node(tree, "CompositorNodeScale", "Plate To Render Size", location)
    if "Type" in scale.inputs:  # 5.x: the options are menu sockets
        scale.inputs["Type"].default_value = "Render Size"
        scale.inputs["Frame Type"].default_value = "Stretch"
        for axis in ("Extension X", "Extension Y"):  # 5.2 has them
            if axis in scale.inputs:
                scale.inputs[axis].default_value = "Extend"
    else:
        scale.space, scale.frame_method = "RENDER_SIZE", "STRETCH"
        if hasattr(scale, "interpolation"):  # 4.5; 4.2-4.4 have neither
            scale.interpolation = "NEAREST"
    tree.links.new(plate.outputs["Image"], scale.inputs["Image"])
    return scale


# 4.5: scene.node_tree with a Composite node.


def _setup_tree(scene, image):
    record = {
        "use_nodes": scene.use_nodes,
        "had_tree": scene.node_tree is not None,
        # Adding a Viewer creates Blender's "Viewer Node" image if there is none.
        "had_viewer_image": any(i.type == "COMPOSITING" for i in bpy.data.images),
    }
    scene.use_nodes = True  # creates the default tree (Render Layers -> Composite) if none
    tree = scene.node_tree
    record["active"] = tree.nodes.active.name if tree.nodes.active else None
    added = []
    composite = next((n for n in tree.nodes if n.type == "COMPOSITE" and not n.mute), None)
    if composite is None:
        composite = _new_node(tree, "CompositorNodeComposite", "Composite", (600, 0))
        added.append(composite.name)
    x, y = composite.location
    target = composite.inputs[0]
    previous = target.links[0].from_socket if target.is_linked else None
    record["composite"] = composite.name
    record["previous_link"] = (
        [previous.node.name, previous.identifier] if previous is not None else None
    )
    if previous is None:  # nothing fed the Composite: our own Render Layers is the foreground
        layers = _new_node(tree, "CompositorNodeRLayers", "Render Layers", (x - 600, y - 150))
        layers.scene = scene
        added.append(layers.name)
        previous = layers.outputs["Image"]
    plate = _plate_node(tree, image, (x - 800, y + 250))
    scale = _render_size(tree, plate, (x - 500, y + 250))
    over = _new_node(tree, "CompositorNodeAlphaOver", "Alpha Over", (x - 250, y + 100))
    viewer = _new_node(tree, "CompositorNodeViewer", "Viewer", (x, y + 250))
    added += [plate.name, scale.name, over.name, viewer.name]
    # 4.5 Alpha Over sockets: Fac, Image (background), Image_001 (foreground).
    background, foreground = _input(over, "Image"), _input(over, "Image_001")
    tree.links.new(scale.outputs["Image"], background)
    tree.links.new(previous, foreground)
    tree.links.new(over.outputs["Image"], target)  # replaces the previous link
    tree.links.new(over.outputs["Image"], viewer.inputs["Image"])
    tree.nodes.active = viewer  # the active Viewer is the one Blender shows
    record["added"] = added
    return record


def _input(node, identifier):
    return next(s for s in node.inputs if s.identifier == identifier)


def _undo_tree(scene, record):
    tree = scene.node_tree
    if tree is not None:
        composite = tree.nodes.get(record["composite"])
        previous = record["previous_link"]
        if composite is not None and previous is not None and _fed_by_us(composite.inputs[0]):
            node = tree.nodes.get(previous[0])
            outputs = node.outputs if node is not None else ()
            socket = next((s for s in outputs if s.identifier == previous[1]), None)
            if socket is not None:
                tree.links.new(socket, composite.inputs[0])
        for name in record["added"]:
            node = tree.nodes.get(name)
            if node is not None:
                tree.nodes.remove(node)
        active = tree.nodes.get(record["active"]) if record["active"] else None
        if active is not None:
            tree.nodes.active = active
    scene.use_nodes = record["use_nodes"]
    if not record["had_viewer_image"] and not _viewers_left():
        for image in [i for i in bpy.data.images if i.type == "COMPOSITING"]:
            bpy.data.images.remove(image)


def _fed_by_us(socket):
    """True unless the user has linked something else into `socket` since the setup."""
    return not socket.is_linked or socket.links[0].from_node.name.startswith(PREFIX)


def _viewers_left():
    trees = [s.node_tree for s in bpy.data.scenes if s.node_tree is not None]
    trees += list(bpy.data.node_groups)
    return any(n.type == "VIEWER" for t in trees for n in t.nodes)


# 5.x: scene.compositing_node_group, a node group whose Group Output is the result.


def _setup_group(scene, image):
    previous = scene.compositing_node_group
    group = bpy.data.node_groups.new(GROUP_NAME, "CompositorNodeTree")
    group[CREATED] = "compositor"
    group.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    output = group.nodes.new("NodeGroupOutput")
    output.location = (600, 0)
    # Blender renders the scene for the compositor only if the scene's compositor group has a
    # Render Layers node for it at its top level (render pipeline, compositor_needs_render():
    # nested groups are not searched), so ours is always there, even when the nested user
    # group's own Render Layers provides the foreground.
    layers = _new_node(group, "CompositorNodeRLayers", "Render Layers", (0, -150))
    layers.scene = scene
    foreground = layers.outputs["Image"]
    result = _image_output(previous) if previous is not None else None
    if result is not None:
        # The user's compositor, nested: its result is what goes over the plate.
        user = _new_node(group, "CompositorNodeGroup", "Previous Compositor", (0, -350))
        user.node_tree = previous
        foreground = next(s for s in user.outputs if s.identifier == result)
    plate = _plate_node(group, image, (-300, 250))
    scale = _render_size(group, plate, (0, 250))
    over = _new_node(group, "CompositorNodeAlphaOver", "Alpha Over", (350, 100))
    viewer = _new_node(group, "CompositorNodeViewer", "Viewer", (600, 250))
    group.links.new(scale.outputs["Image"], over.inputs["Background"])
    group.links.new(foreground, over.inputs["Foreground"])
    group.links.new(over.outputs["Image"], output.inputs[0])
    group.links.new(over.outputs["Image"], viewer.inputs["Image"])
    scene.compositing_node_group = group
    return {"previous_group": previous.name if previous else None, "group": group.name}


def _image_output(group):
    """The identifier of a group's result (its first colour output, as the compositor uses)."""
    for item in group.interface.items_tree:
        if item.item_type == "SOCKET" and item.in_out == "OUTPUT":
            if item.socket_type == "NodeSocketColor":
                return item.identifier
    return None


def _undo_group(scene, record):
    previous = record["previous_group"]
    group = bpy.data.node_groups.get(record["group"])
    if scene.compositing_node_group in (group, None):  # else the user has chosen another since
        scene.compositing_node_group = bpy.data.node_groups.get(previous) if previous else None
    if group is not None and group.get(CREATED) == "compositor":
        bpy.data.node_groups.remove(group)
