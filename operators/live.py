"""Live update: a reflective object's map follows it while the artist moves, turns or scales it
or edits its mesh (``scene.virtual_reflections.live_update``).

Per change the data flows one way (the map pipeline, pipeline.py):

    depsgraph_update_post  which reflective objects changed? (a set lookup per update; other
                           objects, images and selection changes are ignored)
      -> pending names, a timer (bpy.app.timers) that coalesces every update since it last ran,
         at most MAX_RATE times a second
      -> per map: the evaluated object's screen bounds (bounds.object_bounds) rounded to whole
         plate pixels; unchanged -> nothing (the engine's cached table is reused when an object
         comes back to where it was)
      -> moving: a MOVING_WIDTH map from the plate reduced to about 1.5 x that width (small
         table, small gather)
      -> resting for REST seconds: the full map (the scene's resolution, the whole plate), saved
         or marked for packing as Generate does.

Only objects that already have a reflection (Generate attached one) are followed; in World mode
the shared map follows the union of its objects' bounds. Nothing runs while a render job runs
(``bpy.app.is_job_running("RENDER")``): changes wait until it ends. The handler is installed
while a scene of the open file has live update on and removed on unregister and before another
file loads (``load_pre``); after loading, a file whose scene has it on turns it on again.

Image sequences and movies on frame changes are sequence.py's ("Update Every Frame").
"""

import threading
import time
from dataclasses import dataclass, field, replace

import bpy

from ..virtual_reflections import methods
from ..virtual_reflections.mipmap import build_pyramid, level_shapes, level_view
from . import pipeline, previews
from .node_trees import shading, world_probe
from .scene import app_handlers, maps, plate
from .scene.choices import map_width
from .scene.composite import union_box

MOVING_WIDTH = 256  # map width while the object moves
PLATE_MARGIN = 1.5  # the reduced plate stays at least this many times the moving map's width
REST = 0.3  # seconds without a change before the full map is built
MAX_RATE = 60.0  # at most this many moving passes a second (leaves the viewport time to draw)


@dataclass
class _State:
    scene: str = ""  # the scene whose objects are pending
    pending: set = field(default_factory=set)  # object names that changed since the last pass
    resting: dict = field(default_factory=dict)  # map built small -> its objects' names
    built: dict = field(default_factory=dict)  # map name -> (what it was built from, width)
    scene_key: dict = field(default_factory=dict)  # scene name -> settings that shape a map
    last_change: float = 0.0
    last_pass: float = 0.0
    next_tick: float = 0.0  # when the registered timer runs next (time.monotonic)
    reduced: tuple = ()  # (plate array id, level, reduced plate)
    status: dict = field(default_factory=dict)  # scene name -> one line for the panel
    passes: int = 0
    last_report: object = None  # the last pass's Report (benchmarks read its timings)


_state = _State()


# --- what to rebuild -----------------------------------------------------------------------------


def _scene_key(scene):
    """What, besides the objects, shapes a map: the method's settings, the plate, the render."""
    s, r = scene.virtual_reflections, scene.render
    image = plate.scene_plate(scene)
    return (
        s.enlarge,
        s.border,
        s.front,
        s.triangles,
        s.method,
        s.resolution,
        image.name_full if image is not None else None,
        r.resolution_x,
        r.resolution_y,
        r.resolution_percentage,
        r.pixel_aspect_x,
        r.pixel_aspect_y,
    )


def _reads_world(scene) -> bool:
    settings = scene.virtual_reflections
    return methods.takes_world_hdri(settings.method, settings.surroundings)


def _world_image(world):
    try:
        return world_probe.environment_node(world).image
    except ValueError:
        return None


def changed_objects(scene, depsgraph) -> set:
    """Names of ``scene``'s reflective objects a depsgraph update may have moved on screen:
    the objects themselves (transform or geometry), or all of them when the camera or the
    settings that shape a map changed. Cheap: no bounds are computed here."""
    camera = scene.camera
    names, everything = set(), False
    for update in depsgraph.updates:
        data = getattr(update.id, "original", update.id)
        if isinstance(data, bpy.types.Object):
            if not (update.is_updated_transform or update.is_updated_geometry):
                continue
            if data == camera:
                everything = True
            elif shading.is_attached(data):
                names.add(data.name)
        elif isinstance(data, bpy.types.Camera):
            everything = everything or (camera is not None and camera.data == data)
        elif isinstance(data, (bpy.types.World, bpy.types.Image)) and _reads_world(scene):
            # Surroundings World HDRI: the artist turning or swapping the HDRI
            world = world_probe.user_world(scene)
            everything = everything or data == world or _world_image(world) == data
        elif isinstance(data, bpy.types.Scene) and data == scene:
            key = _scene_key(scene)
            if _state.scene_key.get(scene.name) != key:
                _state.scene_key[scene.name] = key
                everything = True
    if everything:
        names |= {o.name for o in scene.objects if shading.is_attached(o)}
    return names


# --- the handler and the timer ------------------------------------------------------------------


