"""Image sequences and movies as plates: every frame's maps come from that frame's plate.

Update Every Frame (``scene.virtual_reflections.sequence``): on every frame change -- viewport
playback, scrubbing, ``frame_set``, and each frame of a render -- the maps of the scene's
objects that have a reflection attached are rebuilt from the plate's current frame and the
objects' bounds at that frame. The batch entry (batch.py) calls the same `update` per frame.

Frames and threads, verified in Blender 4.5 and 5.2 (tests/blender/test_sequence.py; an
interactive render in Blender's window: tests/e2e/test_sequence_blender.py):

- Rendering an animation, Blender calls, per frame: ``render_pre`` (scene.frame_current is
  the new frame, but no depsgraph is evaluated there yet: the view layer's shows the old
  frame), then ``frame_change_pre`` / ``frame_change_post`` with the render's own depsgraph
  evaluated at the new frame, then the engine syncs the scene and renders. So the maps are
  built in ``frame_change_post``, from the depsgraph it is given: before the render starts,
  with the bounds of the frame being rendered.
- ``blender -b ... -a``, ``bpy.ops.render.render(animation=True)`` without a window and the
  bpy module run all of this on the main thread; ``bpy.app.is_job_running('RENDER')`` is
  False there. An interactive render (F12, Ctrl F12) is a job: the same handlers run on the
  render job's thread with ``is_job_running('RENDER')`` True. Blender's API documentation
  ("Note on Altering Data" in bpy.app.handlers) allows data edits from those handlers only
  with the interface locked (``render.use_lock_interface``), else the viewport may draw the
  data while it changes. So edits happen on the main thread when no render job runs, and
  during a render job only when the interface is locked; turning Update Every Frame on locks it
  (`enable`). A render job with the interface unlocked renders the maps as they were.
- No datablock is created or removed off the main thread: the private images that read the
  plate's frames (`FramePlate`) are made on the main thread (`sync`, and every main-thread
  update); a render thread only loads a file into one and writes pixels into existing maps.

Reading frame n of a sequence or a movie: ``Image.pixels`` has no frame argument (it shows
the frame last loaded through an image user). Sequences: frame n's file (Blender's rule: the
last run of digits in the file name, padded to its width) is loaded into a private image.
Movies: ``Image.scale(w, h, frame=n)`` on a private copy of the movie -- the one Python call
that acquires a given frame, in 4.5 and 5.x -- leaves that frame in the copy's pixels. The
plate frame of a scene frame follows the camera's background image of the plate when that
has a frame range set (Start, Offset, Frames, Cyclic, as Blender maps it); else plate frame =
scene frame.

Bounds are smoothed over time (`BoundsFilter`, an exponential filter, ``smoothing`` 0..1) and
rounded to whole plate pixels, so tracking jitter does not make the maps flicker and the
engine's cached lookup table is reused while the rounded bounds stay put.
"""

import contextlib
import math
import os
import re
import threading
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..virtual_reflections import lookup_table
from ..virtual_reflections.envmap import apply_table
from ..virtual_reflections.frames import (  # noqa: F401 (re-exported for batch.py and tests)
    FRAMES_HELP,
    MAX_FRAMES,
    MOVIE_EXTENSIONS,
    is_movie_path,
    is_pattern,
    parse_frames,
    pattern_path,
    sequence_path,
    sequence_range,
    user_frame,
)
from . import bounds, compositor, generate, maps, shading

FRAME_IMAGE = ".VR Plate Frame"  # private images reading plate frames (dot: hidden in lists)
CREATED = "vr_created"  # their custom property, value "plate_frame"
# --- reading frame n of a plate -----------------------------------------------------------------


def _on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


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


