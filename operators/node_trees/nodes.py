"""Small helpers for the shader node trees the add-on builds (shading.py, ground_nodes.py).

Groups are found by the flag ``images.CREATED`` (their kind), never by name, so a user's group
with the same name is left alone; a group made by an older version of the add-on (another
``vr_version``) is emptied and rebuilt.
"""

import bpy

from ..scene.images import CREATED

USE_NODES_DEPRECATED = bpy.app.version >= (5, 0, 0)  # 5.x: node trees always on
GROUP_VERSION = 1  # bump when the lookup groups' contents change; old ones are rebuilt


def find_or_new_group(name, kind, version=GROUP_VERSION):
    """Our group of this kind (emptied when made by another version), or a new empty one."""
    for group in bpy.data.node_groups:
        if group.get(CREATED) == kind and group.library is None:
            if group.get("vr_version") != version:
                group.nodes.clear()
                group.interface.clear()
                group["vr_version"] = version
            return group
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group[CREATED] = kind
    group["vr_version"] = version
    return group


def new_node(nodes, bl_idname, name, location):
    """A new node named and labelled ``name`` at ``location``."""
    made = nodes.new(bl_idname)
    made.name = made.label = name
    made.location = location
    return made


def link_or_set(links, socket, value):
    """Link ``value`` into ``socket`` when it is a socket, else set the socket's value."""
    if isinstance(value, bpy.types.NodeSocket):
        links.new(value, socket)
    else:
        socket.default_value = value


def math_node(nodes, links, operation, name, location, *inputs):
    """A Math node; each input is a socket to link or a number to set. Returns its output."""
    made = new_node(nodes, "ShaderNodeMath", name, location)
    made.operation = operation
    for socket, value in zip(made.inputs, inputs):
        link_or_set(links, socket, value)
    return made.outputs["Value"]


def vector_math_node(nodes, links, operation, name, location, *inputs):
    """A Vector Math node; inputs as for `math_node` (a float for SCALE's scale). Returns its
    "Vector" output (or "Value" for DOT_PRODUCT / LENGTH)."""
    made = new_node(nodes, "ShaderNodeVectorMath", name, location)
    made.operation = operation
    sockets = [made.inputs[0], made.inputs["Scale" if operation == "SCALE" else 1]]
    for socket, value in zip(sockets, inputs):
        link_or_set(links, socket, value)
    if operation in ("DOT_PRODUCT", "LENGTH", "DISTANCE"):
        return made.outputs["Value"]
    return made.outputs["Vector"]


def view_ray(nodes, links):
    """The "Geometry" node and the Vector Math node "View Ray" made from it: the direction
    the camera (or reflected) ray travels, -Incoming (both at the left of the tree)."""
    geometry = new_node(nodes, "ShaderNodeNewGeometry", "Geometry", (-900, 300))
    view = new_node(nodes, "ShaderNodeVectorMath", "View Ray", (-700, 300))
    view.operation = "SCALE"
    view.inputs["Scale"].default_value = -1.0
    links.new(geometry.outputs["Incoming"], view.inputs[0])
    return geometry, view
