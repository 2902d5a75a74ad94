"""The world look: a NEW world "VR World" whose background is the map, so every glossy material
reflects the plate (shading.py's WORLD mode); `detach_world` restores the scene's previous world
and deletes only what `attach_world` made.

The world does not use Vector Transform: EEVEE evaluates the world for its light probes with the
probes' own views as "camera", which scrambles what materials reflect; drivers on
``scene.camera.matrix_world`` take the direction into the camera frame instead (shading.py).
"""

import bpy

from ..scene.images import CREATED, check_local
from .nodes import USE_NODES_DEPRECATED, math_node, new_node, view_ray
from .reflection_nodes import ensure_latlong_group, remove_unused_groups

WORLD_NAME = "VR World"


ENVIRONMENT_NODE = "VR Environment"  # the world's map node


WORLD_RECORD = "vr_world"  # on scenes: what attach_world() replaced


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
    check_local(scene, f"scene {scene.name!r}")
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
    if not USE_NODES_DEPRECATED:
        world.use_nodes = True
    tree = world.node_tree
    nodes, links = tree.nodes, tree.links
    nodes.clear()
    # In a world shader the camera (or reflected) ray travels along -Incoming.
    _, view = view_ray(nodes, links)

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
    remove_unused_groups()
