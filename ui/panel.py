"""The N-panel tab "Reflections" in the 3D viewport.

The main panel holds the workflow top to bottom (plate, look, surroundings, Generate, live
update); the sub-panels hold what an artist opens less often: the active object's previews,
the method's parameters, shading, and maps & animation.
"""

import textwrap

import bpy

from ..operators import compositor, generate, live, pipeline, previews, sequence
from ..operators.node_trees import shading, world_probe
from ..operators.scene import floor, maps, plate
from ..virtual_reflections import methods
from . import presets


def _wrapped(layout, text, context, icon="NONE"):
    """A long line as several labels that fit the sidebar (labels do not wrap)."""
    chars = max(20, int(context.region.width / (7 * context.preferences.system.ui_scale)))
    for i, line in enumerate(textwrap.wrap(text, chars - 4)):
        layout.label(text=line, icon=icon if i == 0 else "BLANK1")


def _draw_surroundings(col, settings, context):
    """What stands around the shot (Camera View + Ground): in the main panel, as what sets the
    unseen sky's brightness matters more than any other setting (docs/scenes3d.md, "Surroundings
    named by the artist"); Custom's Sky Brightness and Sky Tint; the Sky Texture, greyed out
    while World HDRI reads an HDRI (the HDRI is the sky it would texture); the World HDRI's
    source; under Auto, a hint when the world holds an HDRI (World HDRI would read it) or else
    when the camera sees no sky."""
    col.prop(settings, "surroundings")
    if settings.surroundings == "CUSTOM":  # the artist's own sky: its brightness and colour
        col.prop(settings, "sky_brightness")
        col.prop(settings, "sky_tint")
    image = problem = world = None
    if settings.surroundings in ("WORLD", "AUTO"):
        world = world_probe.user_world(context.scene)
        try:  # the one HDRI World HDRI reads from the artist's world
            image, problem = world_probe.environment_node(world).image.name, None
        except ValueError as exc:
            image, problem = None, str(exc)
    row = col.row()
    row.active = not (settings.surroundings == "WORLD" and image is not None)
    row.prop(settings, "sky_texture")
    if settings.surroundings not in ("WORLD", "AUTO"):
        return
    if settings.surroundings == "WORLD":
        if image is not None:
            _wrapped(col, f"Reads '{image}' from world '{world.name}'", context)
        else:
            _wrapped(col, f"{problem}: Auto is used", context, icon="ERROR")
    elif image is not None:  # Auto, the on-set HDRI perhaps there already: say how to use it
        _wrapped(
            col,
            f"World '{world.name}' holds '{image}': World HDRI reads it for the sky the plate "
            "does not show",
            context,
            icon="INFO",
        )
    elif pipeline.camera_sky(context.scene) == 0:
        _wrapped(
            col,
            "The camera sees no sky: name the Surroundings if you know them",
            context,
            icon="INFO",
        )


def _regions_note(method) -> str:
    """What the segmentation preview shows under a method that cuts no regions."""
    name = methods.method(method).label
    ground = " and reads the ground under the objects" if methods.reads_ground(method) else ""
    return (
        f"{name} cuts no regions: it places the whole plate by the camera's view{ground}. "
        "The regions shown are the paper's, for reference"
    )


class _Tab:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reflections"


class VR_PT_main(_Tab, bpy.types.Panel):
    bl_label = "Virtual Reflections"
    bl_idname = "VR_PT_main"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        settings = scene.virtual_reflections
        layout.use_property_split = True
        layout.use_property_decorate = False

        box = layout.box()
        box.label(text="Plate", icon="IMAGE_BACKGROUND")
        box.template_ID(settings, "plate_image", open="image.open")
        if settings.plate_image is None:
            image = plate.scene_plate(scene)
            _wrapped(
                box,
                f"Using camera background: {image.name}"
                if image
                else "No plate: open one or give the camera a background image",
                context,
                icon="INFO",
            )
        row = box.row(align=True)
        row.operator("vr.setup_plate", icon="CAMERA_DATA")
        row.operator("vr.undo_setup_plate", text="", icon="LOOP_BACK")
        warning = compositor.view_warning(scene)
        if warning:
            col = box.column(align=True)
            col.alert = True
            _wrapped(col, warning, context, icon="ERROR")

        col = layout.column(align=True)
        col.label(text="Look")
        presets.draw_buttons(col, settings)
        if methods.reads_ground(settings.method):
            _draw_surroundings(layout.column(align=True), settings, context)

        col = layout.column(align=True)
        col.scale_y = 1.4
        job = generate.running()
        if job is not None:  # Generate under way: its stage and a bar (Esc stops it)
            col.progress(factor=job.done, type="BAR", text=f"{job.stage}... (Esc to stop)")
        else:
            col.operator("vr.generate", icon="MATSPHERE")
        row = col.row(align=True)
        row.scale_y = 1 / 1.4
        row.operator("vr.remove", icon="X", text="Remove")
        row.operator("vr.render_passes", icon="RENDER_STILL", text="Inter-Reflections")

        row = layout.row()
        row.use_property_split = False
        row.prop(settings, "live_update", icon="RECOVER_LAST", toggle=True)
        line = live.status(scene) if settings.live_update else ""
        if not line and settings.last_report:  # "n reflection(s) in t ms (stages)": the gist
            line = settings.last_report.split(" (")[0]
        if line:
            _wrapped(layout, line, context, icon="TIME")


