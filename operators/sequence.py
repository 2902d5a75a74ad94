"""Image sequences and movies as plates: every frame's maps come from that frame's plate.

Update Every Frame (``scene.virtual_reflections.sequence``): on every frame change -- viewport
playback, scrubbing, ``frame_set``, and each frame of a render -- the maps of the scene's
objects that have a reflection attached are rebuilt from the plate's current frame and the
objects' bounds at that frame. The batch's frame ranges (batch/ranges.py) call the same
`update` per frame.

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
  (`on_setting_changed`). A render job with the interface unlocked renders the maps as they were.
- No datablock is created or removed off the main thread: the private images that read the
  plate's frames (`plate.FramePlate`) are made on the main thread (`sync`, and every
  main-thread update); a render thread only loads a file into one and writes pixels into
  existing maps.

Plates are read per frame by plate.py (`plate.frame`).

Bounds are smoothed over time (`BoundsFilter`, an exponential filter, ``smoothing`` 0..1) and
rounded to whole plate pixels, so tracking jitter does not make the maps flicker and the
engine's cached lookup table is reused while the rounded bounds stay put.
"""

import contextlib
import math
from dataclasses import dataclass, field

import bpy
import numpy as np

from ..virtual_reflections import methods
from . import pipeline
from .node_trees import shading
from .scene import floor, maps, plate
from .scene.composite import union_box

# --- bounds over time --------------------------------------------------------------------------


class BoundsFilter:
    """Exponential smoothing of a box over frames, then rounding to whole plate pixels (or,
    with ``unit`` None, no rounding: the ground method's centre, which map_params rounds).

    smoothed = smoothing * previous smoothed + (1 - smoothing) * this frame's box; smoothing 0
    is off, 0.5 averages over ~3 frames, 0.9 over ~19 (and lags a moving object by
    smoothing / (1 - smoothing) frames of its motion). The filter restarts when frames jump
    (not the next frame: 0 < frame - last <= step), so scrubbing never smooths across a cut.
    The result is the smoothed box rounded to whole pixels: a jitter that smoothing brings
    below half a pixel leaves it unchanged, and so the cached lookup table is reused.
    """

    def __init__(self, unit=1.0):
        self.unit = unit
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
        held = self.smoothed if self.unit is None else np.floor(self.smoothed / self.unit + 0.5)
        self.held = tuple(float(v) * (self.unit or 1.0) for v in held)
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
class FrameUpdate(pipeline.Report):
    """What `update` did for one frame (the batch report's per-frame entry draws on it); a
    pipeline.Report (warnings, timings, tables built / reused) with, besides:

    frame: the scene frame; plate: the file read; info: how; maps: map image names rewritten;
    unchanged: maps whose plate frame and rounded bounds were those already in them; boxes:
    map name -> the rounded, smoothed box used (plate pixels); raw: the frame's own box.
    """

    frame: int = 0
    info: str = ""
    maps: list = field(default_factory=list)
    unchanged: list = field(default_factory=list)
    boxes: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)

    def summary(self):
        total = 1000 * sum(self.timings.values())
        return (
            f"frame {self.frame}: {len(self.maps)} map(s) updated, {len(self.unchanged)} "
            f"unchanged, tables {self.tables['built']} built / {self.tables['reused']} reused, "
            f"{total:.0f} ms"
        )


_filters = {}  # (scene name, map name) -> BoundsFilter, for the handler
_written = {}  # map name -> what its pixels were built from (plate identity, box, params, width)


def _group_box(view, scene, depsgraph, objs, warnings):
    """The union of ``objs``' boxes in plate pixels, or None when none is in view."""
    boxes, _, problems = pipeline.object_boxes(
        view, scene, depsgraph, objs, outside="its map is kept"
    )
    warnings += problems
    return union_box(boxes.values())


def advance(scene, depsgraph, filters, frame=None, step=1, plate_shape=None):
    """Step the bounds filters through ``frame`` without building maps (the batch runs this
    for frames it skips or pre-rolls, so that later frames match an uninterrupted run)."""
    frame = scene.frame_current if frame is None else frame
    settings = scene.virtual_reflections
    if plate_shape is None or scene.camera is None or scene.camera.type != "CAMERA":
        return
    view = pipeline.view(scene, plate_shape, depsgraph)
    for image, objs in shading.reflecting(scene).items():
        box = _group_box(view, scene, depsgraph, objs, [])
        if box is not None:
            filters.setdefault(image.name, BoundsFilter())(frame, box, settings.smoothing, step)
            _smoothed_centre(filters, image.name, depsgraph, objs, frame, settings, step)


