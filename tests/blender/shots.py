"""Small scenes the bpy tests share: a camera on -Y looking along +Y (Z up), and plates."""

import importlib.util
import math
import pathlib
import sys

import bpy
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
PACKAGE = "vr_addon_under_test"  # the repository, imported as an extension package


def load_addon():
    """Import the repository as an extension package (once per process), the way Blender loads
    an extension: its relative imports and `__package__` work."""
    if PACKAGE in sys.modules:
        return sys.modules[PACKAGE]
    spec = importlib.util.spec_from_file_location(
        PACKAGE, ROOT / "__init__.py", submodule_search_locations=[str(ROOT)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[PACKAGE] = module
    spec.loader.exec_module(module)
    return module


def addon_part(name):
    """A submodule of the add-on, e.g. ``addon_part("operators.generate")`` (imported if needed)."""
    load_addon()
    return importlib.import_module(f"{PACKAGE}.{name}")


def add_camera(scene=None, distance=6.0, size=None):
    """A camera at (0, -distance, 0) looking along +Y with Z up, made the scene's camera;
    ``size`` (width, height) sets the render resolution at 100 %. Returns the camera object."""
    scene = scene or bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -distance, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    if size is not None:
        scene.render.resolution_x, scene.render.resolution_y = size
        scene.render.resolution_percentage = 100
    return cam


def ramp_plate(width=96, height=64, name="Plate"):
    """A float plate: left half red, right half blue, green rising left to right (every
    column differs, so a move shows in the map)."""
    plate = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
    px = np.zeros((height, width, 4), np.float32)
    px[..., 3] = 1
    px[:, : width // 2, 0] = 1.0
    px[:, width // 2 :, 2] = 1.0
    px[:, :, 1] = np.linspace(0, 1, width)[None, :]
    plate.pixels.foreach_set(px.ravel())
    return plate


def project_points(bounds, points_world, scene, camera_obj=None):
    """(N, 3) world points -> ((N, 2) float64 plate pixels (px, py), (N,) bool in front), through
    ``bounds`` (operators/scene/bounds.py) and the scene camera (or ``camera_obj``). In front means
    beyond the near plane (depth >= clip_start); rows not in front are NaN."""
    projection = bounds.camera_projection(scene, camera_obj)
    cam = projection.to_camera(np.asarray(points_world, dtype=np.float64).reshape(-1, 3).T)
    in_front = -cam[2] >= projection.clip_start
    pixels = np.full((len(in_front), 2), np.nan)
    pixels[in_front] = np.stack(projection.to_pixels(*projection.frame_coords(cam[:, in_front])), 1)
    return pixels, in_front


_SKIPPED_NODE_PROPS = {"rna_type", "select", "dimensions"}  # UI state, not shading


def node_tree_signature(tree):
    """A comparable description of a node tree: per node (by name) its type, settings, socket
    default values and referenced datablocks; and every link. Equal signatures mean the trees
    render the same."""
    if tree is None:
        return None
    nodes = {}
    for node in tree.nodes:
        props = {}
        for prop in node.bl_rna.properties:
            key = prop.identifier
            if key in _SKIPPED_NODE_PROPS or prop.type == "COLLECTION":
                continue
            props[key] = _plain(getattr(node, key, None))
        nodes[node.name] = {
            "type": node.bl_idname,
            "props": props,
            "inputs": [
                (s.identifier, _plain(getattr(s, "default_value", None))) for s in node.inputs
            ],
            "outputs": [
                (s.identifier, _plain(getattr(s, "default_value", None))) for s in node.outputs
            ],
        }
    links = sorted(
        (
            link.from_node.name,
            link.from_socket.identifier,
            link.to_node.name,
            link.to_socket.identifier,
            link.is_muted,
        )
        for link in tree.links
    )
    return {"nodes": nodes, "links": links}


def _plain(value):
    if isinstance(value, bpy.types.ID):
        return ("ID", type(value).__name__, value.name)
    if isinstance(value, bpy.types.bpy_struct):
        return None  # nested structs (e.g. texture mapping) are not compared
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, (set, frozenset)):  # enum flags
        return tuple(sorted(value))
    try:
        return tuple(_plain(v) for v in value)
    except TypeError:
        return repr(value)


def render_exr(scene, path):
    """Render ``scene`` as it is set up to the 32-bit EXR ``path``: (H, W, 4) float32 linear
    RGBA, top row first."""
    r = scene.render
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    w, h = image.size
    pixels = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(h, w, 4)[::-1]


def render_transparent(scene, path, samples=16):
    """`render_exr` with Cycles on the CPU, the film transparent, no denoising, the Standard
    view."""
    scene.render.engine = "CYCLES"
    scene.render.film_transparent = True
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.view_settings.view_transform = "Standard"
    return render_exr(scene, path)


def camera_rays(scene, width, height):
    """World-space rays through the pixel centres of a ``width`` x ``height`` render of the
    scene's camera: ((3,) origin, (height, width, 3) directions), top row first."""
    bounds = addon_part("operators.scene.bounds")
    projection = bounds.camera_projection(scene)
    left, right, bottom, top = projection.frame
    py, px = np.mgrid[0:height, 0:width] + 0.5
    local = np.stack(
        (
            left + px * (right - left) / width,
            top - py * (top - bottom) / height,
            -np.ones_like(px),
        ),
        -1,
    )
    camera_to_world = np.linalg.inv(projection.world_to_camera)
    return camera_to_world[:3, 3], local @ camera_to_world[:3, :3].T


def ground_plate(scene, ground_z, colour, sky, size=None, name="Plate"):
    """The plate the scene's camera would see of a ground plane at height ``ground_z``:
    ``colour(x, y)`` ((..., 3) linear RGB at world X, Y) where a pixel's ray meets it, else
    ``sky``; a packed float image of the render's size (or ``size`` (W, H))."""
    w, h = size or (scene.render.resolution_x, scene.render.resolution_y)
    origin, d = camera_rays(scene, w, h)
    down = d[..., 2] < -1e-9
    t = np.where(down, (ground_z - origin[2]) / np.where(down, d[..., 2], -1.0), 0.0)
    x, y = origin[0] + t * d[..., 0], origin[1] + t * d[..., 1]
    rgb = np.where(down[..., None], colour(x, y), sky).astype(np.float32)
    image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    image.pixels.foreach_set(rgba[::-1].ravel())
    image.pack()
    return image
