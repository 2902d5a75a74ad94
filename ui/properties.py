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

from ..operators import live, sequence
from ..operators.scene.choices import (
    COMBINE_ITEMS,
    FRONT_ITEMS,
    MAP_STORAGE_ITEMS,
    METHOD_ITEMS,
    RESOLUTION_ITEMS,
    SURROUNDINGS_ITEMS,
)
from ..virtual_reflections.methods import MAX_TRIANGLES, SKY_TEXTURE
from ..virtual_reflections.params import MAX_SKY_GAIN, SKY_GAINS


def _shaping_changed(settings, context):
    """Settings that shape a map changed: live update (operators/live.py) follows."""
    live.on_shaping_changed(settings, context)


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
        items=METHOD_ITEMS,
        default="GROUND",
        description="How the plate becomes each reflective object's environment map: placed by "
        "the camera's view (with the ground under the objects), or cut into the paper's regions",
    )
    ground_object: PointerProperty(
        update=_shaping_changed,
        name="Ground",
        type=bpy.types.Object,
        description="The object the reflective objects stand on (Camera View + Ground); empty: "
        "a shadow catcher in the scene, else a flat mesh under them, else their lowest point",
    )
    contact_shadow: FloatProperty(
        update=_shaping_changed,
        name="Contact Shadow",
        default=1.0,
        min=0.0,
        max=1.0,
        subtype="FACTOR",
        description="How much the reflective objects darken the ground they reflect around "
        "them (Camera View + Ground): 1, the share of the sky they hide from it; 0, none, for a "
        "plate that already shows their shadow",
    )
    surroundings: EnumProperty(
        update=_shaping_changed,
        name="Surroundings",
        items=SURROUNDINGS_ITEMS,
        default="AUTO",
        description="What stands around the shot where the photo does not show it (Camera View + "
        "Ground): how bright the unseen sky above and behind the camera is taken to be",
    )
    sky_brightness: FloatProperty(
        update=_shaping_changed,
        name="Sky Brightness",
        default=SKY_GAINS["auto"],
        min=0.0,
        max=MAX_SKY_GAIN,  # the engine's Params.sky_gain bound
        soft_max=8.0,
        step=10,
        precision=2,
        description="Surroundings Custom: the unseen sky above and behind the camera is taken "
        "as a neutral grey this many times the ground's brightness in the photo (an average "
        f"place near {SKY_GAINS['auto']:g}, Open Sky {SKY_GAINS['open']:g}, Enclosed "
        f"{SKY_GAINS['enclosed']:g}); raise it until the chrome's top matches the sky you know",
    )
    sky_tint: FloatVectorProperty(
        update=_shaping_changed,
        name="Sky Tint",
        subtype="COLOR",
        size=3,
        default=(1.0, 1.0, 1.0),
        min=0.0,
        max=1.0,
        description="Surroundings Custom: the unseen sky's colour (its brightness is Sky "
        "Brightness): white, neutral grey as under Open Sky and Enclosed; a blue for an open "
        "sky, an orange for a sunset",
    )
    sky_texture: FloatProperty(
        update=_shaping_changed,
        name="Sky Texture",
        default=SKY_TEXTURE,
        min=0.0,
        max=1.0,
        subtype="FACTOR",
        description="How much of the photo's own texture the unseen sky in the reflection "
        "takes (Camera View + Ground; 1: the photo's own contrast; 0: a flat colour estimated "
        "from the photo): the skyline the photo shows continues around the camera as a band, "
        "its average brightness still the one the Surroundings set, the sky above it smooth "
        "(World HDRI: the HDRI is that sky)",
    )
    front: EnumProperty(
        name="Front Face",
        items=FRONT_ITEMS,
        default="CONTINUOUS",
        update=_shaping_changed,
        description="Paper (2004): how the plate's outer ring (region F) is folded onto the "
        "map's front face, what is behind the camera",
    )
    triangles: IntProperty(
        update=_shaping_changed,
        name="Triangles",
        description="n triangles for the front face (a multiple of 4)",
        default=32,
        min=4,
        max=MAX_TRIANGLES,
        step=4,
    )
    resolution: EnumProperty(
        name="Resolution",
        items=RESOLUTION_ITEMS,
        default="1024",
        update=_shaping_changed,
        description="The width of each object's lat-long map (its height is half): a larger "
        "map shows finer detail in a large or close mirror and costs more memory and time",
    )
    combine: EnumProperty(
        name="Combine",
        items=COMBINE_ITEMS,
        default="REPLACE",
        description="How the reflection meets each object's material: in place of it, times "
        "its colour, mixed over it, or as one shared map lighting the world",
    )
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
    map_storage: EnumProperty(
        name="Maps",
        items=MAP_STORAGE_ITEMS,
        default="PACK",
        description="Where the maps' pixels are kept: packed into the .blend, or saved as files",
    )
    live_update: BoolProperty(
        name="Live Update",
        description="Rebuild a reflective object's map while it moves, turns, scales or its mesh "
        "is edited: a quick small map during the drag, the full one once it rests",
        default=False,
        update=lambda settings, context: live.on_setting_changed(settings, context),
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
        update=lambda settings, context: sequence.on_setting_changed(settings, context),
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


class VR_ObjectSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(
        name="Mark for Generate",
        description="Marked objects get a reflection when Generate runs with nothing selected, "
        "and in the batch; an object generated while selected reflects without the mark",
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
