"""What the method does, for the active object: the plate with the paper's segmentation drawn
over it (regions X, L/R/T/B, F and the triangles; engine ``overlay.draw_segmentation``) and the
map it produced, as small previews in the panel, and full size in an Image Editor.

Previews live in a ``bpy.utils.previews`` collection (an icon each: the panel draws them with
``template_icon``; works in Blender 4.2 to 5.x). They are made when the panel draws and only
when what they show changed: the map when its pixels were written (``maps.version``; live
update hands its pixels over with `note_map`, so nothing is read back), the overlay when the
plate, the object's bounds or the method's settings changed.

Colour: maps and plates are in the file's scene-linear working space; previews are sRGB-encoded
by colour_space.to_srgb (icons are shown as they are, without the scene's view transform),
clipped to [0, 1].
"""

import bpy
import bpy.utils.previews
import numpy as np

from ..virtual_reflections import methods, segment
from ..virtual_reflections.overlay import draw_segmentation
from . import pipeline
from .node_trees import shading
from .scene import colour_space, images, maps, plate
from .scene.composite import union_box

PREVIEW_WIDTH = 256  # pixels across a preview image (maps: 256 x 128)
OVERLAY = "overlay"  # the CREATED value of the full-size segmentation picture
OVERLAY_PREFIX = "VR Segmentation "

_collection = None  # bpy.utils.previews collection, made on register
_keys = {}  # preview name -> what it was made from
_noted = {}  # map image name -> (version, (h, w, 3) linear pixels) handed over by live.py
_small_plates = {}  # plate key -> (h, w, 3) linear plate about PREVIEW_WIDTH wide
_pixels = {}  # preview name -> the (h, w, 3) linear pixels it shows
GAP = 6  # pixels between the two pictures of the combined preview


# --- pixels ---------------------------------------------------------------------------------------


def shrink(pixels, width=PREVIEW_WIDTH):
    """(H, W, 3) float32 -> about ``width`` pixels wide: 2 x 2 box averages while it stays at
    least twice as wide, then nearest pixels (previews only; no aliasing worth a filter)."""
    px = np.asarray(pixels, np.float32)
    while px.shape[1] >= 2 * width and px.shape[0] >= 2:
        h, w = px.shape[0] // 2 * 2, px.shape[1] // 2 * 2
        px = 0.25 * (px[0:h:2, 0:w:2] + px[1:h:2, 0:w:2] + px[0:h:2, 1:w:2] + px[1:h:2, 1:w:2])
    if px.shape[1] > width:
        height = max(1, round(px.shape[0] * width / px.shape[1]))
        ys = ((np.arange(height) + 0.5) * px.shape[0] / height).astype(int)
        xs = ((np.arange(width) + 0.5) * px.shape[1] / width).astype(int)
        px = px[ys][:, xs]
    return px


def _set_preview(name, linear):
    """Put (h, w, 3) linear pixels (top row first) into the preview ``name``; returns it."""
    preview = _collection.get(name) or _collection.new(name)
    h, w = linear.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = colour_space.to_srgb(linear)[::-1]  # icons: rows bottom-up
    preview.image_size = (w, h)
    preview.image_pixels_float.foreach_set(rgba.ravel())
    _pixels[name] = linear
    return preview


def combined_preview(name, top_name, bottom_name):
    """One preview with preview ``top_name`` above ``bottom_name`` (``template_icon`` draws a
    square: two wide pictures stacked fill it, one alone would leave it half empty)."""
    key = (_keys.get(top_name), _keys.get(bottom_name))
    preview = _collection.get(name)
    if preview is not None and _keys.get(name) == key:
        return preview
    top, bottom = _pixels[top_name], _pixels[bottom_name]
    width = max(top.shape[1], bottom.shape[1])
    canvas = np.full((top.shape[0] + GAP + bottom.shape[0], width, 3), 0.02, np.float32)
    canvas[: top.shape[0], : top.shape[1]] = top
    canvas[top.shape[0] + GAP :, : bottom.shape[1]] = bottom
    _keys[name] = key
    return _set_preview(name, canvas)


# --- what the active object shows -----------------------------------------------------------------


def map_objects(scene, obj):
    """The objects whose bounds made ``obj``'s map: every object reflecting the same map."""
    image = shading.map_of(obj)
    return shading.reflecting(scene).get(image, [obj]) if image is not None else [obj]


def plate_box(scene, obj):
    """The box the map was made from, in plate pixels (x0, y0, x1, y1), or None."""
    boxes = [tuple(o.virtual_reflections.bounds) for o in map_objects(scene, obj)]
    return union_box(b for b in boxes if b[2] > b[0] and b[3] > b[1])


def note_map(image, env):
    """Live update hands over the pixels it wrote, so the panel does not read them back."""
    _noted[image.name_full] = (maps.version(image), shrink(env))


