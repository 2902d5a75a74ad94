"""Generate and remove virtual reflections: the artist's two buttons as functions, for the
operators (ops.py), scripts and the headless batch entry.

Generate runs the map pipeline (pipeline.py) for each object, stores each map as an image
(maps.py) and puts it on the object's material copies, or on a world (shading.py).
"""

import functools
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import bpy

from . import pipeline
from .node_trees import shading, world, world_probe
from .scene import maps, plate
from .scene.choices import map_width
from .scene.composite import union_box

RENDER_START_GRACE = 5.0  # s: an invoked render job not seen running by then counts as over


def candidates(context):
    """Objects to generate for: the selected reflectable ones, else all marked ones."""
    selected = [o for o in context.selected_objects if o.type in shading.REFLECTABLE]
    if selected:
        return selected
    return [
        o
        for o in context.scene.objects
        if o.type in shading.REFLECTABLE and o.virtual_reflections.enabled
    ]


def why_not_generate(context):
    """A one-line reason why Generate cannot run now, or None."""
    scene = context.scene
    if scene is None:
        return "No scene"
    if _running is not None:
        return f"{_running.name} is under way: wait for it, or press Esc to stop it"
    if scene.camera is None:
        return "The scene has no camera: add one and make it active"
    if scene.camera.type != "CAMERA":
        return "The scene camera is not a camera object"
    if plate.scene_plate(scene) is None:
        return "Pick a plate image (or give the camera a background image)"
    if not candidates(context):
        return "Select the objects that should reflect the plate, or mark them"
    return None


@dataclass(frozen=True)
class Step:
    """One step of Generate (`steps`) or of another run: ``stage`` says what runs now (the
    panel shows it), ``done`` the share of the run done before it (0..1); ``work``, when
    given, is the step's engine work: a bpy-free callable whose result the driver sends back
    into the steps, so it may run off Blender's main thread while the window stays
    responsive (ops.py); ``render``, when given, (scene name, view layer name): a still to
    render and write to the scene's output path (interreflect.py), which the window runs as
    Blender's own render job (F12's: drawn as it renders, the window working meanwhile) and a
    blocking driver in place; the driver sends None back."""

    stage: str
    done: float
    work: Callable | None = None
    render: tuple | None = None


class Stopped(Exception):
    """A run from the window that stopped because the artist asked it to (Esc, or the render
    cancelled): not an error."""


def generate(scene, depsgraph, objects, progress=None, pixels=None) -> pipeline.Report:
    """Build each object's map from the plate and wire it in; returns a pipeline.Report.

    depsgraph: evaluated for the frame wanted (``context.evaluated_depsgraph_get()``).
    pixels: (H, W, 3) float32 scene-linear pixels, the plate's size, to build the maps from
    instead of the plate's own (interreflect.py: the previous pass's composite).
    progress: called with a count up to 2 x len(objects).
    Raises ValueError (one line) when nothing can be done: no camera, no or bad plate.
    Per-object problems (off-screen, linked data, no geometry) become warnings.
    """
    total = 2 * len(objects)
    return drive(
        steps(scene, depsgraph, objects, pixels),
        (lambda done: progress(done * total)) if progress else None,
    )


def drive(run, progress=None):
    """Run a generator of `Step`s to its end on this thread (the blocking run: scripts,
    ``blender -b``, the batch) and return its value. progress: called with each step's
    ``done`` (0..1) before the step runs."""
    try:
        step = next(run)
        while True:
            if progress:
                progress(step.done)
            if step.render is not None:
                scene, layer = step.render
                bpy.ops.render.render(write_still=True, scene=scene, layer=layer)
            step = run.send(step.work() if step.work else None)
    except StopIteration as finished:
        return finished.value


def within(run, start, end, label=""):
    """Delegate to the generator of `Step`s ``run`` (``yield from`` it), its ``done`` put
    in ``start..end`` of the whole and its stage after ``label``; returns its value. Closing
    the outer generator closes ``run``."""
    try:
        try:
            step = next(run)
        except StopIteration as finished:
            return finished.value
        while True:
            stage = f"{label}{step.stage[:1].lower()}{step.stage[1:]}" if label else step.stage
            value = yield Step(stage, start + (end - start) * step.done, step.work, step.render)
            try:
                step = run.send(value)
            except StopIteration as finished:
                return finished.value
    finally:
        run.close()


