"""The ground per shading point: what a mirror's lower half shows, looked up in the node tree.

A lat-long map is seen from one point, the object's centre; the ground around the object is
a few metres away, so from a point of the surface a radius off the centre it lies at another
angle (parallax), most near the contact. In the Replace, Modulate and Mix looks the material
follows each reflected ray instead (Camera View + Ground, docs/ground.md):

    P the shading point, R the reflected direction (world space, +Z up)
    t = (ground - P.z) / R.z        the ray meets the ground plane (R.z < 0, t > 0)
    G = P + t R  --Vector Transform (point, World -> Camera)-->  (x, y, z), z forward
    u = cx/W + (fx/W) x / z,  v = (1 - cy/H) + (fy/H) y / z   the plate's texture coordinates

and reads the plate there. Its weight is 1 where G is on the plate, falls (smoothstep) to 0
at `MARGIN` of the plate's height past the nearest border, and is 0 where the ray does not
meet the ground in front of the camera; the map (the camera view with the world's horizon)
fills the rest. The render camera's transform is applied at render time (as for the map),
so a moving object or camera needs no new lookup; the lens (fx, fy, cx, cy) is the one at
Generate.

The plate was shot without the object, so the ground it shows is lit as if the object were
not there; in the render the object hides part of the sky from the ground around it (its
contact shadow), which is what a mirror's lowest part reflects. `ensure_occlusion_group`
darkens the ground point G by the share of its sky the object hides, the object taken as the
ellipsoid in its bounding box (a sphere's is exact) under an even sky:

    q = (G in object space - box centre) / box half size     (|q| = 1 on the ellipsoid)
    d = box centre in world space - G,  cos = d.z / |d|
    F = min(1, max(cos, 0) / |q|^2)       a sphere's form factor, (r / |d|)^2 cos, with
                                          r = |d| / |q| the ellipsoid's radius toward G
    ground x (1 - k F)                    k: the artist's Contact Shadow (1: the model; 0: off,
                                          for a plate that already shows the object's shadow)

Taken in the object's space, it follows the object at render time as the lookup does.
"""

from dataclasses import dataclass

from .nodes import find_or_new_group, link_or_set, math_node, new_node, vector_math_node

GROUND_GROUP = "VR Ground"
OCCLUSION_GROUP = "VR Ground Occlusion"
SHADOW_NODE = "VR Contact Shadow"  # the Value node holding GroundLookup.shadow
MARGIN = 0.25  # plate heights past the border over which the ground fades (as ground.py)
_VERSION = 1


@dataclass(frozen=True)
class GroundLookup:
    """The ground plane a material looks up per shading point.

    plate: the plate (bpy Image) the camera saw the ground in; height: the ground's world
    height (Z); focal: (fx / W, fy / H) and centre: (cx / W, 1 - cy / H), the camera's
    intrinsics over the plate's size W x H in texture coordinates (v up; docs/conventions.md);
    aspect: W / H; frames: for an image sequence or movie plate, (frame_duration,
    frame_start, frame_offset, cyclic) of its image user, else None; shadow: the contact
    shadow's strength, 0..1 (the module's k).
    """

    plate: object
    height: float
    focal: tuple
    centre: tuple
    aspect: float
    frames: tuple | None = None
    shadow: float = 1.0

    def signature(self) -> str:
        """A string that changes when anything the node tree holds changes."""
        values = (self.height, *self.focal, *self.centre, self.aspect, self.shadow)
        rounded = ",".join(f"{v:.6g}" for v in values)
        return f"{self.plate.name}|{rounded}|{self.frames}|occlusion"


def occluder(obj) -> tuple:
    """(centre, half size) of ``obj``'s bounding box in its own space: the ellipsoid that
    hides the sky from the ground around it (`ensure_occlusion_group`); a zero half size, for
    an object without a box, hides nothing."""
    corners = [tuple(c) for c in getattr(obj, "bound_box", ())]
    if not corners:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    low = [min(c[i] for c in corners) for i in range(3)]
    high = [max(c[i] for c in corners) for i in range(3)]
    centre = tuple((a + b) / 2 for a, b in zip(low, high))
    half = tuple((b - a) / 2 for a, b in zip(low, high))
    return centre, half