def on_depsgraph_update(scene, depsgraph):
    """depsgraph_update_post: note which reflective objects changed and wake the timer."""
    settings = getattr(scene, "virtual_reflections", None)
    if settings is None or not settings.live_update:
        return
    if threading.current_thread() is not threading.main_thread():
        return  # a render thread's depsgraph: not the artist's edits
    names = changed_objects(scene, depsgraph)
    if names:
        queue(scene, names)


def queue(scene, names):
    """Mark objects of ``scene`` as changed; the timer rebuilds their maps soon."""
    if _state.scene != scene.name:
        _state.pending.clear()
        _state.resting.clear()
        _state.scene = scene.name
    _state.pending |= set(names)
    _state.last_change = time.monotonic()
    # Come back soon for the preview, however long the timer was going to sleep. A timer
    # already due that soon is left alone: registering it again would put it behind the
    # other timers, and updates that come from a timer (scripts, drivers) would starve it.
    # Timers are persistent and always unregistered by us: one a file load removed makes the
    # bpy 4.5 module hang at exit.
    wait = _until_next_pass()
    if bpy.app.timers.is_registered(tick):
        if _state.next_tick <= time.monotonic() + wait:
            return
        bpy.app.timers.unregister(tick)
    _state.next_tick = time.monotonic() + wait
    bpy.app.timers.register(tick, first_interval=wait, persistent=True)


def _until_next_pass():
    return max(0.0, _state.last_pass + 1.0 / MAX_RATE - time.monotonic())


def pending() -> set:
    return set(_state.pending)


def resting() -> set:
    """Names of the maps built small, waiting for their full size."""
    return set(_state.resting)


def render_running() -> bool:
    return bpy.app.is_job_running("RENDER")


def tick():
    """The timer: a preview pass for what changed, the full maps once things rest. Returns
    seconds until it should run again, or None when there is nothing left to do."""
    wait = _tick()
    _state.next_tick = time.monotonic() + (wait if wait is not None else 0.0)
    return wait


def _tick():
    scene = bpy.data.scenes.get(_state.scene)
    if scene is None or not scene.virtual_reflections.live_update:
        _state.pending.clear()
        _state.resting.clear()
        return None
    if render_running():
        return 0.5  # a render reads the maps: wait until it ends
    if _state.pending:
        wait = _until_next_pass()
        if wait > 0:
            return wait
        flush(scene, full=False)
        return REST
    if _state.resting:
        wait = _state.last_change + REST - time.monotonic()
        if wait > 0:
            return wait
        flush(scene, full=True)
    return None


def flush(scene=None, full=False, depsgraph=None) -> pipeline.Report:
    """Rebuild now: the pending objects' maps small (``full`` False), or the resting maps (and
    any pending ones) at full size. Returns a Report: ``done`` the maps rebuilt, ``timings``
    per stage, ``warnings``. Tests and benchmarks call this directly instead of the timer."""
    scene = scene or bpy.data.scenes.get(_state.scene) or bpy.context.scene
    report = pipeline.Report()
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()  # may call the handler: read after
    names = set(_state.pending)
    if full:
        names = names.union(*_state.resting.values())
    _state.pending.clear()
    _state.last_pass = time.monotonic()
    if full:
        _state.resting.clear()
    if not names:
        return report
    try:
        _rebuild(scene, depsgraph, names, full, report)
    except (ValueError, RuntimeError) as exc:  # no camera or plate: the panel says so
        report.warnings.append(str(exc))
    _state.passes += 1
    _state.last_report = report
    _set_status(scene, report, full)
    _redraw()
    return report


def _rebuild(scene, depsgraph, names, full, report):
    settings = scene.virtual_reflections
    image = plate.require_plate(scene)
    with report.timed("plate"):
        pixels, _info = plate.pixels(scene, image)
    targets = shading.reflecting(scene, names)
    if not targets:
        return
    with report.timed("bounds"):
        view = pipeline.view(scene, pixels.shape, depsgraph)
        probe = pipeline.scene_probe(scene, view, report)
    save_dir = None
    if full:
        try:
            save_dir = maps.save_folder(settings)
        except ValueError as exc:
            report.warnings.append(f"maps kept in memory: {exc}")
    for map_image, objs in targets.items():
        with report.timed("bounds"):
            boxes, extents, _ = pipeline.object_boxes(view, scene, depsgraph, objs)
        if not boxes:
            continue  # off screen: keep the map it had
        rounded = tuple(float(round(v)) for v in union_box(boxes.values()))
        full_width = map_width(settings.resolution, max(extents.values()))
        own = pipeline.reflect_request(
            view, scene, depsgraph, list(boxes), rounded, full_width
        ).params
        base = (id(pixels), rounded, own, None if probe is None else probe.key)
        built = _state.built.get(map_image.name)
        if built is not None and built[0] == base and (not full or built[1] == full_width):
            continue  # same rounded bounds: the map it has is right
        width = full_width if full else min(MOVING_WIDTH, full_width)
        source, box, shaped = pixels, rounded, own
        if not full:
            source, level = _reduced(pixels, width)
            box = tuple(v / 2**level for v in rounded)
            if level and shaped.intrinsics is not None:  # the camera-view method: plate pixels
                shaped = replace(shaped, intrinsics=tuple(v / 2**level for v in shaped.intrinsics))
        world = shading.mode_of(objs[0]) == "WORLD"
        name = ("World" if world else objs[0].name) if full else None
        rough = pipeline.map_roughness(settings, objs) if full else 0.0  # sharp while moving
        env, _ = pipeline.build_map(source, box, shaped, width, report, name, rough, probe=probe)
        with report.timed("image"):
            for obj, b in boxes.items():
                obj.virtual_reflections.bounds = b  # the panel's segmentation preview follows
            if full:
                maps.store_map(map_image.name, env, save_dir)
            else:
                maps.show_pixels(map_image, env)
                _state.resting[map_image.name] = {o.name for o in objs}
            map_image.update_tag()  # Cycles' rendered viewport reloads tagged images
        _state.built[map_image.name] = (base, width)
        report.done.append(map_image.name)
        previews.note_map(map_image, env)