class VR_PT_object(_Tab, bpy.types.Panel):
    bl_label = ""  # the header shows the object's name
    bl_idname = "VR_PT_object"
    bl_parent_id = "VR_PT_main"

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type in shading.REFLECTABLE

    def draw_header(self, context):
        self.layout.label(text=context.active_object.name, icon="OBJECT_DATA")

    def draw(self, context):
        layout = self.layout
        scene, obj = context.scene, context.active_object
        layout.prop(obj.virtual_reflections, "enabled")
        if shading.is_attached(obj) and not obj.virtual_reflections.enabled:
            _wrapped(
                layout,
                "Reflects the plate: generated while selected, not marked (Generate with "
                "nothing selected takes the marked objects)",
                context,
                icon="INFO",
            )
        shown = previews.for_object(scene, obj)
        if shown["image"] is None:
            layout.label(text="Generate to see how the plate is cut", icon="INFO")
            return
        image = shown["image"]
        row = layout.row(align=True)
        row.label(text="Segmentation")
        op = row.operator("vr.show_image", text="", icon="WINDOW", emboss=False)
        op.kind, op.object = "SEGMENTATION", obj.name
        row.label(text=f"Map {image.size[0]} x {image.size[1]}")
        op = row.operator("vr.show_image", text="", icon="WINDOW", emboss=False)
        op.kind, op.object = "MAP", obj.name
        if shown["both"] is not None:
            # As wide as the sidebar: UI units are 20 pixels times the interface scale.
            unit = 20 * context.preferences.system.ui_scale
            scale = max(6.0, (context.region.width - 2 * unit) / unit)
            layout.template_icon(icon_value=shown["both"].icon_id, scale=scale)
        elif not maps.missing_file(image):  # a missing map's file: its advice says so
            layout.label(text="No plate to show", icon="ERROR")
        if not methods.cuts_regions(scene.virtual_reflections.method):
            _wrapped(layout, _regions_note(scene.virtual_reflections.method), context, "INFO")
        for line in shown["advice"]:
            col = layout.column(align=True)
            col.alert = True
            _wrapped(col, line, context, icon="ERROR")


class VR_PT_method(_Tab, bpy.types.Panel):
    bl_label = "Method"
    bl_idname = "VR_PT_method"
    bl_parent_id = "VR_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.virtual_reflections
        col = layout.column()
        col.prop(settings, "method")
        if methods.reads_ground(settings.method):
            col.prop(settings, "ground_object")
            objects = generate.candidates(context) if settings.ground_object is None else []
            if objects:  # no Ground chosen: say where it is taken from
                depsgraph = context.evaluated_depsgraph_get()
                _wrapped(col, floor.ground_source(context.scene, depsgraph, objects), context)
            col.prop(settings, "contact_shadow")
        col.prop(settings, "enlarge")
        col.prop(settings, "border")
        col.prop(settings, "front")
        sub = col.column()
        sub.active = settings.front == "TRIANGLES"
        sub.prop(settings, "triangles")
        col.prop(settings, "resolution")
        if settings.resolution == "AUTO":
            obj = context.active_object
            image = shading.map_of(obj)
            if image is not None:
                col.label(text=f"{image.size[0]} x {image.size[1]} for {obj.name}")


class VR_PT_shading(_Tab, bpy.types.Panel):
    bl_label = "Shading"
    bl_idname = "VR_PT_shading"
    bl_parent_id = "VR_PT_main"

    def draw_header_preset(self, context):
        self.layout.menu(presets.VR_MT_presets.bl_idname, text="", icon="PRESET")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.virtual_reflections
        col = layout.column()
        col.prop(settings, "combine")
        col.prop(settings, "strength")
        sub = col.column()
        sub.active = settings.combine == "MIX"
        sub.prop(settings, "ior")


class VR_PT_output(_Tab, bpy.types.Panel):
    bl_label = "Maps & Animation"
    bl_idname = "VR_PT_output"
    bl_parent_id = "VR_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.virtual_reflections
        col = layout.column()
        col.prop(settings, "map_storage")
        if settings.map_storage == "FILES":
            try:
                where = maps.maps_folder(context.scene, create=False)
            except ValueError as exc:
                where = str(exc)
            _wrapped(col, where, context, icon="FILE_FOLDER")
        col.prop(settings, "sequence", text="Update Every Frame")
        sub = col.column()
        sub.active = settings.sequence
        sub.prop(settings, "smoothing")
        line = sequence.status(context.scene) if settings.sequence else ""
        if line:  # the last frame's update, or why it was skipped (e.g. a render unlocked)
            _wrapped(layout, line, context, icon="ERROR" if "skipped" in line else "TIME")


classes = (VR_PT_main, VR_PT_object, VR_PT_method, VR_PT_shading, VR_PT_output)
register, unregister = bpy.utils.register_classes_factory(classes)