def steps(scene, depsgraph, objects, pixels=None):
    """Generate as a generator of `Step`s (same arguments as `generate`), returning the
    pipeline.Report. Nothing in the scene changes before the last step ("Writing the maps"),
    so a run stopped between steps leaves the scene as it was."""
    settings = scene.virtual_reflections
    report = pipeline.Report()
    image = plate.require_plate(scene)
    yield Step("Reading the plate", 0.0)
    pixels, pyramids = _plate_pixels(scene, image, pixels, report)
    save_dir = maps.save_folder(settings)
    view = pipeline.view(scene, pixels.shape, depsgraph)
    report.warnings += view.warnings(settings)
    probe = pipeline.scene_probe(scene, view, report)
    yield Step("Measuring the objects", 0.05)
    boxes, requests = _requests(view, scene, depsgraph, objects, image, report)
    if probe is not None and requests:
        warning = world_probe.exposure_warning(probe, pixels, requests[0].params)
        if warning:
            report.warnings.append(warning)
    envs = yield from _map_steps(requests, pixels, pyramids, probe, report)
    yield Step("Writing the maps", 0.95)
    if settings.combine == "WORLD":
        if requests:
            _attach_world(boxes, envs[0], save_dir, settings, report)
    else:
        for request, env in zip(requests, envs, strict=True):
            _attach(request, env, save_dir, settings, report)
    remove_orphans()
    return report


def _plate_pixels(scene, image, pixels, report):
    """(the plate's pixels, their pyramids): the frame of the plate ``image`` read (its
    pyramids shared by every object's map), or the ``pixels`` given (no pyramids yet)."""
    with report.timed("plate"):
        if pixels is not None:
            report.plate = (
                f"{pixels.shape[1]}x{pixels.shape[0]} pixels given for plate '{image.name}'"
            )
            return pixels, {}
        found = plate.frame(scene, image=image)
        report.plate = found.info
        return found.pixels, found.pyramids


def _requests(view, scene, depsgraph, objects, image, report):
    """({object: box} of the objects in view, the maps to build as pipeline.ReflectRequests):
    in the World look one shared, camera-aligned map of the union of their boxes, else one
    map per object (a linked object is named in the warnings and left out)."""
    settings = scene.virtual_reflections
    boxes, extents, problems = pipeline.object_boxes(view, scene, depsgraph, objects)
    report.warnings += problems
    widths = {obj: map_width(settings.resolution, extents[obj]) for obj in boxes}
    if settings.combine == "WORLD":
        if not boxes:
            return boxes, []
        shared = pipeline.reflect_request(
            view, scene, depsgraph, list(boxes), union_box(boxes.values()), max(widths.values())
        )
        return boxes, [shared]
    requests = []
    for obj, box in boxes.items():
        if obj.library is not None:  # linked; a library override (local) is generated
            report.warnings.append(shading.linked_object(obj))
            continue
        requests.append(
            pipeline.reflect_request(
                view, scene, depsgraph, [obj], box, widths[obj], obj=obj, image=image
            )
        )
    return boxes, requests


def _map_steps(requests, pixels, pyramids, probe, report):
    """Each request's lookup table, then its gather, as steps (the engine's work, which the
    operator runs in a thread); returns their maps in the requests' order."""
    envs = []
    for i, request in enumerate(requests):
        share = 0.1 + 0.85 * i / len(requests)
        table = yield Step(
            f"Building the table ({request.name})",
            share,
            functools.partial(
                pipeline.map_table,
                pixels.shape,
                request.box,
                request.params,
                request.width,
                report,
                request.name,
            ),
        )
        gather = functools.partial(
            pipeline.gather, table, pixels, report, request.roughness, pyramids, probe
        )
        envs.append(
            (yield Step(f"Gathering ({request.name})", share + 0.6 * 0.85 / len(requests), gather))
        )
    return envs


