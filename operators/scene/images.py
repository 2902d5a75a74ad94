"""Blender images in and out: pixels as NumPy arrays, and the images the add-on creates.

Arrays here are top row first (Blender stores image rows bottom-up). A float image's
``pixels`` are scene-linear (Blender converts EXR, HDR and 16-bit files to the working space on
load); a byte (8-bit) image's ``pixels`` are the file's codes / 255, still in the image's colour
space, so `read_linear` converts them to the working space (docs/conventions.md, "Colour").

Every datablock the add-on makes (images, materials, worlds, node groups) carries the custom
property ``CREATED`` naming what it is, so the add-on deletes only what it made.
"""

import bpy
import numpy as np

from ...virtual_reflections.colour import decode_uint
from ...virtual_reflections.parallel import for_blocks
from . import colour_space

CREATED = "vr_created"  # custom property on every datablock the add-on made; value: its kind
LINEAR_SPACES = ("Linear Rec.709", "Linear", "Linear BT.709")  # names across Blender versions
DATA_SPACES = {"Non-Color", "Raw"}  # colour spaces whose values are data, used as they are


def created(id_data) -> str | None:
    """What the add-on made ``id_data`` as ("map", "material", ...), or None if not ours."""
    return id_data.get(CREATED) if id_data is not None else None


def set_linear(image):
    """Tag ``image`` scene-linear Rec.709 (whatever this Blender calls it), only if needed:
    setting the colour space, even to its value, regenerates a generated image's buffer."""
    names = {
        item.identifier for item in image.colorspace_settings.bl_rna.properties["name"].enum_items
    }
    for name in LINEAR_SPACES:
        if name in names:
            if image.colorspace_settings.name != name:
                image.colorspace_settings.name = name
            return


def read_pixels(image) -> np.ndarray:
    """(H, W, C) float32 ``image.pixels`` as stored (C channels, usually 4), top row first."""
    w, h = image.size
    count = len(image.pixels)
    channels = count // max(w * h, 1)
    if w * h == 0 or channels < 1 or channels * w * h != count:
        raise ValueError(f"image '{image.name}': {count} pixel values do not fit {w}x{h}")
    buffer = np.empty(count, dtype=np.float32)
    image.pixels.foreach_get(buffer)
    return buffer.reshape(h, w, channels)[::-1]


def read_linear(image) -> tuple[np.ndarray, list]:
    """((H, W, 3) float32 in the file's scene-linear working space, top row first; notes on
    how it was decoded).

    Float images are used as loaded (Blender converted them to the working space); images whose
    colour space is data (Non-Color, Raw) as they are; byte images are converted from their
    colour space to the working space with Blender's OpenColorIO config (colour_space.py); an
    sRGB byte image in a Linear Rec.709 file through the sRGB table (128 -> 0.216), the same
    values ~4x faster. Alpha is dropped.
    """
    stored = read_pixels(image)
    rows = stored[..., :3] if stored.shape[2] >= 3 else np.repeat(stored[..., :1], 3, axis=2)
    space = image.colorspace_settings.name
    is_data = image.colorspace_settings.is_data or space in DATA_SPACES
    working = colour_space.working_space()
    if image.is_float:
        if is_data:
            return rows, [f"float, colour space {space} (data): used as is"]
        return rows, [f"float, scene-linear {working} as loaded"]
    if is_data:
        return rows, [f"8-bit, colour space {space} (data): used as is"]
    if space == "sRGB" and working == colour_space.REC709:
        # Byte pixels are exactly k / 255: decode through the table of srgb_to_linear(k / 255).
        codes = np.rint(rows * 255.0).astype(np.uint8)
        return decode_uint(codes), ["8-bit sRGB, decoded to scene-linear"]
    try:
        converted = colour_space.convert(rows, space, working)
    except ValueError as exc:  # a space no converter knows: decode as sRGB, and say so
        codes = np.rint(rows * 255.0).astype(np.uint8)
        converted = colour_space.convert(decode_uint(codes), colour_space.REC709, working)
        return converted, [f"8-bit, {exc}: decoded as sRGB"]
    return converted, [f"8-bit {space} -> {working}"]


def write_pixels(image, pixels: np.ndarray):
    """Write (H, W, 3) float32 linear pixels (alpha 1) into ``image`` in place, resizing it if
    needed, and nothing else: no file saved, no datablock made, no redraw tagged."""
    h, w = pixels.shape[:2]
    if tuple(image.size) != (w, h):
        if image.source == "GENERATED":
            image.generated_width, image.generated_height = w, h
        else:
            image.scale(w, h)
    image.pixels.foreach_set(_rgba_bottom_up(pixels).ravel())


def _rgba_bottom_up(pixels: np.ndarray) -> np.ndarray:
    """(H, W, 3) pixels as Blender stores them: rows bottom-up, alpha 1, (H, W, 4) float32.
    Written channel by channel (NumPy's loops over 3-float pixels are slow) in blocks of
    rows over the cores: ~2.5x faster than one strided copy for a 4096 x 2048 map."""
    h, w = pixels.shape[:2]
    rgba = np.empty((h, w, 4), dtype=np.float32)

    def rows(a, b):
        dst, src = rgba[a:b], pixels[h - b : h - a][::-1]
        dst[..., 3] = 1.0
        for c in range(3):
            dst[..., c] = src[..., c]

    for_blocks(rows, h, min_rows=8, max_rows=16)
    return rgba


def own_image(name: str, width: int, height: int, kind: str):
    """The float, scene-linear image ``name`` the add-on made as ``kind``: the existing one,
    or a new one. ValueError (one line) when an image of that name exists and is not ours."""
    image = bpy.data.images.get(name)
    if image is not None and created(image) != kind:
        raise ValueError(f"an image named {name!r} exists and is not ours; rename it")
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=False, float_buffer=True)
        image[CREATED] = kind
    set_linear(image)  # before any resize (see set_linear)
    return image


def remove_created(kinds) -> int:
    """Delete every image the add-on made as one of ``kinds``; returns how many."""
    ours = [image for image in bpy.data.images if created(image) in kinds]
    for image in ours:
        bpy.data.images.remove(image)
    return len(ours)


def check_local(id_data, what):
    """ValueError (one line) when ``id_data`` is linked from a library or not editable: the
    add-on edits only local data."""
    if id_data.library is not None or not id_data.is_editable:
        library = id_data.library.filepath if id_data.library is not None else "a library"
        raise ValueError(f"{what} is linked from {library} and read-only; make it local first")
