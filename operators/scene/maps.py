"""Environment maps as Blender images: created once per object, updated in place, packed into
the .blend or saved as files, removed with every other image the add-on made.

Maps are float32 scene-linear Rec.709 lat-long images in the camera frame (shading.py,
docs/conventions.md). Every map carries ``images.CREATED = "map"``. Where a map's pixels are
kept is the scene's ``map_storage``: packed into the .blend when it is saved (`pack_pending`;
packing encodes an EXR, so it happens once per save, not once per regeneration), or saved as
EXR files into `maps_folder`.

Both are the engine's EXR (`imagefiles.write_map`), not Blender's image save: scene-linear
half floats, ZIP-compressed, Rec.709 chromaticities, tagged scene-linear, with the standard
``envmap = LATLONG`` attribute, so a saved or unpacked map is a pipeline file as it is.
(Blender's ``Image.save`` writes a generated float image uncompressed, in float32, and 5.x
tags it with the display's space.) The image then reads its pixels from that file.
"""

import hashlib
import os
import tempfile
import uuid

import bpy
import numpy as np

from ...virtual_reflections.atomic_files import ImageError
from ...virtual_reflections.imagefiles import write_map
from . import app_handlers, images, undo_pixels
from .choices import ADDON, addon_preferences

KIND = "map"  # images.CREATED value of maps
NEEDS_PACK = "vr_needs_pack"  # on maps: pack again at the next save
MAP_PREFIX = "VR Map "
WORLD_MAP = "VR World Map"  # the map shared by the objects in World mode (no object's name)

_versions = {}  # image name -> how often its pixels were written this session (previews.py)


NAME_BYTES = 63  # Blender cuts longer datablock names (4.5; 5.x allows more)


def map_name(object_name: str) -> str:
    """The name of an object's own map: "VR Map <object>", or, when that would not fit in
    NAME_BYTES, the object's name cut and a hash of the whole name (so a long name gets the
    same map every time, and two long names that start alike get two)."""
    name = f"{MAP_PREFIX}{object_name}"
    if len(name.encode()) <= NAME_BYTES:
        return name
    tag = "~" + hashlib.sha1(object_name.encode()).hexdigest()[:8]
    room = NAME_BYTES - len(MAP_PREFIX.encode()) - len(tag)
    cut = object_name.encode()[:room].decode(errors="ignore")
    return f"{MAP_PREFIX}{cut}{tag}"


def touch(image):
    """Note that ``image``'s pixels changed: the image is tagged for the dependency graph (a
    Cycles render with Persistent Data reloads it only then; bpy 5.x,
    tests/blender/test_map_refresh.py) and previews follow the count."""
    image.update_tag()
    _versions[image.name_full] = _versions.get(image.name_full, 0) + 1


def version(image) -> int:
    return _versions.get(image.name_full, 0)


FILE_ID = "vr_file_id"  # on a scene: its id in the user folder while its .blend is unsaved


def maps_folder(scene=None, create=True) -> str:
    """The folder ``scene``'s (default: the context's) saved maps go to, the preferences'
    choice. Raises ValueError (one line) when that is "beside the .blend" and the file has not
    been saved yet. ``create`` False: nothing is made (the panel draws it)."""
    blend = bpy.data.filepath
    if addon_preferences().map_folder == "USER":
        try:
            return bpy.utils.extension_path_user(
                ADDON,
                path=os.path.join("maps", _user_key(scene or bpy.context.scene, create)),
                create=create,
            )
        except ValueError:
            pass  # not installed as an extension (imported by a test or a script): beside it
    if not blend:
        raise ValueError(
            "save the .blend first to save maps beside it (or pack them, or pick the "
            "extension user folder in the preferences)"
        )
    return os.path.join(os.path.dirname(bpy.path.abspath(blend)), "vr_maps")


