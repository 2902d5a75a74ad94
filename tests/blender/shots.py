"""Small scenes the bpy tests share: a camera on -Y looking along +Y (Z up), and plates."""

import math
import sys

import bpy
import numpy as np

PACKAGE = "vr_addon_under_test"  # conftest.load_addon's name for the repository


def addon_part(name):
    """A submodule of the loaded add-on, e.g. ``addon_part("operators.generate")``."""
    return sys.modules[f"{PACKAGE}.{name}"]


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
