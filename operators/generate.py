"""Generate and remove virtual reflections: the artist's two buttons as functions, for the
operators (ops.py), scripts and the headless batch entry.

Generate runs the map pipeline (pipeline.py) for each object, stores each map as an image
(maps.py) and puts it on the object's material copies, or on a world (shading.py).
"""

import bpy

from ..virtual_reflections.composite import union_box
from . import maps, pipeline, plate, shading
from .choices import map_width


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
    if scene.camera is None:
        return "The scene has no camera: add one and make it active"
    if scene.camera.type != "CAMERA":
        return "The scene camera is not a camera object"
    if plate.scene_plate(scene) is None:
        return "Pick a plate image (or give the camera a background image)"
    if not candidates(context):
        return "Select the objects that should reflect the plate, or mark them"
    return None


def generate(scene, depsgraph, objects, progress=None, pixels=None) -> pipeline.Report:
    """Build each object's map from the plate and wire it in; returns a pipeline.Report.

    depsgraph: evaluated for the frame wanted (``context.evaluated_depsgraph_get()``).
    pixels: (H, W, 3) float32 scene-linear pixels, the plate's size, to build the maps from
    instead of the plate's own (interreflect.py: the previous pass's composite).
    progress: called with a count up to 2 x len(objects).
    Raises ValueError (one line) when nothing can be done: no camera, no or bad plate.
    Per-object problems (off-screen, linked data, no geometry) become warnings.
    """
    settings = scene.virtual_reflections
    report = pipeline.Report()
    image = plate.require_plate(scene)
    pyramids = {}  # the plate's pyramids, shared by every object's map
    with report.timed("plate"):
        if pixels is None:
            found = plate.frame(scene, image=image)
            pixels, report.plate, pyramids = found.pixels, found.info, found.pyramids
        else:
            report.plate = (
                f"{pixels.shape[1]}x{pixels.shape[0]} pixels given for plate '{image.name}'"
            )
    save_dir = maps.save_folder(settings)
    view = pipeline.view(scene, pixels.shape, depsgraph)
    report.warnings += view.warnings(settings)
    step = (lambda i: progress(i + 0.5)) if progress else None
    with report.timed("bounds"):
        boxes, extents, problems = pipeline.object_boxes(
            view, scene, depsgraph, objects, progress=step
        )
    report.warnings += problems
    widths = {obj: map_width(settings.resolution, extents[obj]) for obj in boxes}

    if settings.combine == "WORLD" and boxes:
        # One shared, camera-aligned world map from the union of the objects' bounds.
        box = union_box(boxes.values())
        shared = pipeline.map_params(view, scene, depsgraph, list(boxes))
        env, _ = pipeline.build_map(
            pixels, box, shared, max(widths.values()), report, "World", pyramids=pyramids
        )
        with report.timed("image"):
            world_map = maps.store_map(maps.WORLD_MAP, env, save_dir)
        with report.timed("wiring"):
            for obj in boxes:
                try:
                    shading.attach(obj, world_map, "WORLD", settings.strength, settings.ior)
                except ValueError as exc:
                    report.warnings.append(str(exc))
                    continue
                obj.virtual_reflections.bounds = boxes[obj]
                report.done.append(obj.name)
        remove_orphans()
        return report

    for i, (obj, box) in enumerate(boxes.items()):
        if obj.library is not None or obj.override_library is not None:
            report.warnings.append(f"{obj.name} is linked from a library (read-only): skipped")
            continue
        own = pipeline.map_params(view, scene, depsgraph, [obj])
        rough = pipeline.map_roughness(scene, [obj])
        env, _ = pipeline.build_map(
            pixels, box, own, widths[obj], report, obj.name, rough, pyramids=pyramids
        )
        with report.timed("image"):
            image_map = maps.store_map(maps.map_name(obj.name), env, save_dir)
        with report.timed("wiring"):
            ground = pipeline.ground_lookup(view, scene, depsgraph, [obj], image)
            try:
                shading.attach(
                    obj, image_map, settings.combine, settings.strength, settings.ior, ground
                )
            except ValueError as exc:  # raised before anything changed (e.g. linked materials)
                report.warnings.append(str(exc))
                if not shading.is_attached(obj):
                    bpy.data.images.remove(image_map)
                continue
        obj.virtual_reflections.bounds = box
        report.done.append(obj.name)
        if progress:
            progress(len(objects) + i + 1)
    remove_orphans()
    return report


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
        if scene.get(shading.WORLD_RECORD) is not None:
            shading.detach_world(scene)
    maps.remove_maps()
    plate.clear_cache()
    return restored


def anything_attached():
    """Anything Remove would take away: a reflection on an object or a world, or a map of the
    add-on's left behind by a deleted object."""
    return (
        any(shading.is_attached(o) for o in bpy.data.objects)
        or any(s.get(shading.WORLD_RECORD) is not None for s in bpy.data.scenes)
        or bool(maps.orphans({shading.map_of(o) for o in bpy.data.objects}))
    )
