"""The plate: the photograph the objects are composited into, as the scene has it.

One home for everything about it: which image is the scene's plate (`scene_plate`), its file
on disk (`disk_path`), its size (`size`), its pixels for a frame (`frame`, `pixels`), and one
cache of what was read. Stills are read once and kept while the image is unchanged; image
sequences and movies are read frame by frame through private images (`FramePlate`), so the
artist's image is never touched.

Colour: pixels are (H, W, 3) float32 in the file's scene-linear working space (Linear Rec.709,
or in 5.x possibly Linear Rec.2020 / ACEScg), top row first (images.read_linear converts byte
images from their colour space, colour_space.py);
NaN/Inf values are replaced (engine ``colour.clean_plate``) and counted in the info line.

Reading frame n of a sequence or a movie: ``Image.pixels`` has no frame argument (it shows the
frame last loaded through an image user). Sequences: frame n's file (Blender's rule: the last
run of digits in the file name, padded to its width) is loaded into a private image. Movies:
``Image.scale(w, h, frame=n)`` on a private copy of the movie -- the one Python call that
acquires a given frame, in 4.5 and 5.x -- leaves that frame in the copy's pixels. The plate
frame of a scene frame follows the camera's background image of the plate when that has a
frame range set (Start, Offset, Frames, Cyclic, as Blender maps it); else plate frame = scene
frame. Private images are made on the main thread only; a render thread only loads a file
into one (sequence.py explains the threads).
"""

import contextlib
import os
import re
import threading
from dataclasses import dataclass, field

import bpy
import numpy as np

from ...virtual_reflections.colour import clean_plate
from ...virtual_reflections.frames import sequence_path, user_frame
from . import images

FRAME_IMAGE = ".VR Plate Frame"  # private images reading plate frames (dot: hidden in lists)
FRAME_KIND = "plate_frame"  # their images.CREATED value
MOVING = {"SEQUENCE", "MOVIE"}  # image sources with a frame per scene frame
NO_PLATE = "no plate: pick a plate image or give the camera a background image"


def on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


# --- which image, which file ----------------------------------------------------------------------


def scene_plate(scene):
    """The plate of a scene: ``scene.virtual_reflections.plate_image`` when set, else the first
    shown IMAGE background image of the active camera. Returns a bpy Image or None."""
    image = scene.virtual_reflections.plate_image
    if image is not None:
        return image
    camera = scene.camera
    if camera is None or camera.type != "CAMERA":
        return None
    for background in camera.data.background_images:
        if background.source == "IMAGE" and background.image and background.show_background_image:
            return background.image
    return None


def require_plate(scene):
    """The scene's plate image; ValueError (one line) without a camera or a plate."""
    if scene.camera is None:
        raise ValueError("the scene has no camera")
    image = scene_plate(scene)
    if image is None:
        raise ValueError(NO_PLATE)
    return image


def disk_path(image):
    """The absolute path an image reads its pixels from, or None (packed, generated, ...)."""
    if image.source not in {"FILE", "SEQUENCE", "MOVIE"} or not image.filepath:
        return None
    if image.packed_file is not None or len(image.packed_files):
        return None
    return os.path.normpath(bpy.path.abspath(image.filepath, library=image.library))


def background_user(scene, image):
    """The image user of the camera background entry showing ``image``, or None."""
    camera = scene.camera
    if camera is None or camera.type != "CAMERA":
        return None
    for entry in camera.data.background_images:
        if entry.image == image:
            return entry.image_user
    return None


def plate_frame(scene, image, frame=None) -> int:
    """The frame of a sequence/movie ``image`` shown at scene ``frame`` (default: the current
    one): through the camera background entry's frame range when it has one (Blender's image
    user mapping), else the scene frame itself."""
    frame = scene.frame_current if frame is None else frame
    user = background_user(scene, image)
    if user is None or user.frame_duration <= 0:
        return frame
    return user_frame(
        frame, user.frame_start, user.frame_duration, user.frame_offset, user.use_cyclic
    )


# --- size and pixels of a still image -------------------------------------------------------------


