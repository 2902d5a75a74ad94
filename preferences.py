"""The extension's preferences (Edit > Preferences > Add-ons > Virtual Reflections): what new
files start with, and where maps go when they are saved as files.

The defaults are copied into a scene once (`apply_defaults`, on file load), so a .blend
renders the same on every machine whatever the preferences there. Where saved maps go is
read when they are written (`maps_folder`).

Loaded the way the tests load it (a package that is not in ``preferences.addons``), `get`
returns `DEFAULTS`, plain values with the same names, so nothing else needs to care.
"""

import os
from types import SimpleNamespace

import bpy
from bpy.props import BoolProperty, EnumProperty

from .ui.properties import COMBINE_ITEMS, RESOLUTION_ITEMS

FOLDER_ITEMS = (
    (
        "BLEND",
        "Beside the .blend",
        "A vr_maps folder next to the .blend file (travels with the shot; save the file first)",
    ),
    (
        "USER",
        "Extension User Folder",
        "Blender's per-user folder for this extension, maps/<file name>/ (works for unsaved "
        "files; stays on this machine)",
    ),
)

DEFAULTS = SimpleNamespace(combine="REPLACE", resolution="AUTO", pack_maps=True, map_folder="BLEND")


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
    pack_maps: BoolProperty(
        name="Pack Maps into the .blend",
        default=DEFAULTS.pack_maps,
        description="New files pack their maps into the .blend when it is saved; off: maps are "
        "saved as EXR files in the folder below",
    )
    map_folder: EnumProperty(
        name="Saved Maps",
        items=FOLDER_ITEMS,
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
        col.prop(self, "pack_maps")
        col = layout.column()
        col.prop(self, "map_folder")
        try:
            where = maps_folder(create=False)
        except ValueError as exc:
            where = str(exc)
        col.label(text=where, icon="FILE_FOLDER")


def get(context=None):
    """The add-on's preferences, or `DEFAULTS` when it is not an enabled add-on (tests,
    scripts that import the package)."""
    preferences = getattr(context or bpy.context, "preferences", None)
    addon = preferences.addons.get(__package__) if preferences is not None else None
    if addon is None or addon.preferences is None:
        return DEFAULTS
    return addon.preferences


def maps_folder(create=True) -> str:
    """The folder saved maps go to. Raises ValueError (one line) when the preferences say
    "beside the .blend" and the file has not been saved yet."""
    blend = bpy.data.filepath
    if get().map_folder == "USER":
        stem = bpy.path.display_name_from_filepath(blend) if blend else "untitled"
        try:
            return bpy.utils.extension_path_user(
                __package__, path=os.path.join("maps", bpy.path.clean_name(stem)), create=create
            )
        except ValueError:
            pass  # not installed as an extension (imported by a test or a script): beside it
    if not blend:
        raise ValueError(
            "save the .blend first to save maps beside it (or pack them, or pick the "
            "extension user folder in the preferences)"
        )
    return os.path.join(os.path.dirname(bpy.path.abspath(blend)), "vr_maps")


def _untouched(scene) -> bool:
    """True when the add-on has done nothing in ``scene`` yet (no map, no report)."""
    from .operators import shading

    settings = scene.virtual_reflections
    if settings.last_report or scene.get(shading.WORLD_RECORD) is not None:
        return False
    return not any(shading.is_attached(obj) for obj in scene.objects)


def apply_defaults(scene, prefs=None) -> bool:
    """Give ``scene`` the preferred combine mode, resolution and packing, once.

    A scene is set once (``defaults_applied``), and only while the add-on has done nothing in
    it; a new, unsaved file takes the current preferences again. Returns True when it set them.
    """
    settings = scene.virtual_reflections
    if settings.defaults_applied and bpy.data.filepath:
        return False
    if not _untouched(scene):
        settings.defaults_applied = True
        return False
    prefs = prefs or get()
    settings.combine = prefs.combine
    settings.resolution = prefs.resolution
    settings.save_maps = not prefs.pack_maps
    settings.defaults_applied = True
    return True


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
