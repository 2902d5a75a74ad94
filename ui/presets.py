"""Looks in one click: Chrome, Car Paint and Glossy set the combine mode and its settings.

A preset sets exactly the values in `PRESETS` on the scene's settings; objects that already
have a reflection among the selected (else all that have one) are generated again, so the
look changes at once. The panel shows the preset whose values are current as pressed.
"""

import bpy

from ..operators import generate
from ..operators.node_trees import shading

# name -> (label, icon, description, {setting: value})
PRESETS = {
    "CHROME": (
        "Chrome",
        "SHADING_RENDERED",
        "Mirror: the object shows the plate's environment, nothing of its material "
        "(Replace, the paper's GL replace)",
        {"combine": "REPLACE", "strength": 1.0},
    ),
    "CAR_PAINT": (
        "Car Paint",
        "AUTO",
        "Coloured reflections: the material's base colour times the environment "
        "(Modulate, the paper's Fig. 7)",
        {"combine": "MODULATE", "strength": 1.0},
    ),
    "GLOSSY": (
        "Glossy",
        "MATERIAL",
        "Your material with a clear-coat reflection over it, strongest at grazing angles "
        "(Mix by a Fresnel weight of IOR 1.5)",
        {"combine": "MIX", "strength": 1.0, "ior": 1.5},
    ),
}


def matches(settings, name) -> bool:
    """True when the scene's settings hold preset ``name``'s values."""
    values = PRESETS[name][3]
    return all(
        abs(getattr(settings, k) - v) < 1e-6 if isinstance(v, float) else getattr(settings, k) == v
        for k, v in values.items()
    )


def apply(settings, name):
    """Set preset ``name``'s values on a VR_SceneSettings."""
    for key, value in PRESETS[name][3].items():
        setattr(settings, key, value)


class VR_OT_apply_preset(bpy.types.Operator):
    """Set the combine mode and its settings for a look; reflecting objects are generated again"""

    bl_idname = "vr.apply_preset"
    bl_label = "Reflection Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: bpy.props.EnumProperty(
        name="Preset",
        items=[(key, p[0], p[2], p[1], i) for i, (key, p) in enumerate(PRESETS.items())],
    )

    @classmethod
    def description(cls, context, properties):
        return PRESETS[properties.preset][2]

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("No scene")
            return False
        return True

    def execute(self, context):
        settings = context.scene.virtual_reflections
        apply(settings, self.preset)
        label = PRESETS[self.preset][0]
        attached = [o for o in context.selected_objects if shading.is_attached(o)] or [
            o for o in context.scene.objects if shading.is_attached(o)
        ]
        if not attached or generate.why_not_generate(context) is not None:
            self.report({"INFO"}, f"{label}: set for the next Generate")
            return {"FINISHED"}
        try:
            report = generate.generate(context.scene, context.evaluated_depsgraph_get(), attached)
        except ValueError as exc:
            self.report({"WARNING"}, f"{label} set; could not generate again: {exc}")
            return {"FINISHED"}
        for warning in report.warnings:
            self.report({"WARNING"}, warning)
        settings.last_report = report.summary()
        self.report({"INFO"}, f"{label}: {report.outcome()}")
        return {"FINISHED"}


class VR_MT_presets(bpy.types.Menu):
    bl_idname = "VR_MT_presets"
    bl_label = "Reflection Presets"

    def draw(self, context):
        for key, (label, icon, _description, _values) in PRESETS.items():
            self.layout.operator(VR_OT_apply_preset.bl_idname, text=label, icon=icon).preset = key


def draw_buttons(layout, settings):
    """A row with one button per preset, the current one pressed."""
    row = layout.row(align=True)
    for key, (label, icon, _description, _values) in PRESETS.items():
        op = row.operator(
            VR_OT_apply_preset.bl_idname, text=label, icon=icon, depress=matches(settings, key)
        )
        op.preset = key
    return row


classes = (VR_OT_apply_preset, VR_MT_presets)
register, unregister = bpy.utils.register_classes_factory(classes)