def _user_key(scene, create) -> str:
    """The folder of one file's maps in the user folder, unique to that file: its name and a
    hash of its whole path (two shots named lighting.blend in two folders keep their own), or
    for an unsaved file "untitled-" and an id made once and kept in the scene (each unsaved
    file its own). Without ``create`` an id not made yet reads "new"."""
    blend = bpy.data.filepath
    if blend:
        path = os.path.realpath(bpy.path.abspath(blend))
        digest = hashlib.sha1(path.encode(errors="surrogateescape")).hexdigest()[:8]
        return f"{bpy.path.clean_name(bpy.path.display_name_from_filepath(blend))}-{digest}"
    file_id = scene.get(FILE_ID) if scene is not None else None
    if not file_id and create and scene is not None:
        file_id = scene[FILE_ID] = uuid.uuid4().hex[:12]
    return f"untitled-{file_id or 'new'}"


_saved_under = {}  # scene.session_uid -> where its saved maps go instead (the batch: save_under)


def save_under(scene, folder: str):
    """Save ``scene``'s maps stored as files into ``folder`` instead, for this session (the
    batch: under --out; it writes nothing beside the shot, which may be read-only on a farm,
    and never replaces the artist's saved maps; the .blend is not saved, so the shot keeps
    its own paths)."""
    _saved_under[scene.session_uid] = folder


def save_folder(settings):
    """Where a scene's maps are saved: `maps_folder` (or the batch's `save_under`) when its
    ``map_storage`` is FILES, None when they are packed. ValueError as `maps_folder`."""
    if settings.map_storage != "FILES":
        return None
    scene = settings.id_data
    return _saved_under.get(scene.session_uid) or maps_folder(scene)


def store_map(name: str, env: np.ndarray, save_dir: str | None = None, kind: str = KIND):
    """Write an (H, W, 3) float32 map into the image ``name`` (made if missing, updated in
    place) and keep it: saved as EXR into ``save_dir`` when given, else packed into the .blend
    at its next save. Returns the image. ValueError when an image of that name is not ours;
    atomic_files.ImageError (a ValueError) when the file cannot be written."""
    h, w = env.shape[:2]
    image = images.own_image(name, w, h, kind)
    if missing_file(image):  # its file is gone (it would load nothing): start it afresh
        image.source = "GENERATED"
        image.use_generated_float = True
        image.generated_width, image.generated_height = w, h
        images.set_linear(image)
    image.use_fake_user = True  # kept with the .blend even while no material uses it
    images.write_pixels(image, env)
    image.file_format = "OPEN_EXR"
    if save_dir:
        os.makedirs(save_dir, exist_ok=True)
        path = os.path.join(save_dir, bpy.path.clean_name(name) + ".exr")
        write_map(path, env, _layout(kind))  # atomic: a previous map stays until this is whole
        if image.packed_file:
            image.unpack(method="REMOVE")
        _read_from(image, _beside_relative(path))
        image[NEEDS_PACK] = False
    else:
        image[NEEDS_PACK] = True  # packed when the .blend is saved (pack_pending)
    image.update()
    undo_pixels.remember(image, env)  # undo and redo bring these pixels back
    touch(image)
    return image


def _beside_relative(path: str) -> str:
    """``path`` as the image keeps it: "//"-relative when it is in the saved .blend's folder
    (the shot's folder, vr_maps/ with it, moves as one and its maps still load), else as it
    is (the user folder, which stays on this machine)."""
    blend = bpy.data.filepath
    if not blend:
        return path
    home = os.path.dirname(os.path.abspath(blend))
    try:
        inside = os.path.commonpath([home, os.path.abspath(path)]) == home
    except ValueError:  # another drive
        inside = False
    return bpy.path.relpath(path) if inside else path


def missing_file(image) -> str | None:
    """One line when ``image``, a map (or composite) saved as a file, cannot find its file
    (the file deleted, or the shot moved without it), else None. Blender would render it
    magenta; Generate makes it again."""
    if image is None or images.created(image) is None:
        return None
    if image.source != "FILE" or image.packed_file or not image.filepath:
        return None
    if os.path.isfile(bpy.path.abspath(image.filepath, library=image.library)):
        return None
    return f"map '{image.name}': its file {image.filepath} is missing"