def _reduced(pixels, width):
    """The pixels box-filtered down to the coarsest mip level still PLATE_MARGIN x ``width``
    wide, and that level; cached for the plate being dragged over."""
    h, w = pixels.shape[:2]
    level = 0
    while w / 2 ** (level + 1) >= PLATE_MARGIN * width and level < 6:
        level += 1
    if level == 0:
        return pixels, 0
    if _state.reduced[:2] != (id(pixels), level):
        shapes = level_shapes(h, w, level + 1)
        flat = build_pyramid(pixels, level + 1, level)
        _state.reduced = (id(pixels), level, level_view(flat, shapes, level, level).copy())
    return _state.reduced[2], level


def _set_status(scene, report, full):
    if not report.done:
        line = "; ".join(report.warnings)
    else:
        ms = 1000 * sum(report.timings.values())
        line = f"{'full' if full else 'moving'}: {len(report.done)} map(s) in {ms:.0f} ms"
        if report.warnings:
            line += f"; {report.warnings[0]}"
    if line:
        _state.status[scene.name] = line


def status(scene) -> str:
    """The last live pass of ``scene`` as one line for the panel, or ""."""
    return _state.status.get(scene.name, "")


def _redraw():
    wm = getattr(bpy.context, "window_manager", None)
    for window in wm.windows if wm is not None else ():
        for area in window.screen.areas:
            if area.type in {"VIEW_3D", "IMAGE_EDITOR", "PROPERTIES"}:
                area.tag_redraw()


# --- switching on and off -----------------------------------------------------------------------


def installed() -> bool:
    return on_depsgraph_update in bpy.app.handlers.depsgraph_update_post


def on_shaping_changed(settings, context=None):
    """Update callback of the settings that shape a map (enlargement, border, front face,
    triangles, method, resolution, plate): with live update on, check every reflective object
    of the scene (the depsgraph does not report these edits)."""
    scene = settings.id_data
    if not settings.live_update or not installed():
        return
    _state.scene_key[scene.name] = _scene_key(scene)
    names = {o.name for o in scene.objects if shading.is_attached(o)}
    if names:
        queue(scene, names)


def enable():
    if not installed():
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def disable():
    """Remove the handler and the timer and forget every pending change."""
    while on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
    if bpy.app.timers.is_registered(tick):
        bpy.app.timers.unregister(tick)
    _state.pending.clear()
    _state.resting.clear()
    _state.built.clear()
    _state.scene_key.clear()
    _state.status.clear()
    _state.reduced = ()


def sync():
    """Install the handler when a scene of the open file has live update on, else remove it."""
    try:
        scenes = list(bpy.data.scenes)
    except AttributeError:  # registering at start-up: no file yet (load_post follows)
        return
    if any(
        getattr(s, "virtual_reflections", None) and s.virtual_reflections.live_update
        for s in scenes
    ):
        enable()
    else:
        disable()


def on_setting_changed(settings, context):
    """Update callback of ``scene.virtual_reflections.live_update``."""
    scene = settings.id_data
    _state.status.pop(scene.name, None)
    _state.scene_key[scene.name] = _scene_key(scene)
    sync()


@bpy.app.handlers.persistent
def _on_load_pre(*_args):
    disable()


@bpy.app.handlers.persistent
def _on_load_post(*_args):
    sync()


_FILE_HANDLERS = (("load_pre", _on_load_pre), ("load_post", _on_load_post))


def _sync_soon():
    sync()  # the scene settings register after the operators: look once they exist
    return None


def register():
    app_handlers.add(_FILE_HANDLERS)
    if not bpy.app.timers.is_registered(_sync_soon):
        bpy.app.timers.register(_sync_soon, first_interval=0.0, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(_sync_soon):
        bpy.app.timers.unregister(_sync_soon)
    disable()
    app_handlers.remove(_FILE_HANDLERS)