def ensure_ground_group():
    """The shader node group "VR Ground": where a ray from a point meets the ground, on the plate.

    Inputs: ``Position`` and ``Direction`` (world space), ``Height`` (the ground's world Z),
    ``Focal`` (fx / W, fy / H, 0), ``Centre`` (cx / W, 1 - cy / H, 0): the principal point in
    texture coordinates, ``Aspect`` (W / H).
    Outputs: ``UV`` (the plate's texture coordinates of the ground point) and ``Weight`` (of
    the ground: 1 on the plate, 0 where the ray misses the ground or the point is far off it).
    """
    group = find_or_new_group(GROUND_GROUP, "ground", _VERSION)
    if group.nodes:
        return group
    _new_sockets(
        group.interface,
        inputs=(
            ("Focal", "NodeSocketVector"),
            ("Centre", "NodeSocketVector"),
            ("Aspect", "NodeSocketFloat"),
        ),
        outputs=(("UV", "NodeSocketVector"), ("Weight", "NodeSocketFloat")),
    )
    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-1400, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (1400, 0))
    r, t, hit = _ray_meets_ground(nodes, links, g_in)
    down = math_node(nodes, links, "LESS_THAN", "Ray Goes Down", (-1000, 0), r.outputs["Z"], -1e-6)
    ahead = math_node(nodes, links, "GREATER_THAN", "Ground Ahead", (-600, 300), t, 0.0)

    # The camera sees it at (x, y, z): renderer camera space, x right, y up, z forward.
    to_cam = new_node(nodes, "ShaderNodeVectorTransform", "World to Camera", (-200, 100))
    to_cam.vector_type = "POINT"
    to_cam.convert_from = "WORLD"
    to_cam.convert_to = "CAMERA"
    links.new(hit, to_cam.inputs["Vector"])
    c = new_node(nodes, "ShaderNodeSeparateXYZ", "Camera Point", (0, 100))
    links.new(to_cam.outputs["Vector"], c.inputs["Vector"])
    front = math_node(nodes, links, "GREATER_THAN", "In Front", (200, 300), c.outputs["Z"], 1e-4)
    sx = math_node(nodes, links, "DIVIDE", "x / z", (200, 150), c.outputs["X"], c.outputs["Z"])
    sy = math_node(nodes, links, "DIVIDE", "y / z", (200, 0), c.outputs["Y"], c.outputs["Z"])
    focal = new_node(nodes, "ShaderNodeSeparateXYZ", "Focal XY", (0, -150))
    links.new(g_in.outputs["Focal"], focal.inputs["Vector"])
    centre = new_node(nodes, "ShaderNodeSeparateXYZ", "Centre XY", (0, -300))
    links.new(g_in.outputs["Centre"], centre.inputs["Vector"])
    u = math_node(
        nodes, links, "MULTIPLY_ADD", "U", (400, 150), sx, focal.outputs["X"], centre.outputs["X"]
    )
    v = math_node(
        nodes, links, "MULTIPLY_ADD", "V", (400, 0), sy, focal.outputs["Y"], centre.outputs["Y"]
    )
    uv = new_node(nodes, "ShaderNodeCombineXYZ", "UV", (600, 100))
    links.new(u, uv.inputs["X"])
    links.new(v, uv.inputs["Y"])
    links.new(uv.outputs["Vector"], g_out.inputs["UV"])

    # Off the plate by max(|u - .5| - .5, 0) widths and max(|v - .5| - .5, 0) heights, in
    # plate heights; the ground fades out over MARGIN of them.
    off_u = _outside(nodes, links, u, "U", (600, -100))
    off_u = math_node(
        nodes, links, "MULTIPLY", "Outside U (heights)", (800, -100), off_u, g_in.outputs["Aspect"]
    )
    off_v = _outside(nodes, links, v, "V", (600, -300))
    outside = math_node(nodes, links, "MAXIMUM", "Outside", (1000, -200), off_u, off_v)
    fade = new_node(nodes, "ShaderNodeMapRange", "Fade", (1000, -400))
    fade.interpolation_type = "SMOOTHSTEP"
    fade.clamp = True
    links.new(outside, fade.inputs["Value"])
    fade.inputs["From Min"].default_value = 0.0
    fade.inputs["From Max"].default_value = MARGIN
    fade.inputs["To Min"].default_value = 1.0
    fade.inputs["To Max"].default_value = 0.0

    weight = math_node(nodes, links, "MULTIPLY", "Down And Ahead", (800, 300), down, ahead)
    weight = math_node(nodes, links, "MULTIPLY", "Seen", (1000, 300), weight, front)
    weight = math_node(
        nodes, links, "MULTIPLY", "Weight", (1200, 100), weight, fade.outputs["Result"]
    )
    links.new(weight, g_out.inputs["Weight"])
    return group


