"""Settings the artist edits: on the Scene (method, plate, combine) and on each Object.

Defaults follow the paper (§3.2): enlargement 7.5 % (5–10 %), border distance 15 % (10–20 %),
continuous front face or n triangles.
"""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

COMBINE_ITEMS = (
    (
        "REPLACE",
        "Replace",
        "Chrome: the object shows the environment map (the paper's replace mode)",
    ),
    ("MODULATE", "Modulate", "Material colour times the environment (the paper's modulate mode)"),
    ("MIX", "Mix", "Blend the map over the material's own shader by strength and Fresnel"),
    ("WORLD", "World", "Use one shared map as camera-aligned world lighting for any material"),
)
FRONT_ITEMS = (
    (
        "CONTINUOUS",
        "Continuous",
        "The front face in the continuous limit (n -> infinity): no seams",
    ),
    ("TRIANGLES", "Triangles", "The paper's n triangles cut from the outer ring"),
)
RESOLUTION_ITEMS = (
    (
        "AUTO",
        "Auto",
        "From the object's size on screen: about 3 map pixels (pi) per pixel it spans, rounded "
        "up to the next size below (256 to 4096)",
    ),
) + tuple(
    (str(w), f"{w} x {w // 2}", f"Lat-long map {w} x {w // 2} pixels")
    for w in (256, 512, 1024, 2048, 4096)
)


def _shaping_changed(settings, context):
    """Settings that shape a map changed: live update (operators/live.py) follows."""
    _live().on_shaping_changed(settings, context)


class VR_SceneSettings(bpy.types.PropertyGroup):
    plate_image: PointerProperty(
        update=_shaping_changed,
        name="Plate",
        type=bpy.types.Image,
        description="Background photograph; empty: the active camera's background image",
    )
    enlarge: FloatProperty(
        update=_shaping_changed,
        name="Enlargement",
        description="Grow the object's screen bounds by this share of the image size (region X)",
        default=7.5,
        min=0.0,
        max=50.0,
        soft_min=0.0,
        soft_max=20.0,
        subtype="PERCENTAGE",
    )
    border: FloatProperty(
        update=_shaping_changed,
        name="Border Distance",
        description="Keep region X at least this share of the image size away from its edges",
        default=15.0,
        min=0.0,
        max=45.0,
        subtype="PERCENTAGE",
    )
    method: EnumProperty(
        update=_shaping_changed,
        name="Method",
        items=(
            (
                "CAMERA",
                "Camera View",
                "Place the plate exactly by the camera's field of view; where the photo saw "
                "nothing, extend its edges into the sky, ground and sides it suggests (the most "
                "accurate on the ground truth, docs/accuracy.md)",
            ),
            (
                "PAPER",
                "Paper (2004)",
                "Ropinski et al.: the plate cut into regions around the object's bounds and "
                "folded onto a cube (neighbouring objects show on the sides facing them)",
            ),
        ),
        default="CAMERA",
    )
    front: EnumProperty(
        name="Front Face", items=FRONT_ITEMS, default="CONTINUOUS", update=_shaping_changed
    )
    triangles: IntProperty(
        update=_shaping_changed,
        name="Triangles",
        description="n triangles for the front face (a multiple of 4)",
        default=32,
        min=4,
        max=1024,
        step=4,
    )
    resolution: EnumProperty(
        name="Resolution", items=RESOLUTION_ITEMS, default="1024", update=_shaping_changed
    )
    combine: EnumProperty(name="Combine", items=COMBINE_ITEMS, default="REPLACE")
    strength: FloatProperty(
        name="Strength",
        description="Brightness of the reflection (Mix: its maximum weight)",
        default=1.0,
        min=0.0,
        soft_max=2.0,
    )
    ior: FloatProperty(
        name="IOR",
        description="Index of refraction for the Fresnel weight of Mix",
        default=1.45,
        min=1.0,
        max=4.0,
    )
    save_maps: BoolProperty(
        name="Save Maps as Files",
        description="Save maps as EXR files (in a vr_maps folder beside the .blend, or where the "
        "extension's preferences say) instead of packing them into the .blend",
        default=False,
    )
    live_update: BoolProperty(
        name="Live Update",
        description="Rebuild a reflective object's map while it moves, turns, scales or its mesh "
        "is edited: a quick small map during the drag, the full one once it rests",
        default=False,
        update=lambda settings, context: _live().on_setting_changed(settings, context),
    )
    defaults_applied: BoolProperty(
        name="Preference Defaults Applied",
        description="The extension's preferred defaults were copied into this scene",
        default=False,
        options={"HIDDEN"},
    )
    last_report: StringProperty(name="Last Run", default="")
    sequence: BoolProperty(
        name="Update Every Frame",
        description="Rebuild the maps of the objects with a reflection on every frame change and "
        "rendered frame, from that frame's plate (image sequences, movies) and bounds; locks the "
        "interface during renders",
        default=False,
        update=lambda settings, context: _sequence().on_setting_changed(settings, context),
    )
    smoothing: FloatProperty(
        name="Bounds Smoothing",
        description="Smooth the objects' screen bounds over frames so the maps do not flicker: "
        "0 off, 0.5 about 3 frames, 0.9 about 19 (a moving object's map lags behind more)",
        default=0.5,
        min=0.0,
        max=0.95,
        subtype="FACTOR",
    )

    def params(self, intrinsics=None):
        """The engine's Params for these settings; `intrinsics` (fx, fy, cx, cy) in plate
        pixels select the camera-view method when it is chosen (else the paper's)."""
        from ..virtual_reflections import Params

        n = 0 if self.front == "CONTINUOUS" else 4 * max(1, round(self.triangles / 4))
        camera = self.method == "CAMERA" and intrinsics is not None
        return Params(
            enlarge=self.enlarge / 100.0,
            border=self.border / 100.0,
            triangles=n,
            method="frustum" if camera else "paper",
            intrinsics=tuple(intrinsics) if camera else None,
        )

    def map_width(self, extent=None):
        """The lat-long map width for an object ``extent`` render pixels wide or high on
        screen: the chosen resolution, or with Auto one from the extent (1024 without one)."""
        from ..operators import generate

        return generate.map_width(self.resolution, extent)


def _live():
    from ..operators import live

    return live


def _sequence():
    from ..operators import sequence

    return sequence


class VR_ObjectSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(
        name="Reflect Plate",
        description="Give this object a virtual reflection when generating for marked objects",
        default=False,
    )
    bounds: FloatVectorProperty(
        name="Screen Bounds",
        size=4,
        description="Last screen bounds on the plate (x0 y0 x1 y1)",
    )


classes = (VR_SceneSettings, VR_ObjectSettings)
_register, _unregister = bpy.utils.register_classes_factory(classes)


def register():
    _register()
    bpy.types.Scene.virtual_reflections = PointerProperty(type=VR_SceneSettings)
    bpy.types.Object.virtual_reflections = PointerProperty(type=VR_ObjectSettings)


def unregister():
    del bpy.types.Object.virtual_reflections
    del bpy.types.Scene.virtual_reflections
    _unregister()