class FramePlate:
    """Reads frame n of a SEQUENCE or MOVIE image through a private image made on the main
    thread, so the artist's image is never touched. `read` may run on a render thread: it only
    loads a file into the private image. The private image is found by name each time (a
    Python reference to an ID does not survive undo)."""

    def __init__(self, image):
        if not _on_main_thread():
            raise RuntimeError("plate frame readers are made on the main thread")
        self.source = image.source
        self.path = compositor._disk_path(image)
        if self.path is None:
            raise ValueError(f"plate '{image.name}': a {image.source.lower()} must be a file")
        if self.source == "SEQUENCE":
            sequence_path(self.path, 0)  # ValueError without a frame number in the name
        self.colorspace = image.colorspace_settings.name
        self.key = reader_key(image)
        self.name = None  # the private image's name
        self.loaded = None  # the last frame read: ((number, file, mtime), result)
        self._private()

    def _private(self):
        image = bpy.data.images.get(self.name) if self.name else None
        if image is not None and image.get(CREATED) == "plate_frame":
            return image
        if not _on_main_thread():
            raise ValueError("the plate's frame reader is gone; change the frame once")
        if not os.path.isfile(self.path):
            raise ValueError(f"plate not found: {self.path}")
        image = bpy.data.images.load(self.path, check_existing=False)
        image.name = FRAME_IMAGE
        image[CREATED] = "plate_frame"
        with contextlib.suppress(TypeError):  # a colour space this Blender does not know
            image.colorspace_settings.name = self.colorspace
        self.name = image.name
        return image

    def file(self, number):
        return sequence_path(self.path, number) if self.source == "SEQUENCE" else self.path

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
            pixels, info = compositor.plate_image_pixels(image)
        else:
            count = image.frame_duration
            if not 1 <= number <= count:
                raise ValueError(f"plate frame {number}: the movie {path} has frames 1-{count}")
            w, h = image.size
            image.scale(w, h, frame=number)  # loads that frame into the private copy
            pixels, info = compositor.plate_image_pixels(image)
            # scale() marks the frame's buffer dirty, and Blender never frees dirty movie
            # frames by itself: free them, or a long movie would stay in memory frame by frame.
            image.buffers_free()
        self.loaded = (key, (pixels, f"{info}; frame {number}", path))
        return self.loaded[1]

    def close(self):
        """Remove the private image (main thread)."""
        image = bpy.data.images.get(self.name) if self.name else None
        if image is not None and image.get(CREATED) == "plate_frame":
            bpy.data.images.remove(image)
        self.name = None


_readers = {}  # reader_key -> FramePlate
_stills = {}  # the last still plate read: key -> (pixels, info)


def reader_key(image):
    return (image.name_full, image.source, image.filepath, image.colorspace_settings.name)


def frame_reader(image, create=True):
    """The FramePlate of a sequence/movie image (made when ``create`` and on the main thread),
    or None."""
    key = reader_key(image)
    reader = _readers.get(key)
    if reader is None and create and _on_main_thread():
        reader = _readers[key] = FramePlate(image)
    return reader


def frame_plate(scene, frame=None):
    """The scene's plate at ``frame`` (default: current) -> (pixels, info, file, identity).

    pixels: (H, W, 3) float32 scene-linear; file: the file read; identity: a hashable value
    that changes exactly when the pixels do. Stills are cached across frames. Raises
    ValueError (one line) when there is no plate or the frame cannot be read.
    """
    image = compositor.scene_plate(scene)
    if image is None:
        raise ValueError("no plate: pick a plate image or give the camera a background image")
    if image.source in {"SEQUENCE", "MOVIE"}:
        reader = frame_reader(image)
        if reader is None:
            raise ValueError(
                f"plate '{image.name}': its frames are read through a private image made on "
                "the main thread; change the frame once before rendering"
            )
        number = plate_frame(scene, image, frame)
        pixels, info, path = reader.read(number)
        return pixels, info, path, (reader.key, reader.loaded[0])
    key = (
        image.session_uid,
        image.name_full,
        tuple(image.size),
        image.filepath,
        image.source,
        image.is_dirty,
    )
    hit = _stills.get(key)
    if hit is None:
        _stills.clear()
        hit = _stills[key] = compositor.plate_image_pixels(image)
    return hit[0], hit[1], compositor._disk_path(image) or image.name, key


