"""The add-on's operators: thin wrappers that check, call one function of the layer below,
and report in one line (``self.report``), so scripts and the batch can call the same functions.

Generate / Remove (generate.py), Set Up From Plate and its undo (compositor.py), Render
Inter-Reflections (interreflect.py), Open in Image Editor (previews.py).
"""

import bpy

from . import compositor, generate, interreflect, previews, reflection_snapshot
from .node_trees import shading
from .scene import maps, plate

COMPOSITE_IMAGE = "VR Inter-Reflections"  # the last inter-reflection render over the plate
COMPOSITE_KIND = "composite"


def _poll_generate(cls, context):
    reason = generate.why_not_generate(context)
    if reason:
        cls.poll_message_set(reason)
    return reason is None


# Navigating the view is harmless while Generate runs; every other event waits for it.
_NAVIGATION = {
    "MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM",
    "MOUSEROTATE", "MOUSEMOVE", "INBETWEEN_MOUSEMOVE", "NDOF_MOTION", "TIMER",
}  # fmt: skip


class _Stepped:
    """The window's run of an operator's generator of steps (generate.Job): each step's
    engine work in a thread, a progress bar (the cursor's and the panel's, with the stage),
    Esc to stop. Subclasses give ``_finish(context, result)`` and may give ``_undo(context)``
    (what a stopped or failed run must put back)."""

    def _start(self, context, run, name):
        try:
            self._job = generate.Job(run, name)
        except ValueError as exc:
            self._undo(context)
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._shown = None  # the stage the panel shows
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        _redraw_panels(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            if self._job.rendering:  # Blender's render job: stop once it ends
                self._job.stop_requested = True
                return {"PASS_THROUGH"}
            return self._stopped(context)
        if event.type != "TIMER":
            if self._job.rendering:  # as during F12: the window works while Blender renders
                return {"PASS_THROUGH"}
            return {"PASS_THROUGH"} if event.type in _NAVIGATION else {"RUNNING_MODAL"}
        try:
            result = self._job.advance()
        except generate.Stopped:
            return self._stopped(context)
        except Exception as exc:  # ValueError: bad input; else a bug, one line all the same
            self._end(context)
            self._undo(context)
            self.report({"ERROR"}, str(exc).strip().splitlines()[0] if str(exc) else repr(exc))
            return {"CANCELLED"}
        if self._job.stage != self._shown:  # redraw when there is something new to show
            self._shown = self._job.stage
            context.window_manager.progress_update(int(100 * self._job.done))
            _redraw_panels(context)
        if result is None:
            return {"RUNNING_MODAL"}
        self._end(context)
        return self._finish(context, result)

    def _stopped(self, context):
        self._end(context)
        self._undo(context)
        self.report({"INFO"}, f"{self._job.name} stopped: the scene is as it was")
        return {"CANCELLED"}

    def cancel(self, context):  # Blender closes the window or loads a file meanwhile
        self._end(context)
        self._undo(context)

    def _end(self, context):
        self._job.stop()
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        _redraw_panels(context)

    def _undo(self, context):
        pass


class VR_OT_generate(_Stepped, bpy.types.Operator):
    """Build each selected (or marked) object's environment map and make it reflect it"""

    bl_idname = "vr.generate"
    bl_label = "Generate Virtual Reflection"
    bl_description = (
        "Build each selected (or marked) object's environment map from the plate and make it "
        "reflect it (Esc stops it)"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _poll_generate(cls, context)

    def execute(self, context):
        """The blocking run: scripts, `blender -b`, the batch (EXEC_DEFAULT)."""
        objects = generate.candidates(context)
        wm = context.window_manager
        wm.progress_begin(0, 2 * len(objects))
        try:
            report = generate.generate(
                context.scene,
                context.evaluated_depsgraph_get(),
                objects,
                progress=wm.progress_update,
            )
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        return self._finish(context, report)

    def _finish(self, context, report):
        for warning in report.warnings:
            self.report({"WARNING"}, warning)
        context.scene.virtual_reflections.last_report = report.summary()
        if not report.done:
            self.report({"ERROR"}, "No reflection generated: see the warnings")
            return {"CANCELLED"}
        self.report({"INFO"}, report.outcome())  # the timings: the panel
        return {"FINISHED"}

    def invoke(self, context, event):
        """From the window: step by step, the engine's work in a thread, with a progress bar
        (the panel's and the cursor's); Esc stops it and leaves the scene as it was (Generate
        changes the scene only in its last step)."""
        if context.window is None or bpy.app.background:
            return self.execute(context)
        run = generate.steps(
            context.scene, context.evaluated_depsgraph_get(), generate.candidates(context)
        )
        return self._start(context, run, "Generate")


def _redraw_panels(context):
    """Redraw the sidebars (the panel's progress bar), not the views: a view redrawn in
    software (a virtual display) costs as much as the work."""
    for area in context.screen.areas if context.screen else ():
        if area.type == "VIEW_3D":
            for region in area.regions:
                if region.type == "UI":
                    region.tag_redraw()


class VR_OT_remove(bpy.types.Operator):
    """Remove all virtual reflections: restore materials and world, delete generated maps"""

    bl_idname = "vr.remove"
    bl_label = "Remove Virtual Reflections"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        job = generate.running()
        if job is not None:
            cls.poll_message_set(f"{job.name} is under way: wait for it, or press Esc to stop it")
            return False
        if not generate.anything_attached():
            cls.poll_message_set("Nothing to remove: no object has a virtual reflection")
            return False
        return True

    def execute(self, context):
        try:
            restored = generate.remove_all()
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Removed virtual reflections from {restored} object(s)")
        context.scene.virtual_reflections.last_report = ""
        return {"FINISHED"}


class VR_OT_setup_plate(bpy.types.Operator):
    """Match the render to the plate: size, camera background, film, composited over it"""

    bl_idname = "vr.setup_plate"
    bl_label = "Set Up From Plate"
    bl_options = {"REGISTER", "UNDO"}

    ground: bpy.props.BoolProperty(
        name="Shadow-Catcher Ground",
        description="Put a plane under the objects (unless the scene has a ground): in Cycles a "
        "shadow catcher, their shadows on the photo; EEVEE has none and shows the plate there",
        default=True,
    )
    lens: bpy.props.BoolProperty(
        name="Focal Length From Photo",
        description="Set the camera's focal length from the photo's 35 mm-equivalent metadata",
        default=True,
    )

    @classmethod
    def poll(cls, context):
        scene = context.scene
        if scene is None or scene.camera is None:
            cls.poll_message_set("The scene has no camera: add one and make it active")
            return False
        if plate.scene_plate(scene) is None:
            cls.poll_message_set("Pick a plate image first")
            return False
        return True

    def execute(self, context):
        scene = context.scene
        image = plate.scene_plate(scene)
        try:
            record = compositor.setup_from_plate(scene, image, ground=self.ground, lens=self.lens)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        plate.clear_cache()
        message = f"Render set to {image.size[0]}x{image.size[1]}, composited over {image.name}"
        view = compositor.describe_view(record["view"])
        if view:  # a tone-mapping view would repaint the plate in the composite
            message += f"; {view} so the composite keeps the plate's colours"
        if record["ground"]:
            message += f"; shadow-catcher ground '{record['ground']['object']}' added"
            if "EEVEE" in scene.render.engine:  # no shadow catcher there: a holdout
                message += " (EEVEE shows the plate there; Cycles also catches the shadows)"
        self.report({"INFO"}, message)
        for line in record["advice"]:
            warning = line.removeprefix("Warning: ")  # Blender's report says "Warning:" itself
            self.report({"WARNING"} if warning != line else {"INFO"}, warning)
        return {"FINISHED"}


class VR_OT_undo_setup_plate(bpy.types.Operator):
    """Undo Set Up From Plate"""

    bl_idname = "vr.undo_setup_plate"
    bl_label = "Undo Plate Set-Up"
    bl_description = (
        "Undo Set Up From Plate: the render size, film, view transform (colour management), "
        "camera background, focal length and compositor as they were, its ground deleted"
    )
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


def show_composite(context, composite):
    """Put an (h, w, 3) composite into the image COMPOSITE_IMAGE (made by the add-on, updated
    in place, removed with the maps) and show it in the open Image Editors."""
    image = maps.store_map(COMPOSITE_IMAGE, composite, kind=COMPOSITE_KIND)
    screen = context.screen if context.window is not None else None
    for area in screen.areas if screen is not None else ():
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image
    return image


class VR_OT_render_passes(_Stepped, bpy.types.Operator):
    """Render the reflective objects reflecting each other (paper §3.3)"""

    bl_idname = "vr.render_passes"
    bl_label = "Render Inter-Reflections"
    bl_description = (
        "Render the reflective objects reflecting each other (paper §3.3): each pass builds the "
        f"maps from the previous composite, into the image '{COMPOSITE_IMAGE}' (Esc stops it)"
    )
    bl_options = {"REGISTER", "UNDO"}

    passes: bpy.props.IntProperty(
        name="Passes",
        description="Recursion depth r: 1 reflects the plate only, 2 the objects in each other, "
        "3 those reflections again",
        default=2,
        min=1,
        max=32,
        soft_max=8,
    )
    auto: bpy.props.BoolProperty(
        name="Until Converged",
        description=f"Render passes until one changes the image less than the tolerance "
        f"(at most {interreflect.R_MAX})",
        default=False,
    )
    tolerance: bpy.props.FloatProperty(
        name="Tolerance",
        description="Mean change of the objects' pixels (scene-linear) under which Until "
        "Converged stops",
        default=interreflect.TOLERANCE,
        min=0.0,
        soft_max=0.05,
        precision=4,
    )

    @classmethod
    def poll(cls, context):
        if bpy.app.is_job_running("RENDER"):
            cls.poll_message_set("Blender is rendering: wait for the render to end")
            return False
        return _poll_generate(cls, context)

    def _arguments(self, context):
        """(scene, depsgraph, objects, plate pixels, passes): ValueError (one line) when the
        plate cannot be read."""
        scene = context.scene
        pixels, _ = plate.pixels(scene)
        passes = "auto" if self.auto else self.passes
        objects = generate.candidates(context)
        return scene, context.evaluated_depsgraph_get(), objects, pixels, passes

    def execute(self, context):
        """The blocking run: scripts, `blender -b` (EXEC_DEFAULT). A failed run puts the
        objects' reflections back as they were."""
        wm = context.window_manager
        self._snapshot = None
        wm.progress_begin(0, interreflect.R_MAX if self.auto else self.passes)
        try:
            scene, depsgraph, objects, pixels, passes = self._arguments(context)
            self._snapshot = reflection_snapshot.Snapshot(scene, objects)
            result = interreflect.render_passes(
                scene, depsgraph, objects, pixels, passes,
                tolerance=self.tolerance, progress=wm.progress_update,
            )  # fmt: skip
        except (ValueError, RuntimeError) as exc:
            self._undo(context)
            self.report({"ERROR"}, str(exc).strip().splitlines()[0])
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        return self._finish(context, result)

    def invoke(self, context, event):
        """From the window: pass by pass, the maps' engine work in a thread and each render
        between two redraws, with a progress bar and the stage in the panel; Esc stops it
        (after the render under way) and puts the scene back as it was: the render settings,
        the objects' reflections and maps (reflection_snapshot), the composite image."""
        if context.window is None or bpy.app.background:
            return self.execute(context)
        self._snapshot = None
        try:
            scene, depsgraph, objects, pixels, passes = self._arguments(context)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._snapshot = reflection_snapshot.Snapshot(scene, objects)
        run = interreflect.pass_steps(
            scene, depsgraph, objects, pixels, passes, tolerance=self.tolerance
        )
        return self._start(context, run, "Inter-Reflections")

    def _undo(self, context):
        if self._snapshot is not None:
            self._snapshot.restore()
            self._snapshot = None

    def _finish(self, context, result):
        composite, _, reports = result
        scene = context.scene
        show_composite(context, composite)
        for warning in reports[0].warnings:
            self.report({"WARNING"}, warning)
        total = sum(r.seconds for r in reports)
        per_pass = "; ".join(
            f"{r.index}: {r.seconds:.1f} s, change {r.change:.4f}" for r in reports
        )
        summary = f"{len(reports)} pass(es) in {total:.1f} s ({per_pass}) -> '{COMPOSITE_IMAGE}'"
        scene.virtual_reflections.last_report = summary  # the details, for the panel
        self.report({"INFO"}, f"Rendered {len(reports)} pass(es) into '{COMPOSITE_IMAGE}'")
        return {"FINISHED"}


def show_image(context, image):
    """Show ``image`` in an Image Editor: one in this window if there is one, else a new
    window (as View Render does). Returns the area, or None when there is no window."""
    screen = context.screen if context.window is not None else None
    if screen is None:
        return None
    for area in screen.areas:
        if area.type == "IMAGE_EDITOR":
            area.spaces.active.image = image
            area.tag_redraw()
            return area
    wm = context.window_manager
    before = {w.as_pointer() for w in wm.windows}
    bpy.ops.wm.window_new()
    window = next((w for w in wm.windows if w.as_pointer() not in before), None)
    if window is None:
        return None
    area = max(window.screen.areas, key=lambda a: a.width * a.height)
    area.type = "IMAGE_EDITOR"
    area.spaces.active.image = image
    return area


class VR_OT_show_image(bpy.types.Operator):
    """Open the picture in an Image Editor (this window's, or a new window)"""

    bl_idname = "vr.show_image"
    bl_label = "Open in Image Editor"
    bl_options = {"REGISTER"}

    kind: bpy.props.EnumProperty(
        items=(
            ("MAP", "Map", "The object's environment map (lat-long, camera frame)"),
            ("SEGMENTATION", "Segmentation", "The plate cut into the paper's regions"),
        ),
        default="MAP",
    )
    object: bpy.props.StringProperty(name="Object", description="Default: the active object")

    @classmethod
    def description(cls, context, properties):
        if properties.kind == "SEGMENTATION":
            return "Open the plate with the paper's regions around this object in an Image Editor"
        return "Open this object's environment map in an Image Editor"

    @classmethod
    def poll(cls, context):
        if context.window is None or bpy.app.background:
            cls.poll_message_set("Needs Blender's window")
            return False
        if shading.map_of(context.active_object) is None:
            cls.poll_message_set("The active object has no virtual reflection: generate first")
            return False
        return True

    def execute(self, context):
        obj = context.scene.objects.get(self.object) if self.object else context.active_object
        if obj is None or shading.map_of(obj) is None:
            self.report({"WARNING"}, "No virtual reflection on that object: generate first")
            return {"CANCELLED"}
        try:
            if self.kind == "SEGMENTATION":
                image = previews.overlay_image(context.scene, obj)
            else:
                image = shading.map_of(obj)
        except ValueError as exc:
            self.report({"WARNING"}, str(exc))
            return {"CANCELLED"}
        if show_image(context, image) is None:
            self.report({"WARNING"}, "No window to open an Image Editor in")
            return {"CANCELLED"}
        return {"FINISHED"}


classes = (
    VR_OT_generate,
    VR_OT_remove,
    VR_OT_setup_plate,
    VR_OT_undo_setup_plate,
    VR_OT_render_passes,
    VR_OT_show_image,
)
register, unregister = bpy.utils.register_classes_factory(classes)
