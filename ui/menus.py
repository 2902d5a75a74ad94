"""The extension in Blender's menus: Object > Virtual Reflections, so its operators are found
by menu search (F3) too."""

import bpy

ITEMS = (  # (operator, icon), in the panel's order
    ("vr.setup_plate", "CAMERA_DATA"),
    ("vr.generate", "MATSPHERE"),
    ("vr.render_passes", "RENDER_STILL"),
    ("vr.remove", "X"),
)


class VR_MT_object(bpy.types.Menu):
    bl_label = "Virtual Reflections"
    bl_idname = "VR_MT_object"

    def draw(self, context):
        for operator, icon in ITEMS:
            self.layout.operator(operator, icon=icon)


def _draw_in_object_menu(self, context):
    self.layout.separator()
    self.layout.menu(VR_MT_object.bl_idname)


def register():
    bpy.utils.register_class(VR_MT_object)
    bpy.types.VIEW3D_MT_object.append(_draw_in_object_menu)


def unregister():
    bpy.types.VIEW3D_MT_object.remove(_draw_in_object_menu)
    bpy.utils.unregister_class(VR_MT_object)