def frame_size(image):
    """(width, height) of a sequence/movie image: of the file its path names (sequences) or
    of its first frame (movies). ValueError (one line) when that cannot be read."""
    if image.get(CREATED) == "plate_frame":  # a reader's own copy: it holds the frame read
        return tuple(image.size)
    reader = frame_reader(image)
    if reader is None:
        raise ValueError(f"plate '{image.name}': no frame reader (made on the main thread)")
    number = 1
    if reader.source == "SEQUENCE":
        m = re.search(r"(\d+)\D*$", os.path.splitext(os.path.basename(reader.path))[0])
        number = int(m.group(1)) if m else 0
    pixels = reader.read(number)[0]
    return pixels.shape[1], pixels.shape[0]


def image_pixels(scene, image, frame=None):
    """A sequence/movie ``image``'s pixels at scene ``frame`` -> (pixels, info); what
    `generate.plate_pixels` returns for such plates. ValueError off the main thread when its
    reader does not exist yet."""
    reader = frame_reader(image)
    if reader is None:
        raise ValueError(f"plate '{image.name}': no frame reader (made on the main thread)")
    pixels, info, _ = reader.read(plate_frame(scene, image, frame))
    return pixels, info


# --- bounds over time --------------------------------------------------------------------------


class BoundsFilter:
    """Exponential smoothing of a box over frames, then rounding to whole plate pixels.

    smoothed = smoothing * previous smoothed + (1 - smoothing) * this frame's box; smoothing 0
    is off, 0.5 averages over ~3 frames, 0.9 over ~19 (and lags a moving object by
    smoothing / (1 - smoothing) frames of its motion). The filter restarts when frames jump
    (not the next frame: 0 < frame - last <= step), so scrubbing never smooths across a cut.
    The result is the smoothed box rounded to whole pixels: a jitter that smoothing brings
    below half a pixel leaves it unchanged, and so the cached lookup table is reused.
    """

    def __init__(self):
        self.frame = None
        self.smoothed = None
        self.held = None

    def __call__(self, frame, box, smoothing, step=1):
        box = np.asarray(box, dtype=np.float64)
        a = min(max(float(smoothing), 0.0), 0.99)
        if self.frame is not None and frame == self.frame:
            return self.held  # the same frame again (a render after frame_set): no new step
        if self.smoothed is None or not 0 < frame - self.frame <= max(1, step):
            self.smoothed = box
        else:
            self.smoothed = a * self.smoothed + (1.0 - a) * box
        self.frame = frame
        self.held = tuple(float(v) for v in np.floor(self.smoothed + 0.5))
        return self.held


def preroll(smoothing, tolerance=1e-3, limit=100) -> int:
    """Frames to run a filter over before the first one wanted, so that the frames before a
    chunk's start weigh less than ``tolerance`` in its first frame (chunks of a farm and one
    uninterrupted run then agree)."""
    a = min(max(float(smoothing), 0.0), 0.99)
    if a <= 0.0:
        return 0
    return min(limit, math.ceil(math.log(tolerance) / math.log(a)))


# --- one frame ---------------------------------------------------------------------------------


@dataclass
class FrameUpdate:
    """What `update` did for one frame (the batch report's per-frame entry draws on it).

    maps: map image names rewritten; unchanged: maps whose plate frame and rounded bounds were
    those already in them; tables: lookup tables built / reused from the engine's cache;
    boxes: map name -> the rounded, smoothed box used (plate pixels); raw: the frame's own box.
    """

    frame: int
    plate: str = ""
    info: str = ""
    maps: list = field(default_factory=list)
    unchanged: list = field(default_factory=list)
    tables: dict = field(default_factory=lambda: {"built": 0, "reused": 0})
    boxes: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)

    def time(self, stage, seconds):
        self.timings[stage] = self.timings.get(stage, 0.0) + seconds

    def summary(self):
        total = 1000 * sum(self.timings.values())
        return (
            f"frame {self.frame}: {len(self.maps)} map(s) updated, {len(self.unchanged)} "
            f"unchanged, tables {self.tables['built']} built / {self.tables['reused']} reused, "
            f"{total:.0f} ms"
        )