def _layout(kind: str) -> str | None:
    """The EXR ``envmap`` of an image the add-on made: maps are lat-long, composites none."""
    return "latlong" if kind == KIND else None


def _read_from(image, path: str = ""):
    """Make ``image`` a file image reading ``path`` (or its packed file when ``path`` is
    empty), and load its pixels from there now."""
    if path:
        image.filepath_raw = path
    if image.source != "FILE":
        image.source = "FILE"  # reloads from the file (or the packed data)
    else:
        image.reload()
    images.set_linear(image)


def pack(image):
    """Pack ``image``'s pixels into the .blend as the engine's compressed half-float EXR (the
    same file `store_map` saves), instead of Blender's uncompressed float32 one; Blender's own
    when that cannot be written (the map is never lost on save)."""
    pixels = images.read_pixels(image)[..., :3]
    try:
        with tempfile.TemporaryDirectory(prefix="vr-pack-") as folder:
            path = os.path.join(folder, bpy.path.clean_name(image.name) + ".exr")
            write_map(path, pixels, _layout(images.created(image)))
            with open(path, "rb") as f:
                data = f.read()
    except (ImageError, OSError):
        # No OpenImageIO, or no room for the temporary file: this runs while the .blend is
        # saved, so keep the pixels the way Blender can (its own, uncompressed, EXR).
        image.pack()
        return
    if image.packed_file:
        image.unpack(method="REMOVE")
    image.filepath_raw = "//" + bpy.path.clean_name(image.name) + ".exr"  # the unpack name
    image.pack(data=data, data_len=len(data))
    _read_from(image)


def show_pixels(image, env: np.ndarray):
    """Write a map's new pixels into its image at once, nothing else (the full pass, which
    saves or packs it, comes later: live.py)."""
    images.write_pixels(image, env)
    image.update()
    undo_pixels.remember(image, env, new=False)
    touch(image)


def overwrite(image, env: np.ndarray):
    """Write an (H, W, 3) map of the image's own size into it, in place, changing nothing but
    pixels (no save, no datablock made), so it may run on a render thread; a packed map is
    marked to be packed again at the next save. ValueError when the size differs."""
    h, w = env.shape[:2]
    if tuple(image.size) != (w, h):
        raise ValueError(f"map '{image.name}' has another size; generate again")
    show_pixels(image, env)
    if image.get(NEEDS_PACK) is False:
        image[NEEDS_PACK] = True


def pack_pending():
    """Pack every map (or composite) regenerated since the last save."""
    for image in bpy.data.images:
        if images.created(image) is not None and image.get(NEEDS_PACK):
            pack(image)
            image[NEEDS_PACK] = False


@bpy.app.handlers.persistent
def _pack_before_save(*_args):
    pack_pending()


@bpy.app.handlers.persistent
def _say_missing_after_load(*_args):
    """A .blend opened with maps whose files are gone: one line each on the console, so it
    is known before a render shows them magenta (the object's panel says it too)."""
    for image in bpy.data.images:
        note = missing_file(image)
        if note:
            print(f"Virtual Reflections: {note}; Generate makes it again")


def orphans(in_use) -> list:
    """The add-on's maps that no object reflects any more (its object was deleted or renamed
    and generated again), given the images ``in_use``."""
    return [i for i in bpy.data.images if images.created(i) == KIND and i not in in_use]


def remove_maps():
    """Delete every map (and segmentation picture, composite) the add-on made; returns how
    many."""
    return images.remove_created(("map", "overlay", "composite"))


_HANDLERS = (("save_pre", _pack_before_save), ("load_post", _say_missing_after_load))


def register():
    app_handlers.add(_HANDLERS)


def unregister():
    app_handlers.remove(_HANDLERS)
