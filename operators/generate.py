"""Generate and remove virtual reflections: the artist's two buttons, and the same as functions
for scripts and the headless batch entry.

Per frame the data flows one way (docs/architecture.md): plate pixels (linear) -> each object's screen
bounds (bounds.py) -> the engine's cached table and one gather (virtual_reflections) -> a map
image (maps.py) -> a node group on object-level material copies, or a world (shading.py).
"""

import time
from dataclasses import dataclass, field

import bpy

from ..virtual_reflections import lookup_table
from ..virtual_reflections.envmap import apply_table
from ..virtual_reflections.mapsize import auto_map_width
from . import bounds, compositor, maps, shading

REFLECTABLE = {"MESH", "CURVE", "SURFACE", "FONT", "META", "CURVES"}


@dataclass
class Report:
    """What a run did, for the operator's report, the panel and the batch log."""

    done: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)  # stage -> seconds, summed over objects
    plate: str = ""  # what was read as the plate

    def time(self, stage, seconds):
        self.timings[stage] = self.timings.get(stage, 0.0) + seconds

    def summary(self):
        stages = ", ".join(f"{k} {1000 * v:.0f} ms" for k, v in self.timings.items())
        total = 1000 * sum(self.timings.values())
        return f"{len(self.done)} reflection(s) in {total:.0f} ms ({stages})"


# The plate as linear pixels, cached by what identifies its content.
_plate_cache = {}


def _plate_key(image, scene):
    return (
        image.session_uid,  # a new image under an old name is a new plate
        image.name_full,
        tuple(image.size),
        image.filepath,
        image.source,
        scene.frame_current,
        image.is_dirty,
    )


def plate_pixels(scene, image):
    """(H, W, 3) float32 linear pixels and an info line for the scene's plate, cached."""
    if image.source in {"SEQUENCE", "MOVIE"}:  # the scene frame's plate (sequence.py)
        from . import sequence

        return sequence.image_pixels(scene, image)
    key = _plate_key(image, scene)
    hit = _plate_cache.get(key)
    if hit is None:
        _plate_cache.clear()
        hit = _plate_cache[key] = compositor.plate_image_pixels(image)
    return hit


def camera_and_plate(scene):
    """The scene's plate image; ValueError (one line) without a camera or a plate."""
    if scene.camera is None:
        raise ValueError("the scene has no camera")
    image = compositor.scene_plate(scene)
    if image is None:
        raise ValueError("no plate: pick a plate image or give the camera a background image")
    return image


def clear_plate_cache():
    _plate_cache.clear()


def candidates(context):
    """Objects to generate for: the selected reflectable ones, else all marked ones."""
    selected = [o for o in context.selected_objects if o.type in REFLECTABLE]
    if selected:
        return selected
    return [
        o for o in context.scene.objects if o.type in REFLECTABLE and o.virtual_reflections.enabled
    ]


def why_not_generate(context):
    """A one-line reason why Generate cannot run now, or None."""
    scene = context.scene
    if scene is None:
        return "No scene"
    if scene.camera is None:
        return "The scene has no camera: add one and make it active"
    if scene.camera.type != "CAMERA":
        return "The scene camera is not a camera object"
    if compositor.scene_plate(scene) is None:
        return "Pick a plate image (or give the camera a background image)"
    if not candidates(context):
        return "Select the objects that should reflect the plate, or mark them"
    return None


def _save_dir(settings):
    if not settings.save_maps:
        return None
    from .. import preferences  # beside the .blend, or the extension's user folder

    return preferences.maps_folder()


# --- sensible defaults: map size and advice ------------------------------------------------

LARGE_SHARE = 0.4  # an object covering more of the plate leaves little to reflect


def auto_width(extent) -> int:
    """Lat-long width for an object ``extent`` render pixels across on screen: the engine's
    rule (W = π × extent, a power of two from 256 to 4096; virtual_reflections/mapsize.py),
    the one the accuracy study measured."""
    return auto_map_width(extent)


def map_width(resolution: str, extent=None) -> int:
    """The width for the resolution setting ("AUTO" or a number as text); Auto without an
    extent gives 1024."""
    if resolution != "AUTO":
        return int(resolution)
    return 1024 if extent is None else auto_width(extent)


def screen_extent(box) -> float:
    """The larger side of a ScreenBounds cut to the frame, in render pixels."""
    w = min(box.x1, box.width) - max(box.x0, 0.0)
    h = min(box.y1, box.height) - max(box.y0, 0.0)
    return max(w, h, 0.0)


