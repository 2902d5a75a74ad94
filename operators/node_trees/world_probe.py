"""The scene's world as the on-set HDRI (Surroundings: World HDRI).

When the artist lights the shot with the HDRI shot on set, the scene's world already holds what
no plate shows: the sky and the surroundings above and behind the camera, turned and exposed
the way the artist matched them. With Surroundings set to World HDRI, Camera View + Ground
takes that HDRI in place of its guessed sky (engine probe.py); the plate still gives all it
shows, the ground per shading point included.

The world is read, never changed: its one Environment Texture (equirectangular, an image
with pixels), turned by the Mapping nodes in front of it (rotation; a uniform scale), times the
Strength of the Background it feeds. In the World look the add-on's own world stands in the
scene's place; the world it replaced (the artist's) is the one read.
"""

from __future__ import annotations

import math

import numpy as np

from ...virtual_reflections.mapsize import WIDTHS
from ...virtual_reflections.probe import Probe, exposure_ratio, shrink_to
from ..scene import images
from .world import WORLD_RECORD

CAMERA_TO_LOCAL = np.diag([-1.0, 1.0, -1.0])  # the engine's camera frame -> Blender camera-local
STOPS_WARNED = 1.0  # a world this many stops off the plate's sky gets a warning
_read = {}  # the last HDRI's pixels read, by image, file, size, edits and strength
_probes = {}  # the last Probe made of them, by that and the camera's turn


def clear_cache():
    _read.clear()
    _probes.clear()


def user_world(scene):
    """The artist's world: the scene's, or the one the add-on's World look replaced."""
    record = scene.get(WORLD_RECORD)
    if record is not None and scene.world is not None and scene.world == record.get("world"):
        return record.get("previous")
    return scene.world


def _euler(rotation) -> np.ndarray:
    """Blender's XYZ Euler rotation matrix (X first, then Y, then Z)."""
    x, y, z = (float(a) for a in rotation)
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _unlinked(node, *names):
    for name in names:
        socket = node.inputs.get(name)
        if socket is not None and socket.is_linked:
            raise ValueError(
                f"the world's Mapping node '{node.name}' has its {name} driven by other nodes: "
                "set the HDRI's turn as plain values"
            )


def _mapping(node) -> np.ndarray:
    """The turn a Mapping node gives a direction, world -> image frame (3, 3)."""
    _unlinked(node, "Rotation", "Scale", "Location")
    kind = node.vector_type
    rotation = _euler(node.inputs["Rotation"].default_value)
    scale = np.array(node.inputs["Scale"].default_value, np.float64)
    if not (np.allclose(scale, scale[0]) and scale[0] > 0):
        raise ValueError(
            f"the world's Mapping node '{node.name}' scales unevenly or mirrors: "
            "only a turn (and an even scale) is understood"
        )
    if kind in ("POINT", "TEXTURE"):
        location = node.inputs.get("Location")
        if location is not None and any(abs(v) > 1e-6 for v in location.default_value):
            raise ValueError(
                f"the world's Mapping node '{node.name}' moves the directions (Location): "
                "only a turn is understood"
            )
    return rotation.T if kind == "TEXTURE" else rotation


def _turn(environment) -> np.ndarray:
    """World direction -> the image's frame, from the nodes in front of the texture's Vector."""
    turn = np.eye(3)
    socket = environment.inputs["Vector"]
    while socket.is_linked:
        link = socket.links[0]
        node = link.from_node
        if node.bl_idname == "ShaderNodeMapping":
            turn = turn @ _mapping(node)
            socket = node.inputs["Vector"]
        elif node.bl_idname == "ShaderNodeTexCoord" and link.from_socket.name == "Generated":
            break
        elif node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
        else:
            raise ValueError(
                f"the world's HDRI reads its directions through '{node.name}': only Mapping "
                "nodes and a Texture Coordinate's Generated output are understood"
            )
    return turn


