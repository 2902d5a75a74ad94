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
NEEDS_PACK = "vr_needs_pack"
MAP_PREFIX = "VR Map "
LINEAR = ("Linear Rec.709", "Linear", "Linear BT.709")


def _set_linear(image):
    names = {
        item.identifier for item in image.colorspace_settings.bl_rna.properties["name"].enum_items
    }
    for name in LINEAR:
        if name in names:
            if image.colorspace_settings.name != name:
                image.colorspace_settings.name = name
            return


_versions = {}  # image name -> how often its pixels were written this session (previews.py)


def touch(image):
    """Note that ``image``'s pixels changed (previews follow the count)."""
    _versions[image.name_full] = _versions.get(image.name_full, 0) + 1


def version(image) -> int:
    return _versions.get(image.name_full, 0)


def map_name(owner_name: str) -> str:
    return f"{MAP_PREFIX}{owner_name}"


def write_pixels(image, env: np.ndarray):
    """Write an (H, W, 3) float32 linear map into ``image`` in place (resized if needed), and
    nothing else: no file saved, no packing flag set."""
    h, w = env.shape[:2]
    if tuple(image.size) != (w, h):
        if image.source == "GENERATED":
            image.generated_width, image.generated_height = w, h
        else:
            image.scale(w, h)
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = env[::-1]  # Blender stores rows bottom-up
    image.pixels.foreach_set(rgba.ravel())


def store_map(name: str, env: np.ndarray, save_dir: str | None = None):
    """Write a (H, W, 3) float32 map into the image `name` (made if missing, updated in place).

    The image is packed into the .blend when it is saved (see pack_pending), or saved as EXR
    into `save_dir` when given.
    Returns the image.
    """
    h, w = env.shape[:2]
    image = bpy.data.images.get(name)
    if image is not None and image.get(CREATED) != "map":
        raise ValueError(f"an image named {name!r} exists and is not ours; rename it")
    if image is None:
        image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
        image[CREATED] = "map"
        image.use_fake_user = True  # kept with the .blend even while no material uses it
    # Setting the colour space (even to its current value) regenerates a generated image's
    # buffer at its generated size, so it comes before any resize, and only when needed.
    _set_linear(image)
    write_pixels(image, env)
    image.file_format = "OPEN_EXR"
    if save_dir:
        os.makedirs(save_dir, exist_ok=True)
        image.filepath_raw = os.path.join(save_dir, bpy.path.clean_name(name) + ".exr")
        image.save()
        if image.packed_file:
            image.unpack(method="REMOVE")
        image[NEEDS_PACK] = False
    else:
        image[NEEDS_PACK] = True  # packed when the .blend is saved (pack_pending)
    image.update()
    touch(image)
    return image


def pack_pending():
    """Pack every map regenerated since the last save. Packing encodes an EXR (~20 ms for
    1024 x 512), so it happens once per save rather than once per regeneration."""
    for image in bpy.data.images:
        if image.get(CREATED) == "map" and image.get(NEEDS_PACK):
            image.pack()
            image[NEEDS_PACK] = False


@bpy.app.handlers.persistent
def _pack_before_save(*_args):
    pack_pending()


def register():
    if _pack_before_save not in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.append(_pack_before_save)


def unregister():
    if _pack_before_save in bpy.app.handlers.save_pre:
        bpy.app.handlers.save_pre.remove(_pack_before_save)


def remove_maps():
    """Delete every map (and segmentation picture) the add-on created; returns how many."""
    ours = [image for image in bpy.data.images if image.get(CREATED) in ("map", "overlay")]
    for image in ours:
        bpy.data.images.remove(image)
    return len(ours)