def size(image) -> tuple[int, int]:
    """Load ``image`` if needed and return its (width, height); ValueError (one line, naming
    the image or file) when it has no pixels: no image, a file missing on disk, a file Blender
    cannot load, 0x0. A missing file is checked before anything touches the pixels: Blender
    would otherwise carry on with an empty (or, in the UI, pink placeholder) buffer."""
    if image is None:
        raise ValueError("No plate image: choose an image (or a camera background image)")
    path = disk_path(image)
    if path is not None and not os.path.exists(path):
        raise ValueError(f"Plate image '{image.name}': file not found: {path}")
    if image.source in MOVING and path is not None and images.created(image) != FRAME_KIND:
        return _first_frame_size(image)  # Image.size shows no frame until one is loaded
    width, height = image.size  # loads the file on first access
    if not image.has_data:  # nothing in memory, so reload() loses nothing
        image.reload()
        width, height = image.size
    if not image.has_data:
        if path is not None:
            raise ValueError(
                f"Plate image '{image.name}' could not be loaded from {path} "
                "(unsupported or damaged file)"
            )
        raise ValueError(f"Plate image '{image.name}' has no pixels ({width}x{height})")
    if width == 0 or height == 0:
        raise ValueError(f"Plate image '{image.name}' has no pixels ({width}x{height})")
    return width, height


def image_pixels(image) -> tuple[np.ndarray, str]:
    """A Blender image's pixels as a plate -> ((H, W, 3) float32 scene-linear; info line).

    See images.read_linear for the colour handling. Movies and sequences give the frame
    Blender has loaded for the image (use `frame` for a given scene frame). Raises ValueError
    (one line) as `size` does.
    """
    width, height = size(image)
    linear, notes = images.read_linear(image)
    notes = [f"Plate '{image.name}' {width}x{height}", *notes]
    if image.source in MOVING:
        notes.append(f"{image.source.lower()}: the frame currently loaded")
    cleaned = clean_plate(linear)
    if cleaned.nonfinite:
        notes.append(f"{cleaned.nonfinite} NaN/Inf values replaced")
    return cleaned.pixels, "; ".join(notes)


# --- frames of sequences and movies ---------------------------------------------------------------


class FramePlate:
    """Reads frame n of a SEQUENCE or MOVIE image through a private image made on the main
    thread, so the artist's image is never touched. `read` may run on a render thread: it only
    loads a file into the private image. The private image is found by name each time (a
    Python reference to an ID does not survive undo)."""

    def __init__(self, image):
        if not on_main_thread():
            raise RuntimeError("plate frame readers are made on the main thread")
        self.source = image.source
        self.path = disk_path(image)
        if self.path is None:
            raise ValueError(f"plate '{image.name}': a {image.source.lower()} must be a file")
        if self.source == "SEQUENCE":
            sequence_path(self.path, 0)  # ValueError without a frame number in the name
        self.colorspace = image.colorspace_settings.name
        self.key = _reader_key(image)
        self.name = None  # the private image's name
        self.loaded = None  # the last frame read: ((number, file, mtime), result)
        self._private()

    def _private(self):
        image = bpy.data.images.get(self.name) if self.name else None
        if image is not None and images.created(image) == FRAME_KIND:
            return image
        if not on_main_thread():
            raise ValueError("the plate's frame reader is gone; change the frame once")
        if not os.path.isfile(self.path):
            raise ValueError(f"plate not found: {self.path}")
        image = bpy.data.images.load(self.path, check_existing=False)
        image.name = FRAME_IMAGE
        image[images.CREATED] = FRAME_KIND
        with contextlib.suppress(TypeError):  # a colour space this Blender does not know
            image.colorspace_settings.name = self.colorspace
        self.name = image.name
        return image

    def file(self, number):
        return sequence_path(self.path, number) if self.source == "SEQUENCE" else self.path

    def first_number(self) -> int:
        """The frame number of the file the image names (sequences), 1 for movies."""
        if self.source != "SEQUENCE":
            return 1
        m = re.search(r"(\d+)\D*$", os.path.splitext(os.path.basename(self.path))[0])
        return int(m.group(1)) if m else 0

    def read(self, number):
        """Frame ``number`` -> ((H, W, 3) float32 scene-linear, info, file). ValueError (one
        line, naming frame and file) for a missing sequence file or a frame outside a movie.
        The last frame read is kept, so reading it again costs nothing."""
        path = self.file(number)
        if not os.path.isfile(path):
            what = "file" if self.source == "SEQUENCE" else "movie"
            raise ValueError(f"plate frame {number}: {what} not found: {path}")
        key = (number, path, os.path.getmtime(path))
        if self.loaded is not None and self.loaded[0] == key:
            return self.loaded[1]
        image = self._private()
        if self.source == "SEQUENCE":
            if os.path.normpath(bpy.path.abspath(image.filepath)) != path:
                image.filepath = path  # loads that file instead
            else:
                image.reload()
            pixels, info = image_pixels(image)
        else:
            count = image.frame_duration
            if not 1 <= number <= count:
                raise ValueError(f"plate frame {number}: the movie {path} has frames 1-{count}")
            w, h = image.size
            image.scale(w, h, frame=number)  # loads that frame into the private copy
            pixels, info = image_pixels(image)
            # scale() marks the frame's buffer dirty, and Blender never frees dirty movie
            # frames by itself: free them, or a long movie would stay in memory frame by frame.
            image.buffers_free()
        self.loaded = (key, (pixels, f"{info}; frame {number}", path))
        return self.loaded[1]

    def close(self):
        """Remove the private image (main thread)."""
        image = bpy.data.images.get(self.name) if self.name else None
        if image is not None and images.created(image) == FRAME_KIND:
            bpy.data.images.remove(image)
        self.name = None