def _strength(environment) -> float:
    """The Strength of the Background the texture's Color feeds directly (else 1)."""
    for link in environment.outputs["Color"].links:
        node = link.to_node
        if node.bl_idname == "ShaderNodeBackground" and not node.inputs["Strength"].is_linked:
            return float(node.inputs["Strength"].default_value)
    return 1.0


def environment_node(world):
    """The world's one Environment Texture with an image (ValueError, one line, otherwise)."""
    if world is None:
        raise ValueError("Surroundings World HDRI: the scene has no world")
    tree = world.node_tree if getattr(world, "node_tree", None) is not None else None
    found = [
        node
        for node in (tree.nodes if tree is not None else ())
        if node.bl_idname == "ShaderNodeTexEnvironment" and node.image is not None and not node.mute
    ]
    if not found:
        raise ValueError(
            f"Surroundings World HDRI: world '{world.name}' has no Environment Texture with an "
            "image"
        )
    if len(found) > 1:
        linked = [node for node in found if node.outputs["Color"].is_linked]
        if len(linked) != 1:
            raise ValueError(
                f"Surroundings World HDRI: world '{world.name}' has {len(found)} Environment "
                "Textures: keep one"
            )
        found = linked
    node = found[0]
    if node.projection != "EQUIRECTANGULAR":
        raise ValueError(
            f"Surroundings World HDRI: '{node.image.name}' is a mirror ball; only an "
            "equirectangular HDRI is read"
        )
    return node


def world_probe(scene, projection) -> Probe:
    """The artist's world HDRI as an engine Probe seen from ``scene``'s camera
    (``projection``: bounds.CameraProjection). ValueError (one line) when it cannot be read."""
    node = environment_node(user_world(scene))
    image = node.image
    try:
        width, height = image.size
        if not image.has_data:
            image.reload()
            width, height = image.size
    except RuntimeError as exc:
        raise ValueError(f"Surroundings World HDRI: '{image.name}' cannot be read: {exc}") from None
    if not image.has_data or width == 0 or height == 0:
        raise ValueError(f"Surroundings World HDRI: '{image.name}' has no pixels (missing file?)")
    strength = _strength(node)
    key = (image.as_pointer(), image.filepath, width, height, image.is_dirty, strength)
    pixels = _read.get(key)
    if pixels is None:  # read once: Live Update rebuilds many times a second
        linear, _ = images.read_linear(image)
        linear = np.nan_to_num(linear, nan=0.0, posinf=0.0, neginf=0.0)
        pixels = (np.maximum(linear, 0.0) * np.float32(strength)).astype(np.float32)
        del linear
        # No map is wider than WIDTHS[-1]: an 8K HDRI is kept at that width (a quarter of it).
        pixels = shrink_to(pixels, WIDTHS[-1])
        _read.clear()
        _read[key] = pixels
    camera_to_world = projection.world_to_camera[:3, :3].T
    rotation = _turn(node) @ camera_to_world @ CAMERA_TO_LOCAL
    u, _, vt = np.linalg.svd(rotation)  # the camera's matrix may hold rounding: the nearest turn
    rotation = np.round(u @ vt, 9)
    turned = (key, rotation.tobytes())
    probe = _probes.get(turned)
    if probe is None:  # the same HDRI from the same camera: its resampled maps are kept
        _probes.clear()
        probe = _probes[turned] = Probe(pixels, rotation, key=turned)
    return probe


def exposure_warning(probe: Probe, plate, params) -> str | None:
    """A line for the report when the world is far off the plate where both show the
    surroundings above the horizon (probe.exposure_ratio), else None."""
    if params.intrinsics is None or params.up is None:
        return None
    ratio = exposure_ratio(plate, params.intrinsics, params.up, probe)
    if ratio is None or abs(math.log2(ratio)) < STOPS_WARNED:
        return None
    way = "darker" if ratio > 1 else "brighter"
    return (
        f"Surroundings World HDRI: the world is {abs(math.log2(ratio)):.1f} stops {way} than "
        "the plate where both show the sky: check the world's Strength"
    )