def targets(scene):
    """[(map image, [objects])]: each attached object's map, and the shared World map with the
    objects in World mode. Only objects in ``scene`` with a reflection attached count."""
    found, world_objects = [], []
    for obj in scene.objects:
        record = obj.get(shading.RECORD)
        if record is None or obj.type not in generate.REFLECTABLE:
            continue
        if record.get("mode") == "WORLD":
            world_objects.append(obj)
        elif record.get("image") is not None:
            found.append((record["image"], [obj]))
    if world_objects:
        record = scene.get(shading.WORLD_RECORD)
        world = record.get("world") if record is not None else None
        tree = world.node_tree if world is not None else None
        node = tree.nodes.get("VR Environment") if tree is not None else None
        if node is not None and node.image is not None:
            found.append((node.image, world_objects))
    return found


_filters = {}  # (scene name, map name) -> BoundsFilter, for the handler
_written = {}  # map name -> what its pixels were built from (plate identity, box, params, width)


def _frame_boxes(scene, depsgraph, objs, projection, scale, update):
    boxes = []
    for obj in objs:
        try:
            box = bounds.object_bounds(obj, depsgraph, scene, projection=projection)
        except ValueError as exc:
            update.warnings.append(f"{obj.name}: {exc}")
            continue
        if box.visible:
            sx, sy = scale
            boxes.append((box.x0 * sx, box.y0 * sy, box.x1 * sx, box.y1 * sy))
        else:
            update.warnings.append(f"{obj.name} is outside the camera view: its map is kept")
    if not boxes:
        return None
    return tuple(f(b[k] for b in boxes) for k, f in enumerate((min, min, max, max)))


def _projection(scene, depsgraph, plate_shape):
    # The camera as evaluated in `depsgraph`: during a render the original objects still hold
    # the frame the viewport showed before.
    camera = scene.camera.evaluated_get(depsgraph) if depsgraph is not None else scene.camera
    projection = bounds.camera_projection(scene, camera)
    ph, pw = plate_shape[:2]
    return projection, (pw / projection.width, ph / projection.height)


def advance(scene, depsgraph, filters, frame=None, step=1, plate_shape=None):
    """Step the bounds filters through ``frame`` without building maps (the batch runs this
    for frames it skips or pre-rolls, so that later frames match an uninterrupted run)."""
    frame = scene.frame_current if frame is None else frame
    settings = scene.virtual_reflections
    if plate_shape is None or scene.camera is None or scene.camera.type != "CAMERA":
        return
    projection, scale = _projection(scene, depsgraph, plate_shape)
    quiet = FrameUpdate(frame)
    for image, objs in targets(scene):
        box = _frame_boxes(scene, depsgraph, objs, projection, scale, quiet)
        if box is not None:
            filters.setdefault(image.name, BoundsFilter())(frame, box, settings.smoothing, step)