def _attach_world(boxes, env, save_dir, settings, report):
    """The World look: the one map stored and every object in ``boxes`` reflecting it."""
    with report.timed("image"):
        world_map = _store(maps.WORLD_MAP, env, save_dir, report)
    with report.timed("wiring"):
        for obj, box in boxes.items():
            try:
                shading.attach(obj, world_map, "WORLD", settings.strength, settings.ior)
            except ValueError as exc:
                report.warnings.append(str(exc))
                continue
            obj.virtual_reflections.bounds = box
            report.done.append(obj.name)


def _attach(request, env, save_dir, settings, report):
    """One object's map stored and its materials reading it (the request's ground and lobe)."""
    obj = request.obj
    with report.timed("image"):
        image_map = _store(maps.map_name(obj.name), env, save_dir, report)
    with report.timed("wiring"):
        try:
            shading.attach(
                obj,
                image_map,
                settings.combine,
                settings.strength,
                settings.ior,
                ground=request.ground,
                shift=request.shift,
            )
        except ValueError as exc:  # raised before anything changed (e.g. linked materials)
            report.warnings.append(str(exc))
            if not shading.is_attached(obj):
                bpy.data.images.remove(image_map)
            return
    obj.virtual_reflections.bounds = request.box
    report.done.append(obj.name)


def _store(name, env, save_dir, report):
    """`maps.store_map`, and a warning when the map's saved file was missing (made again)."""
    missing = maps.missing_file(bpy.data.images.get(name))
    if missing:
        report.warnings.append(f"{missing}: made again")
    return maps.store_map(name, env, save_dir)


