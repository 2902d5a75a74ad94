"""The N-panel tab "Reflections" in the 3D viewport."""

import bpy

from ..operators import generate


class VR_PT_main(bpy.types.Panel):
    bl_label = "Virtual Reflections"
    bl_idname = "VR_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Reflections"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.virtual_reflections
        layout.use_property_split = True
        layout.use_property_decorate = False

        box = layout.box()
        box.label(text="Plate", icon="IMAGE_BACKGROUND")
        box.template_ID(settings, "plate_image", open="image.open")
        if settings.plate_image is None:
            plate = generate.compositor.scene_plate(context.scene)
            box.label(
                text=f"Using camera background: {plate.name}"
                if plate
                else "No plate: open one or give the camera a background image",
                icon="INFO",
            )
        row = box.row(align=True)
        row.operator("vr.setup_plate", icon="CAMERA_DATA")
        row.operator("vr.undo_setup_plate", text="", icon="LOOP_BACK")

        col = layout.column()
        col.prop(settings, "method")
        col.prop(settings, "enlarge")
        col.prop(settings, "border")
        col.prop(settings, "front")
        sub = col.column()
        sub.active = settings.front == "TRIANGLES"
        sub.prop(settings, "triangles")
        col.prop(settings, "resolution")
        col.separator()
        col.prop(settings, "combine")
        col.prop(settings, "strength")
        sub = col.column()
        sub.active = settings.combine == "MIX"
        sub.prop(settings, "ior")
        col.prop(settings, "save_maps")

        obj = context.active_object
        if obj is not None and obj.type in generate.REFLECTABLE:
            layout.prop(obj.virtual_reflections, "enabled", text=f"Mark {obj.name}")

        col = layout.column(align=True)
        col.scale_y = 1.4
        col.operator("vr.generate", icon="MATSPHERE")
        col.operator("vr.remove", icon="X")
        if settings.last_report:
            layout.label(text=settings.last_report, icon="TIME")


classes = (VR_PT_main,)
register, unregister = bpy.utils.register_classes_factory(classes)