def update(scene, depsgraph, *, filters=None, frame=None, step=1, plate_frame=None):
    """Rebuild the maps of ``scene``'s attached objects for ``frame`` (default: current).

    depsgraph: evaluated at that frame (a handler's, or the context's after frame_set).
    filters: map name -> BoundsFilter (default: the per-frame handler's, per scene).
    plate_frame: the plate.PlateFrame to build from (default: read for ``frame``).
    Returns a FrameUpdate. Raises ValueError (one line) for an unreadable plate; per-object
    problems are warnings.
    """
    frame = scene.frame_current if frame is None else frame
    settings = scene.virtual_reflections
    result = FrameUpdate(frame=frame)
    if scene.camera is None or scene.camera.type != "CAMERA":
        raise ValueError(f"scene '{scene.name}' has no camera")
    found = shading.reflecting(scene)
    if not found:
        result.warnings.append("no object has a reflection attached: generate first")
        return result
    if filters is None:
        filters = _filters
        prefix = scene.name
    else:
        prefix = None
    with result.timed("plate"):
        current = plate_frame if plate_frame is not None else plate.frame(scene, frame)
    result.plate, result.info = current.file, current.info
    with result.timed("bounds"):
        view = pipeline.view(scene, current.pixels.shape, depsgraph)
        probe = pipeline.scene_probe(scene, view, result)
    for image, objs in found.items():
        with result.timed("bounds"):
            raw = _group_box(view, scene, depsgraph, objs, result.warnings)
            if raw is None:
                continue
            key = (prefix, image.name) if prefix is not None else image.name
            held = filters.setdefault(key, BoundsFilter())(frame, raw, settings.smoothing, step)
            result.raw[image.name], result.boxes[image.name] = raw, held
        width = _width(settings, image)
        centre = _smoothed_centre(filters, key, depsgraph, objs, frame, settings, step)
        request = pipeline.reflect_request(view, scene, depsgraph, objs, held, width, centre=centre)
        shaped = request.params
        built_from = (
            current.identity,
            held,
            shaped,
            width,
            image.name_full,
            None if probe is None else probe.key,
        )
        if _written.get(image.name) == built_from and tuple(image.size) == (width, width // 2):
            result.unchanged.append(image.name)
            continue
        env, _ = pipeline.build_map(
            current.pixels, held, shaped, width, result, roughness=request.roughness, probe=probe
        )
        with result.timed("image"):
            _write_map(image, env)
        _written[image.name] = built_from
        result.maps.append(image.name)
    return result


def _smoothed_centre(filters, key, depsgraph, objs, frame, settings, step):
    """Camera View + Ground: the objects' centre smoothed over frames like their box (so the
    ground seen from it steadies with the box); None for the other methods."""
    if not methods.reads_ground(settings.method):
        return None
    raw = floor.objects_centre(depsgraph, objs)
    # (scene, map, "centre") for the handler's filters: cleared with the scene's on render_init
    centre_key = (*key, "centre") if isinstance(key, tuple) else (key, "centre")
    held = filters.setdefault(centre_key, BoundsFilter(unit=None))
    return held(frame, raw, settings.smoothing, step)


def _width(settings, image):
    """The map width: the setting's, or with Auto the width Generate chose for this map (a map
    that changed size with the object's extent from frame to frame would flicker in detail)."""
    if settings.resolution == "AUTO":
        return image.size[0] if image.size[0] > 0 else 1024
    return int(settings.resolution)


def _write_map(image, env):
    """The frame's map into the existing map image, in place (maps.overwrite: may run on a
    render thread); one of another size is stored anew, on the main thread only."""
    if tuple(image.size) != env.shape[1::-1] and plate.on_main_thread():
        maps.store_map(image.name, env)
        return
    maps.overwrite(image, env)


# bpy 4.5's Cycles keeps the pixels it loaded of an image while Persistent Data is on: a map
# rewritten in place is not seen again and every frame renders the first one's (5.x reloads a
# tagged image: maps.touch; tests/blender/test_map_refresh.py).
PERSISTENT_DATA_KEEPS_MAPS = bpy.app.version < (5, 0, 0)


def keep_maps_fresh(render) -> bool:
    """Turn ``render.use_persistent_data`` off where it would freeze per-frame maps (bpy 4.x);
    True when it did."""
    if PERSISTENT_DATA_KEEPS_MAPS and render.use_persistent_data:
        render.use_persistent_data = False
        return True
    return False


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
        if plate.on_main_thread():
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
        if not plate.on_main_thread():
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
    plate.reset()


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
        plate.open_readers(scene)


def on_setting_changed(settings, context):
    """Update callback of ``scene.virtual_reflections.sequence``."""
    scene = settings.id_data
    if settings.sequence and not scene.render.use_lock_interface:
        scene.render.use_lock_interface = True
    if settings.sequence:
        keep_maps_fresh(scene.render)
    sync()


def register():
    _add(_FILE_HANDLERS)
    sync()


def unregister():
    _remove(_LIVE_HANDLERS)
    _remove(_FILE_HANDLERS)
    reset()