def update(scene, depsgraph, *, filters=None, frame=None, step=1, plate=None) -> FrameUpdate:
    """Rebuild the maps of ``scene``'s attached objects for ``frame`` (default: current).

    depsgraph: evaluated at that frame (a handler's, or the context's after frame_set).
    filters: map name -> BoundsFilter (default: the per-frame handler's, per scene).
    plate: (pixels, info, file, identity) as `frame_plate` returns it (default: read).
    Raises ValueError (one line) for an unreadable plate; per-object problems are warnings.
    """
    frame = scene.frame_current if frame is None else frame
    settings = scene.virtual_reflections
    result = FrameUpdate(frame)
    if scene.camera is None or scene.camera.type != "CAMERA":
        raise ValueError(f"scene '{scene.name}' has no camera")
    found = targets(scene)
    if not found:
        result.warnings.append("no object has a reflection attached: generate first")
        return result
    if filters is None:
        filters = _filters
        prefix = scene.name
    else:
        prefix = None
    t = time.perf_counter()
    pixels, info, path, identity = plate if plate is not None else frame_plate(scene, frame)
    result.time("plate", time.perf_counter() - t)
    result.plate, result.info = path, info
    t = time.perf_counter()
    projection, scale = _projection(scene, depsgraph, pixels.shape)
    params = settings.params(generate._intrinsics(projection, *scale))
    result.time("bounds", time.perf_counter() - t)
    ph, pw = pixels.shape[:2]
    for image, objs in found:
        t = time.perf_counter()
        raw = _frame_boxes(scene, depsgraph, objs, projection, scale, result)
        if raw is None:
            result.time("bounds", time.perf_counter() - t)
            continue
        key = (prefix, image.name) if prefix is not None else image.name
        held = filters.setdefault(key, BoundsFilter())(frame, raw, settings.smoothing, step)
        result.raw[image.name], result.boxes[image.name] = raw, held
        result.time("bounds", time.perf_counter() - t)
        width = _width(settings, image)
        built_from = (identity, held, params, width, image.name_full)
        if _written.get(image.name) == built_from and tuple(image.size) == (width, width // 2):
            result.unchanged.append(image.name)
            continue
        t = time.perf_counter()
        misses = lookup_table.cache_info().misses
        table = lookup_table(pw, ph, held, params, "latlong", width)
        result.tables["built" if lookup_table.cache_info().misses > misses else "reused"] += 1
        result.time("table", time.perf_counter() - t)
        t = time.perf_counter()
        env = apply_table(table, pixels)
        result.time("gather", time.perf_counter() - t)
        t = time.perf_counter()
        _write_map(image, env)
        result.time("image", time.perf_counter() - t)
        _written[image.name] = built_from
        result.maps.append(image.name)
    return result


def _width(settings, image):
    """The map width: the setting's, or with Auto the width Generate chose for this map (a map
    that changed size with the object's extent from frame to frame would flicker in detail)."""
    if settings.resolution == "AUTO":
        return image.size[0] if image.size[0] > 0 else 1024
    return int(settings.resolution)


def _write_map(image, env):
    """Write an (H, W, 3) map into the existing map image, in place. Unlike `maps.store_map`
    nothing but pixels changes (no saving, no new datablock), so it may run on a render
    thread; the map is marked to be packed again at the next save when it is packed."""
    h, w = env.shape[:2]
    if tuple(image.size) != (w, h):
        if not _on_main_thread():
            raise ValueError(f"map '{image.name}' has another size; generate again")
        maps.store_map(image.name, env)
        return
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = env[::-1]
    image.pixels.foreach_set(rgba.ravel())
    image.update()
    if image.get(maps.NEEDS_PACK) is False:
        image[maps.NEEDS_PACK] = True  # packed maps: pack this frame's map at the next save


# --- Update Every Frame: handlers ------------------------------------------------------------

_state = {"suspended": 0, "last": {}, "skipped": {}}


def status(scene):
    """The last per-frame update of ``scene`` as one line (the panel shows it), or ""."""
    return _state["last"].get(scene.name, "")


def _job_running():
    """An interactive render (F12) is running: its handlers run on the render job's thread."""
    return bpy.app.is_job_running("RENDER")


def may_edit(scene):
    """(True, "") when the handler may change data now; else (False, why). See the module
    docstring: main thread without a render job, or a render job with the interface locked."""
    if not _job_running():
        if _on_main_thread():
            return True, ""
        return False, "not on Blender's main thread"
    if scene.render.use_lock_interface:
        return True, ""
    return False, "a render is running with Render > Lock Interface off: maps left as they are"


@contextlib.contextmanager
def suspended():
    """Within: the per-frame handler does nothing (the batch updates maps itself)."""
    _state["suspended"] += 1
    try:
        yield
    finally:
        _state["suspended"] -= 1


@bpy.app.handlers.persistent
def _on_frame_change(scene, depsgraph=None):
    settings = getattr(scene, "virtual_reflections", None)
    if _state["suspended"] or settings is None or not settings.sequence:
        return
    ok, why = may_edit(scene)
    if not ok:
        _state["skipped"][scene.name] = why
        _state["last"][scene.name] = f"frame {scene.frame_current}: skipped, {why}"
        return
    if depsgraph is None:
        if not _on_main_thread():
            return
        depsgraph = bpy.context.evaluated_depsgraph_get()
    try:
        result = update(scene, depsgraph, step=scene.frame_step)
    except (ValueError, RuntimeError) as exc:  # a missing frame must not stop a render
        _state["last"][scene.name] = f"frame {scene.frame_current}: {exc}"
        print(f"Virtual Reflections: {_state['last'][scene.name]}")
        return
    line = result.summary()
    if result.warnings:
        line += "; " + "; ".join(result.warnings)
    _state["last"][scene.name] = line


@bpy.app.handlers.persistent
def _on_render_init(scene, depsgraph=None):
    # A render starts the bounds filters afresh, so it does not depend on what the viewport
    # played before (the batch does the same). Python state only: safe on a render thread.
    for key in [k for k in _filters if k[0] == scene.name]:
        del _filters[key]
    _written.clear()


@bpy.app.handlers.persistent
def _on_load_pre(*_args):
    remove_handlers()
    reset()


@bpy.app.handlers.persistent
def _on_load_post(*_args):
    sync()


_LIVE_HANDLERS = (("frame_change_post", _on_frame_change), ("render_init", _on_render_init))
_FILE_HANDLERS = (("load_pre", _on_load_pre), ("load_post", _on_load_post))


def _add(pairs):
    for name, function in pairs:
        handlers = getattr(bpy.app.handlers, name)
        if function not in handlers:
            handlers.append(function)


def _remove(pairs):
    for name, function in pairs:
        handlers = getattr(bpy.app.handlers, name)
        while function in handlers:
            handlers.remove(function)


def remove_handlers():
    _remove(_LIVE_HANDLERS)


def installed() -> bool:
    return _on_frame_change in bpy.app.handlers.frame_change_post


def reset():
    """Forget filters, readers and what the maps were built from (a new file, unregister)."""
    _filters.clear()
    _written.clear()
    _state["last"].clear()
    _state["skipped"].clear()
    _stills.clear()
    for reader in _readers.values():
        if _on_main_thread():
            reader.close()
    _readers.clear()


def sync():
    """Install the per-frame handlers when a scene of the open file has Update Every Frame on,
    remove them otherwise; make the plate frame readers of those scenes (main thread)."""
    try:
        scenes = list(bpy.data.scenes)
    except AttributeError:  # registering at start-up: no file data yet (load_post follows)
        return
    live = [
        s
        for s in scenes
        if getattr(s, "virtual_reflections", None) and s.virtual_reflections.sequence
    ]
    if not live:
        remove_handlers()
        return
    _add(_LIVE_HANDLERS)
    for scene in live:
        image = compositor.scene_plate(scene)
        if image is not None and image.source in {"SEQUENCE", "MOVIE"} and _on_main_thread():
            with contextlib.suppress(ValueError):
                frame_reader(image)


def enable(scene, on=True):
    """Turn Update Every Frame on or off for ``scene`` (the property's update calls `sync`). On also
    locks the interface during renders, which Blender requires for data edits from handlers
    during an interactive render."""
    if on:
        scene.render.use_lock_interface = True
    scene.virtual_reflections.sequence = on


def on_setting_changed(settings, context):
    """Update callback of ``scene.virtual_reflections.sequence``."""
    scene = settings.id_data
    if settings.sequence and not scene.render.use_lock_interface:
        scene.render.use_lock_interface = True
    sync()


def register():
    _add(_FILE_HANDLERS)
    sync()


def unregister():
    _remove(_LIVE_HANDLERS)
    _remove(_FILE_HANDLERS)
    reset()
