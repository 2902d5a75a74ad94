"""Environment maps as Blender images: created once per object, updated in place.

Maps are float32 scene-linear Rec.709 lat-long images in the camera frame (see shading.py);
Blender stores image rows bottom-up, the engine top row first, so rows are flipped here.
Every image made here carries the custom property CREATED = "map", so removing reflections
deletes only what the add-on created.
"""

import os

import bpy
import numpy as np

CREATED = "vr_created"
MAP_PREFIX = "VR Map "
LINEAR = ("Linear Rec.709", "Linear", "Linear BT.709")


def _set_linear(image):
    names = {
        item.identifier for item in image.colorspace_settings.bl_rna.properties["name"].enum_items
    }
    for name in LINEAR:
        if name in names:
            image.colorspace_settings.name = name
            return


def map_name(owner_name: str) -> str:
    return f"{MAP_PREFIX}{owner_name}"


def store_map(name: str, env: np.ndarray, save_dir: str | None = None):
    """Write a (H, W, 3) float32 map into the image `name` (made if missing, updated in place).

    The image is packed into the .blend, or saved as EXR into `save_dir` when given.
    Returns the image.
    """
    h, w = env.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and image.get(CREATED) != "map":
        raise ValueError(f"an image named {name!r} exists and is not ours; rename it")
    if image is not None and tuple(image.size) != (w, h):
        image.scale(w, h)
    if image is None:
        image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
        image[CREATED] = "map"
        image.use_fake_user = True  # kept with the .blend even while no material uses it
    _set_linear(image)
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = env[::-1]
    image.pixels.foreach_set(rgba.ravel())
    image.file_format = "OPEN_EXR"
    if save_dir:
        os.makedirs(save_dir, exist_ok=True)
        image.filepath_raw = os.path.join(save_dir, bpy.path.clean_name(name) + ".exr")
        image.save()
        if image.packed_file:
            image.unpack(method="REMOVE")
    else:
        image.pack()
    image.update()
    return image


def remove_maps():
    """Delete every map image the add-on created; returns how many."""
    ours = [image for image in bpy.data.images if image.get(CREATED) == "map"]
    for image in ours:
        bpy.data.images.remove(image)
    return len(ours)