def _reader_key(image):
    return (image.name_full, image.source, image.filepath, image.colorspace_settings.name)


def _first_frame_size(image):
    reader = frame_reader(image)
    if reader is None:
        raise ValueError(f"plate '{image.name}': no frame reader (made on the main thread)")
    pixels = reader.read(reader.first_number())[0]
    return pixels.shape[1], pixels.shape[0]


# --- the one cache --------------------------------------------------------------------------------

_readers = {}  # reader key -> FramePlate (each keeps the last frame it read)
_still = {}  # the last still plate read: key -> (pixels, info)


def frame_reader(image, create=True):
    """The FramePlate of a sequence/movie image (made when ``create`` and on the main thread),
    or None."""
    key = _reader_key(image)
    reader = _readers.get(key)
    if reader is None and create and on_main_thread():
        reader = _readers[key] = FramePlate(image)
    return reader


@dataclass(frozen=True)
class PlateFrame:
    """The plate at one scene frame.

    pixels: (H, W, 3) float32 scene-linear; info: how it was read, one line; file: the file
    read (or the image's name); identity: a hashable value that changes exactly when the
    pixels do.
    """

    pixels: np.ndarray
    info: str
    file: str
    identity: tuple
    # The mip pyramids of these pixels (envmap.apply_table), kept as long as the pixels are:
    # every map of this plate frame shares them.
    pyramids: dict = field(default_factory=dict, compare=False)


def frame(scene, number=None, image=None) -> PlateFrame:
    """The scene's plate (or ``image``) at scene frame ``number`` (default: current). Stills are
    cached while unchanged. Raises ValueError (one line) when there is no plate or the frame
    cannot be read."""
    image = image if image is not None else scene_plate(scene)
    if image is None:
        raise ValueError(NO_PLATE)
    if image.source in MOVING:
        reader = frame_reader(image)
        if reader is None:
            raise ValueError(
                f"plate '{image.name}': its frames are read through a private image made on "
                "the main thread; change the frame once before rendering"
            )
        pixels, info, path = reader.read(plate_frame(scene, image, number))
        return PlateFrame(pixels, info, path, (reader.key, reader.loaded[0]))
    key = (
        image.session_uid,  # a new image under an old name is a new plate
        image.name_full,
        tuple(image.size),
        image.filepath,
        image.source,
        image.is_dirty,
    )
    hit = _still.get(key)
    if hit is None:
        _still.clear()
        hit = _still[key] = (*image_pixels(image), {})
    return PlateFrame(hit[0], hit[1], disk_path(image) or image.name, key, hit[2])


def pixels(scene, image=None, number=None) -> tuple[np.ndarray, str]:
    """(pixels, info) of the scene's plate (or ``image``) at scene frame ``number``."""
    found = frame(scene, number, image)
    return found.pixels, found.info


def clear_cache():
    """Forget the still plate read (its file may have changed on disk)."""
    _still.clear()


def reset():
    """Forget everything read and close the frame readers (a new file, unregister)."""
    _still.clear()
    for reader in _readers.values():
        if on_main_thread():
            reader.close()
    _readers.clear()


def open_readers(scene):
    """Make the frame reader of ``scene``'s plate when it is a sequence or movie (main thread;
    a render thread can then read its frames)."""
    image = scene_plate(scene)
    if image is not None and image.source in MOVING and on_main_thread():
        with contextlib.suppress(ValueError):
            frame_reader(image)