class Job:
    """A run from Blender's window (ops.py) over a generator of `Step`s (`steps`,
    interreflect.pass_steps), one `Step` per `advance`: the steps that touch Blender on the
    main thread, their engine work in a thread and their renders as Blender's render job, so
    the window keeps drawing. One Job at a time (`running`; the panel shows its stage).
    ValueError (one line) when it is made (the first step's, or another run under way) or
    from `advance`; `Stopped` from `advance` when a render ends cancelled or after
    `stop_requested` was set during it."""

    def __init__(self, run, name="Generate"):
        global _running
        if _running is not None:
            run.close()
            raise ValueError(f"{_running.name} is under way: wait for it, or press Esc to stop it")
        self.name = name
        self.stop_requested = False  # set during a render: stop once it ends
        self._steps = run
        self.step = next(self._steps)
        self._thread = None
        self._outcome = None  # (result, exception) of the work in the thread
        self._rendering = False
        self._cancelled = False
        self._render_ended = False  # render_complete or render_cancel has been called
        self._render_seen = False  # the render job was seen running
        self._render_started = 0.0
        _running = self

    @property
    def stage(self) -> str:
        return self.step.stage

    @property
    def done(self) -> float:
        return self.step.done

    @property
    def rendering(self) -> bool:
        """True while the step's render runs as Blender's render job."""
        return self._rendering

    def advance(self, wait=0.05):
        """Do the next step, or give the thread up to ``wait`` seconds to finish the step's
        work, or see whether the step's render has ended. Returns the generator's value once
        the run is over, else None.

        The wait matters: Blender's main thread holds Python's lock while it draws and waits
        for events, so a thread advances mostly while the main thread waits for it here
        (without it, the run took 2-3x as long; docs/benchmarks.md)."""
        if self._rendering:
            if not self._render_over():
                return None
            self._end_render()
            if self._cancelled or self.stop_requested:
                self.stop()
                raise Stopped(f"{self.name} stopped")
            value = None
        elif self._thread is not None:
            self._thread.join(wait)
            if self._thread.is_alive():
                return None
            self._thread = None
            value, error = self._outcome
            if error is not None:
                self.stop()
                raise error
        elif self.step.work is not None:
            self._thread = threading.Thread(target=self._work, args=(self.step.work,))
            self._thread.daemon = True  # Blender may quit meanwhile
            self._thread.start()
            return None
        elif self.step.render is not None:
            self._start_render(*self.step.render)
            return None
        else:
            value = None
        try:
            self.step = self._steps.send(value)
        except StopIteration as finished:
            self.stop()
            return finished.value
        except BaseException:
            self.stop()
            raise
        return None

    def _render_over(self) -> bool:
        """Has the step's render job ended? Blender starts an invoked render job on a later
        turn of its event loop, so "no render job running" right after the invoke means not
        yet begun: it is over once a render_complete or render_cancel handler has run, or once
        it was seen running and is no longer; one that never shows within RENDER_START_GRACE
        seconds counts as over (reading its image then fails, with a message)."""
        if bpy.app.is_job_running("RENDER"):
            self._render_seen = True
            return False
        if self._render_ended or self._render_seen or bpy.app.background:
            return True
        return time.monotonic() - self._render_started > RENDER_START_GRACE

    def _start_render(self, scene, layer):
        if bpy.app.is_job_running("RENDER"):
            self.stop()
            raise ValueError("Blender is rendering already: wait for that render to end")
        self._cancelled = False
        self._render_ended = self._render_seen = False
        self._render_started = time.monotonic()
        bpy.app.handlers.render_cancel.append(self._on_cancel)
        bpy.app.handlers.render_complete.append(self._on_complete)
        self._rendering = True
        try:
            started = bpy.ops.render.render(
                "INVOKE_DEFAULT", write_still=True, scene=scene, layer=layer
            )
        except BaseException:
            self.stop()  # also takes the cancel handler off
            raise
        if "CANCELLED" in started:
            self.stop()
            raise ValueError("Blender could not start the render")

    def _on_cancel(self, *_args):
        self._cancelled = self._render_ended = True

    def _on_complete(self, *_args):
        self._render_ended = True

    def _end_render(self):
        self._rendering = False
        while self._on_cancel in bpy.app.handlers.render_cancel:
            bpy.app.handlers.render_cancel.remove(self._on_cancel)
        while self._on_complete in bpy.app.handlers.render_complete:
            bpy.app.handlers.render_complete.remove(self._on_complete)

    def _work(self, work):
        try:
            self._outcome = (work(), None)
        except Exception as exc:  # handed to the main thread by `advance`
            self._outcome = (None, exc)

    def stop(self):
        """End the run where it is (a thread still working finishes for nothing; a render
        job under way is left to end): the generator is closed, so what it restores on
        closing is restored (interreflect.pass_steps: the render settings). Generate changes
        the scene only in its last step, so it is as it was."""
        global _running
        if self._rendering:
            self._end_render()
        self._steps.close()
        if _running is self:
            _running = None


_running = None  # the Job under way in the window, for the panel and the polls


def running() -> Job | None:
    """The run under way in the window (Generate, Inter-Reflections), or None (the panel
    shows its stage)."""
    return _running


def remove_orphans() -> int:
    """Delete the maps no object reflects any more (an object renamed, then generated again,
    leaves its old map; a deleted object leaves its map packed in the .blend)."""
    in_use = {shading.map_of(o) for o in bpy.data.objects}
    stale = maps.orphans(in_use)
    for image in stale:
        bpy.data.images.remove(image)
    return len(stale)


def remove_all() -> int:
    """Take every virtual reflection off: restore materials and the world exactly, delete the
    maps, copies and groups the add-on created. Returns how many objects were restored."""
    restored = 0
    for obj in bpy.data.objects:
        if shading.is_attached(obj):
            shading.detach(obj)
            restored += 1
    for scene in bpy.data.scenes:
        if scene.get(world.WORLD_RECORD) is not None:
            world.detach_world(scene)
    maps.remove_maps()
    plate.clear_cache()
    return restored


def anything_attached():
    """Anything Remove would take away: a reflection on an object or a world, or a map of the
    add-on's left behind by a deleted object."""
    return (
        any(shading.is_attached(o) for o in bpy.data.objects)
        or any(s.get(world.WORLD_RECORD) is not None for s in bpy.data.scenes)
        or bool(maps.orphans({shading.map_of(o) for o in bpy.data.objects}))
    )