def _new_sockets(iface, inputs, outputs):
    """A ground group's interface: Position, Direction (world space) and Height (the ground's
    world Z), then ``inputs``; ``outputs``: (name, socket type) pairs."""
    ray = (("Position", "NodeSocketVector"), ("Direction", "NodeSocketVector"))
    for name, kind in (*ray, ("Height", "NodeSocketFloat"), *inputs):
        iface.new_socket(name, in_out="INPUT", socket_type=kind)
    for name, kind in outputs:
        iface.new_socket(name, in_out="OUTPUT", socket_type=kind)


def _ray_meets_ground(nodes, links, g_in):
    """Where the ray from the group input's Position along its Direction meets the plane
    Z = Height: t = (height - P.z) / R.z (meaningful for R.z < 0 and t > 0), G = P + t R.
    Returns (the Separate XYZ node of R, the t socket, the G socket)."""
    position, direction = g_in.outputs["Position"], g_in.outputs["Direction"]
    p = new_node(nodes, "ShaderNodeSeparateXYZ", "P", (-1200, 200))
    links.new(position, p.inputs["Vector"])
    r = new_node(nodes, "ShaderNodeSeparateXYZ", "R", (-1200, 0))
    links.new(direction, r.inputs["Vector"])
    rise = math_node(
        nodes, links, "SUBTRACT", "Ground Below", (-1000, 200), g_in.outputs["Height"],
        p.outputs["Z"],
    )  # fmt: skip
    t = math_node(nodes, links, "DIVIDE", "Distance", (-800, 200), rise, r.outputs["Z"])
    travel = vector_math_node(nodes, links, "SCALE", "Along Ray", (-600, 100), direction, t)
    hit = vector_math_node(nodes, links, "ADD", "Ground Point", (-400, 100), position, travel)
    return r, t, hit


def _outside(nodes, links, value, axis, location):
    """max(|value - 0.5| - 0.5, 0): how far a texture coordinate is outside [0, 1]."""
    x, y = location
    centred = math_node(nodes, links, "SUBTRACT", f"{axis} - 0.5", (x, y), value, 0.5)
    size = math_node(nodes, links, "ABSOLUTE", f"|{axis} - 0.5|", (x + 100, y), centred)
    past = math_node(nodes, links, "SUBTRACT", f"{axis} Past Edge", (x + 200, y), size, 0.5)
    return math_node(nodes, links, "MAXIMUM", f"{axis} Outside", (x + 300, y), past, 0.0)


def ensure_occlusion_group():
    """The shader node group "VR Ground Occlusion": how much of a ground point's sky the shaded
    object leaves (the module's docstring).

    Inputs: ``Position`` and ``Direction`` (world space) and ``Height`` as the ground group's
    (the ray meets the ground at G), ``Box Centre`` and ``Box Half Size`` (the object's
    bounding box in its own space; a zero half size hides nothing). A group of its own, so the
    ground group of files saved before it is untouched.
    Output: ``Sky`` (1 - the share hidden, 0..1).
    """
    group = find_or_new_group(OCCLUSION_GROUP, "ground occlusion", _VERSION)
    if group.nodes:
        return group
    _new_sockets(
        group.interface,
        inputs=(("Box Centre", "NodeSocketVector"), ("Box Half Size", "NodeSocketVector")),
        outputs=(("Sky", "NodeSocketFloat"),),
    )
    nodes, links = group.nodes, group.links
    g_in = new_node(nodes, "NodeGroupInput", "Group Input", (-1400, 0))
    g_out = new_node(nodes, "NodeGroupOutput", "Group Output", (1900, 0))
    # Where the ray misses the ground the ground group's weight is 0: never seen.
    _, _, point = _ray_meets_ground(nodes, links, g_in)

    local = new_node(nodes, "ShaderNodeVectorTransform", "World to Object", (100, 200))
    local.vector_type, local.convert_from, local.convert_to = "POINT", "WORLD", "OBJECT"
    links.new(point, local.inputs["Vector"])
    q = vector_math_node(
        nodes,
        links,
        "SUBTRACT",
        "From Centre",
        (300, 200),
        local.outputs["Vector"],
        g_in.outputs["Box Centre"],
    )
    q = vector_math_node(
        nodes, links, "DIVIDE", "In Box Halves", (500, 200), q, g_in.outputs["Box Half Size"]
    )
    q2 = vector_math_node(nodes, links, "DOT_PRODUCT", "|q|^2", (700, 200), q, q)

    centre = new_node(nodes, "ShaderNodeVectorTransform", "Centre in World", (100, -100))
    centre.vector_type, centre.convert_from, centre.convert_to = "POINT", "OBJECT", "WORLD"
    links.new(g_in.outputs["Box Centre"], centre.inputs["Vector"])
    d = vector_math_node(
        nodes, links, "SUBTRACT", "To Centre", (300, -100), centre.outputs["Vector"], point
    )
    unit = vector_math_node(nodes, links, "NORMALIZE", "To Centre Unit", (500, -100), d)
    up = new_node(nodes, "ShaderNodeSeparateXYZ", "Up Share", (700, -100))
    links.new(unit, up.inputs["Vector"])
    cos = math_node(nodes, links, "MAXIMUM", "Cos", (900, -100), up.outputs["Z"], 0.0)
    # Safe divide: |q|^2 = 0 (a zero half size) gives 0, nothing hidden.
    share = math_node(nodes, links, "DIVIDE", "Form Factor", (1100, 0), cos, q2)
    share = math_node(nodes, links, "MINIMUM", "Hidden", (1300, 0), share, 1.0)
    sky = math_node(nodes, links, "SUBTRACT", "Sky", (1500, 0), 1.0, share)
    links.new(sky, g_out.inputs["Sky"])
    return group