def fit_warnings(name, seg, paper=True) -> list:
    """Advice (not errors) for an object's segmentation: region X had to shrink below its
    bounds near a border (paper §3.2; only with the paper's method), or the object covers so
    much of the plate that little is left around it to reflect."""
    out = []
    if paper and seg.shrunk:
        out.append(
            f"{name} is so close to the plate's border that region X is smaller than its "
            "bounds: the reflection behind it is cropped"
        )
    b = seg.bbox
    w = min(b.x1, seg.width) - max(b.x0, 0.0)
    h = min(b.y1, seg.height) - max(b.y0, 0.0)
    share = max(w, 0.0) * max(h, 0.0) / (seg.width * seg.height)
    if share > LARGE_SHARE:
        out.append(
            f"{name} covers {share:.0%} of the plate: little is left around it to reflect "
            "(move the camera back or use a wider plate)"
        )
    return out


def generate(context, objects, progress=None, plate=None) -> Report:
    """Build each object's map from the plate and wire it in; returns a Report.

    ``plate``: (H, W, 3) float32 scene-linear pixels, the plate's size, to build the maps from
    instead of the plate's own (interreflect.py: the previous pass's composite).
    Raises ValueError (one line) when nothing can be done: no camera, no or bad plate.
    Per-object problems (off-screen, linked data, no geometry) become warnings.
    """
    scene = context.scene
    settings = scene.virtual_reflections
    report = Report()
    image = camera_and_plate(scene)
    t = time.perf_counter()
    if plate is None:
        plate, info = plate_pixels(scene, image)
    else:
        info = f"{plate.shape[1]}x{plate.shape[0]} pixels given for plate '{image.name}'"
    report.time("plate", time.perf_counter() - t)
    report.plate = info
    save_dir = _save_dir(settings)
    depsgraph = context.evaluated_depsgraph_get()
    projection = bounds.camera_projection(scene)
    ph, pw = plate.shape[:2]
    sx, sy = pw / projection.width, ph / projection.height
    params = settings.params(_intrinsics(projection, sx, sy))
    if settings.method == "CAMERA" and params.method != "frustum":
        report.warnings.append(
            "orthographic camera: the camera-view method needs a "
            "perspective camera; used the paper's method"
        )
    if abs(sx - sy) > 0.01 * max(sx, sy):
        report.warnings.append(
            f"plate {pw}x{ph} and render {projection.width}x{projection.height} differ in "
            "aspect: use Set Up From Plate"
        )

    boxes, widths = {}, {}
    for i, obj in enumerate(objects):
        t = time.perf_counter()
        try:
            box = bounds.object_bounds(obj, depsgraph, scene, projection=projection)
        except ValueError as exc:
            report.warnings.append(f"{obj.name}: {exc}")
            continue
        finally:
            report.time("bounds", time.perf_counter() - t)
        if not box.visible:
            report.warnings.append(f"{obj.name} is outside the camera view: skipped")
            continue
        boxes[obj] = (box.x0 * sx, box.y0 * sy, box.x1 * sx, box.y1 * sy)
        widths[obj] = map_width(settings.resolution, screen_extent(box))
        if progress:
            progress(i + 0.5)

    if settings.combine == "WORLD" and boxes:
        # One shared, camera-aligned world map from the union of the objects' bounds.
        union = tuple(f(v[k] for v in boxes.values()) for k, f in enumerate((min, min, max, max)))
        env = _map(plate, union, params, max(widths.values()), report, "World")
        t = time.perf_counter()
        image_map = maps.store_map(maps.map_name("World"), env, save_dir)
        report.time("image", time.perf_counter() - t)
        t = time.perf_counter()
        for obj in boxes:
            try:
                shading.attach(obj, image_map, "WORLD", settings.strength, settings.ior)
            except ValueError as exc:
                report.warnings.append(str(exc))
                continue
            obj.virtual_reflections.bounds = boxes[obj]
            report.done.append(obj.name)
        report.time("wiring", time.perf_counter() - t)
        return report

    for i, (obj, box) in enumerate(boxes.items()):
        if obj.library is not None or obj.override_library is not None:
            report.warnings.append(f"{obj.name} is linked from a library (read-only): skipped")
            continue
        env = _map(plate, box, params, widths[obj], report, obj.name)
        t = time.perf_counter()
        image_map = maps.store_map(maps.map_name(obj.name), env, save_dir)
        report.time("image", time.perf_counter() - t)
        t = time.perf_counter()
        try:
            shading.attach(obj, image_map, settings.combine, settings.strength, settings.ior)
        except ValueError as exc:  # raised before anything changed (e.g. linked materials)
            report.warnings.append(str(exc))
            if not shading.is_attached(obj):
                bpy.data.images.remove(image_map)
            continue
        finally:
            report.time("wiring", time.perf_counter() - t)
        obj.virtual_reflections.bounds = box
        report.done.append(obj.name)
        if progress:
            progress(len(objects) + i + 1)
    return report


