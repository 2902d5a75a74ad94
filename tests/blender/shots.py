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