def mix_ground(nodes, links, position, direction, colour, ground, location, boxes=(), sky=None):
    """The map's ``colour`` with the ground of ``ground`` (a GroundLookup) mixed in along the
    ray from ``position`` in ``direction`` (world-space sockets). ``boxes``: (centre, half size)
    of each object whose contact shadow darkens the ground (`occluder`; each a socket or a
    value, in the space of the object the material is on); ``sky``: a float socket, the share
    of the ground point's sky left (the ground is multiplied by it), or None. Returns the
    colour socket."""
    x, y = location
    lookup = new_node(nodes, "ShaderNodeGroup", GROUND_GROUP, (x, y))
    lookup.node_tree = ensure_ground_group()
    links.new(position, lookup.inputs["Position"])
    links.new(direction, lookup.inputs["Direction"])
    lookup.inputs["Height"].default_value = ground.height
    lookup.inputs["Focal"].default_value = (*ground.focal, 0.0)
    lookup.inputs["Centre"].default_value = (*ground.centre, 0.0)
    lookup.inputs["Aspect"].default_value = ground.aspect

    plate = new_node(nodes, "ShaderNodeTexImage", "VR Ground Plate", (x + 200, y))
    plate.image = ground.plate
    plate.interpolation = "Linear"
    plate.extension = "EXTEND"
    if ground.frames is not None:
        duration, start, offset, cyclic = ground.frames
        user = plate.image_user
        user.frame_duration, user.frame_start, user.frame_offset = duration, start, offset
        user.use_cyclic, user.use_auto_refresh = cyclic, True
    links.new(lookup.outputs["UV"], plate.inputs["Vector"])
    seen = plate.outputs["Color"]
    if sky is not None:
        seen = vector_math_node(nodes, links, "SCALE", "Ground Lit", (x + 400, y - 150), seen, sky)
    if boxes:
        strength = new_node(nodes, "ShaderNodeValue", SHADOW_NODE, (x, y - 200))
        strength.outputs[0].default_value = ground.shadow
    for k, box in enumerate(boxes):
        at = (x + 200, y - 300 - 250 * k)
        shade = new_node(nodes, "ShaderNodeGroup", OCCLUSION_GROUP, at)
        shade.node_tree = ensure_occlusion_group()
        links.new(position, shade.inputs["Position"])
        links.new(direction, shade.inputs["Direction"])
        shade.inputs["Height"].default_value = ground.height
        for name, value in zip(("Box Centre", "Box Half Size"), box):
            link_or_set(links, shade.inputs[name], value)
        # 1 - k (1 - Sky): the hidden share times the artist's strength
        hidden = math_node(
            nodes, links, "SUBTRACT", "Hidden", (x + 350, at[1]), 1.0, shade.outputs["Sky"]
        )
        hidden = math_node(
            nodes, links, "MULTIPLY", "Hidden x Strength", (x + 500, at[1]), hidden,
            strength.outputs[0],
        )  # fmt: skip
        left = math_node(nodes, links, "SUBTRACT", "Sky Left", (x + 650, at[1]), 1.0, hidden)
        seen = vector_math_node(
            nodes, links, "SCALE", "Ground Shaded", (x + 800, at[1] + 150), seen, left
        )

    # colour + weight (plate - colour)
    step = vector_math_node(nodes, links, "SUBTRACT", "Ground - Map", (x + 400, y), seen, colour)
    step = vector_math_node(
        nodes, links, "SCALE", "Ground Share", (x + 550, y), step, lookup.outputs["Weight"]
    )
    return vector_math_node(nodes, links, "ADD", "Map And Ground", (x + 700, y), colour, step)