def _intrinsics(projection, sx, sy):
    """(fx, fy, cx, cy) of a perspective camera in plate pixels, or None (orthographic)."""
    if projection.orthographic:
        return None
    left, right, bottom, top = projection.frame  # on the plane z = -1
    fx = projection.width / (right - left) * sx
    fy = projection.height / (top - bottom) * sy
    return (fx, fy, -left * fx, top * fy)


def _map(plate, box, params, width, report, name="an object"):
    h, w = plate.shape[:2]
    t = time.perf_counter()
    table = lookup_table(w, h, tuple(float(v) for v in box), params, "latlong", width)
    report.time("table", time.perf_counter() - t)
    report.warnings.extend(fit_warnings(name, table.segmentation, params.method == "paper"))
    t = time.perf_counter()
    env = apply_table(table, plate)
    report.time("gather", time.perf_counter() - t)
    return env


def remove_all(scene) -> int:
    """Take every virtual reflection off: restore materials and the world exactly, delete the
    maps, copies and groups the add-on created. Returns how many objects were restored."""
    restored = 0
    for obj in bpy.data.objects:
        if shading.is_attached(obj):
            shading.detach(obj)
            restored += 1
    for sc in bpy.data.scenes:
        if sc.get(shading.WORLD_RECORD) is not None:
            shading.detach_world(sc)
    maps.remove_maps()
    clear_plate_cache()
    return restored


def anything_attached():
    return any(shading.is_attached(o) for o in bpy.data.objects) or any(
        s.get(shading.WORLD_RECORD) is not None for s in bpy.data.scenes
    )


# --- operators ----------------------------------------------------------------------------


class VR_OT_generate(bpy.types.Operator):
    """Build each selected (or marked) object's environment map from the plate and make it
    reflect it"""

    bl_idname = "vr.generate"
    bl_label = "Generate Virtual Reflection"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        reason = why_not_generate(context)
        if reason:
            cls.poll_message_set(reason)
        return reason is None

    def execute(self, context):
        objects = candidates(context)
        wm = context.window_manager
        wm.progress_begin(0, 2 * len(objects))
        try:
            report = generate(context, objects, progress=wm.progress_update)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        for warning in report.warnings:
            self.report({"WARNING"}, warning)
        context.scene.virtual_reflections.last_report = report.summary()
        if not report.done:
            self.report({"ERROR"}, "No reflection generated: see the warnings")
            return {"CANCELLED"}
        self.report({"INFO"}, report.summary())
        return {"FINISHED"}


class VR_OT_remove(bpy.types.Operator):
    """Remove all virtual reflections: restore materials and world, delete generated maps"""

    bl_idname = "vr.remove"
    bl_label = "Remove Virtual Reflections"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not anything_attached():
            cls.poll_message_set("Nothing to remove: no object has a virtual reflection")
            return False
        return True

    def execute(self, context):
        try:
            restored = remove_all(context.scene)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Removed virtual reflections from {restored} object(s)")
        context.scene.virtual_reflections.last_report = ""
        return {"FINISHED"}


class VR_OT_setup_plate(bpy.types.Operator):
    """Match the render to the plate: resolution and pixel aspect, camera background,
    transparent film, and the render composited over the plate"""

    bl_idname = "vr.setup_plate"
    bl_label = "Set Up From Plate"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        scene = context.scene
        if scene is None or scene.camera is None:
            cls.poll_message_set("The scene has no camera: add one and make it active")
            return False
        if compositor.scene_plate(scene) is None:
            cls.poll_message_set("Pick a plate image first")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        image = compositor.scene_plate(scene)
        try:
            compositor.setup_from_plate(scene, image)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        clear_plate_cache()
        self.report(
            {"INFO"}, f"Render set to {image.size[0]}x{image.size[1]}, composited over {image.name}"
        )
        return {"FINISHED"}


class VR_OT_undo_setup_plate(bpy.types.Operator):
    """Restore the render settings, camera background and compositor from before Set Up"""

    bl_idname = "vr.undo_setup_plate"
    bl_label = "Undo Plate Set-Up"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if context.scene is None or context.scene.get(compositor.RECORD) is None:
            cls.poll_message_set("The scene was not set up from a plate")
            return False
        return True

    def execute(self, context):
        compositor.undo_setup_from_plate(context.scene)
        return {"FINISHED"}


classes = (VR_OT_generate, VR_OT_remove, VR_OT_setup_plate, VR_OT_undo_setup_plate)
register, unregister = bpy.utils.register_classes_factory(classes)
