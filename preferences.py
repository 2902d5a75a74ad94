"""The extension's preferences (Edit > Preferences > Add-ons > Virtual Reflections): what new
files start with, and where maps go when they are saved as files.

The defaults are copied into a scene once (`apply_defaults`, on file load), so a .blend
renders the same on every machine whatever the preferences there. Where saved maps go is
read when they are written (`maps_folder`).

Loaded the way the tests load it (a package that is not in ``preferences.addons``), `get`
returns `DEFAULTS`, plain values with the same names, so nothing else needs to care.
"""

import bpy
from bpy.props import EnumProperty, IntProperty

from . import dependencies
from .operators.node_trees import shading, world
from .operators.scene import maps
from .operators.scene.choices import (
    COMBINE_ITEMS,
    DEFAULTS,
    MAP_FOLDER_ITEMS,
    MAP_STORAGE_ITEMS,
    RESOLUTION_ITEMS,
    addon_preferences,
)
from .virtual_reflections import backends, cache

BATCH = "The batch command line (render_shot.py)"
FASTER = "Optional: numba installed in Blender's Python makes map updates 2-4x faster"


class VR_AddonPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    combine: EnumProperty(
        name="Combine",
        items=COMBINE_ITEMS,
        default=DEFAULTS.combine,
        description="Combine mode new files start with",
    )
    resolution: EnumProperty(
        name="Resolution",
        items=RESOLUTION_ITEMS,
        default=DEFAULTS.resolution,
        description="Map resolution new files start with",
    )
    map_storage: EnumProperty(
        name="Maps",
        items=MAP_STORAGE_ITEMS,
        default=DEFAULTS.map_storage,
        description="Where new files keep their maps: packed into the .blend, or saved as EXR "
        "files in the folder below",
    )
    table_cache_mb: IntProperty(
        name="Table Cache",
        default=DEFAULTS.table_cache_mb,
        min=0,
        soft_max=8192,
        subtype="NONE",
        description="Memory kept for the maps' lookup tables (MB): a moved object or a new "
        "frame reuses a table it holds; the least recently used go first",
        update=lambda prefs, _context: _apply_cache_limit(prefs),
    )
    map_folder: EnumProperty(
        name="Saved Maps",
        items=MAP_FOLDER_ITEMS,
        default=DEFAULTS.map_folder,
        description="Where maps go when a scene saves them as files",
    )

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column(heading="New Files")
        col.prop(self, "combine")
        col.prop(self, "resolution")
        col.prop(self, "map_storage")
        layout.prop(self, "table_cache_mb")
        col = layout.column()
        col.prop(self, "map_folder")
        try:
            where = maps.maps_folder(create=False)
        except ValueError as exc:
            where = str(exc)
        col.label(text=where, icon="FILE_FOLDER")
        col = layout.column()
        col.label(text=f"Engine: {backends.describe()}", icon="INFO")
        if "numba" not in backends.installed():
            col.label(text=FASTER)
        if not dependencies.available("OpenImageIO"):  # everything in Blender works without
            row = layout.row()
            row.alert = True
            row.label(text=dependencies.needs("OpenImageIO", BATCH), icon="ERROR")


def get(context=None):
    """The add-on's preferences, or `DEFAULTS` when it is not an enabled add-on (tests,
    scripts that import the package)."""
    return addon_preferences(context)


def _untouched(scene) -> bool:
    """True when the add-on has done nothing in ``scene`` yet (no map, no report)."""
    settings = scene.virtual_reflections
    if settings.last_report or scene.get(world.WORLD_RECORD) is not None:
        return False
    return not any(shading.is_attached(obj) for obj in scene.objects)


def apply_defaults(scene, prefs=None) -> bool:
    """Give ``scene`` the preferred combine mode, resolution and map storage, once.

    A scene is set once (``defaults_applied``), and only while the add-on has done nothing in
    it; a new, unsaved file takes the current preferences again. Returns True when it set them.
    """
    settings = scene.virtual_reflections
    _migrate(settings)
    if settings.defaults_applied and bpy.data.filepath:
        return False
    if not _untouched(scene):
        settings.defaults_applied = True
        return False
    prefs = prefs or get()
    settings.combine = prefs.combine
    settings.resolution = prefs.resolution
    settings.map_storage = prefs.map_storage
    settings.defaults_applied = True
    return True


def _apply_cache_limit(prefs=None):
    """The engine's table cache takes the preferred budget (MB)."""
    cache.set_limit(int((prefs or get()).table_cache_mb) * 2**20)


def _migrate(settings):
    """Files saved before map storage was one choice hold the boolean ``save_maps``."""
    if "save_maps" in settings.keys():
        settings.map_storage = "FILES" if settings["save_maps"] else "PACK"
        del settings["save_maps"]


@bpy.app.handlers.persistent
def _on_load_post(*_args):
    for scene in bpy.data.scenes:
        apply_defaults(scene)


def _apply_to_open_file():
    """Enabled in a running session: the open file's scenes (bpy.data is not writable while
    add-ons register, so this runs from a timer)."""
    if isinstance(bpy.data, bpy.types.BlendData):
        _on_load_post()
    return None


def register():
    bpy.utils.register_class(VR_AddonPreferences)
    _apply_cache_limit()
    if _on_load_post not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_on_load_post)
    if not bpy.app.timers.is_registered(_apply_to_open_file):
        bpy.app.timers.register(_apply_to_open_file, first_interval=0.0, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(_apply_to_open_file):
        bpy.app.timers.unregister(_apply_to_open_file)
    if _on_load_post in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_on_load_post)
    bpy.utils.unregister_class(VR_AddonPreferences)