def map_preview(image, scene=None):
    """The preview of a map image, remade when its pixels changed (written by Generate or
    live update; with Update Every Frame on, also on every frame)."""
    name = "map:" + image.name_full
    every_frame = scene is not None and scene.virtual_reflections.sequence
    key = (maps.version(image), tuple(image.size), scene.frame_current if every_frame else None)
    preview = _collection.get(name)
    if preview is not None and _keys.get(name) == key:
        return preview
    noted = _noted.pop(image.name_full, None)
    if noted is not None and noted[0] == key[0]:
        small = noted[1]
    else:
        small = shrink(images.read_pixels(image)[..., :3])
    _keys[name] = key
    return _set_preview(name, small)


def _plate(scene):
    """(key, (h, w, 3) full linear plate, (h, w, 3) small plate) of the scene's plate."""
    image = plate.scene_plate(scene)
    if image is None:
        raise ValueError("no plate")
    pixels, _info = plate.pixels(scene, image)
    key = (image.name_full, pixels.shape, id(pixels))
    small = _small_plates.get(key)
    if small is None:
        _small_plates.clear()
        small = _small_plates[key] = shrink(pixels)
    return key, pixels, small


def segmentation(scene, obj, plate_shape):
    """The paper's segmentation the object's map was made from (full plate size), or None."""
    box = plate_box(scene, obj)
    if box is None:
        return None
    settings = scene.virtual_reflections
    return segment(plate_shape[1], plate_shape[0], box, pipeline.params(settings))


def overlay_pixels(settings, box, pixels, full_shape):
    """(h, w, 3) linear: ``pixels`` (a plate) with the paper's segmentation around ``box``
    (plate pixels of a plate ``full_shape`` (H, W, ...)) drawn over it, scaled to the pixels
    given (a small one for the preview)."""
    h, w = pixels.shape[:2]
    scale = (w / full_shape[1], h / full_shape[0])
    params = pipeline.params(settings)
    seg = segment(w, h, tuple(v * scale[k % 2] for k, v in enumerate(box)), params)
    return draw_segmentation(pixels, seg, params.triangles)


def overlay_preview(scene, obj):
    """The preview of the plate cut into the paper's regions around ``obj``, or None when it
    has no map yet."""
    box = plate_box(scene, obj)
    if box is None:
        return None
    plate_key, full, small = _plate(scene)
    s = scene.virtual_reflections
    name = "overlay:" + obj.name_full
    key = (plate_key, tuple(round(v) for v in box), s.enlarge, s.border, s.front, s.triangles)
    preview = _collection.get(name)
    if preview is not None and _keys.get(name) == key:
        return preview
    _keys[name] = key
    return _set_preview(name, overlay_pixels(s, box, small, full.shape))


def for_object(scene, obj):
    """{"map": ImagePreview | None, "overlay": ImagePreview | None, "both": the two stacked
    (what the panel draws) | None, "advice": [str], "image": the map image | None}; never
    raises."""
    image = shading.map_of(obj)
    out = {"map": None, "overlay": None, "both": None, "advice": [], "image": image}
    missing = maps.missing_file(image)
    if missing:  # nothing to show (Blender would render it magenta): say so, and what to do
        out["advice"] = [f"{missing}: Generate makes it again"]
        return out
    if _collection is None or image is None:
        return out
    try:
        out["map"] = map_preview(out["image"], scene)
        out["overlay"] = overlay_preview(scene, obj)
        if out["overlay"] is not None:
            out["both"] = combined_preview(
                "both:" + obj.name_full, "overlay:" + obj.name_full, "map:" + image.name_full
            )
        image = plate.scene_plate(scene)
        if image is not None and out["overlay"] is not None:
            seg = segmentation(scene, obj, tuple(image.size)[::-1])
            paper = methods.cuts_regions(scene.virtual_reflections.method)
            name = "World" if shading.mode_of(obj) == "WORLD" else obj.name
            out["advice"] = pipeline.fit_warnings(name, seg, paper)
    except (ValueError, RuntimeError) as exc:  # a missing plate file: say so, draw on
        out["advice"] = [str(exc)]
    return out


# --- full size in an Image Editor (ops.py opens it) -----------------------------------------------


def overlay_image(scene, obj):
    """The Blender image "VR Segmentation <object>": the whole plate with the segmentation drawn
    over it (linear float; made or updated; removed with the maps)."""
    _key, full, _small = _plate(scene)
    box = plate_box(scene, obj)
    if box is None:
        raise ValueError(f"{obj.name} has no reflection yet: generate first")
    pixels = overlay_pixels(scene.virtual_reflections, box, full, full.shape)
    h, w = pixels.shape[:2]
    image = images.own_image(OVERLAY_PREFIX + obj.name, w, h, OVERLAY)
    images.write_pixels(image, pixels)
    image.update()
    return image


def register():
    global _collection
    if _collection is None:
        _collection = bpy.utils.previews.new()


def unregister():
    global _collection
    if _collection is not None:
        bpy.utils.previews.remove(_collection)
        _collection = None
    _keys.clear()
    _pixels.clear()
    _noted.clear()
    _small_plates.clear()
