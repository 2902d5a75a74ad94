"""The choices an artist makes, as Blender enum items, and the add-on's preferences as values.

The scene settings (ui/properties.py) and the preferences (preferences.py) both offer these
items, and the map pipeline reads the preferences here, so this module sits at the bottom of
the Blender layer: it imports nothing of the add-on but the engine.
"""

from types import SimpleNamespace

import bpy

from ...virtual_reflections.mapsize import WIDTHS, auto_map_width
from ...virtual_reflections.methods import COMBINES, METHODS, SURROUNDINGS

# The extension's package (preferences' bl_idname): two up from operators/scene/.
ADDON = __package__.rsplit(".", 2)[0]


def _items(choices) -> tuple:
    """Blender enum items (key, label, description) of a choice list of the engine's methods."""
    return tuple((c.key, c.label, c.description) for c in choices)


COMBINE_ITEMS = _items(COMBINES)
METHOD_ITEMS = _items(METHODS)
SURROUNDINGS_ITEMS = _items(SURROUNDINGS)
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
        "From the object's size in the full-size render (Resolution 100 %): about 3 map pixels "
        "(pi) per pixel it spans, rounded up to the next size (256 to 4096)",
    ),
) + tuple((str(w), f"{w} x {w // 2}", f"Lat-long map {w} x {w // 2} pixels") for w in WIDTHS)
MAP_STORAGE_ITEMS = (
    ("PACK", "Pack into .blend", "Maps are packed into the .blend file when it is saved"),
    (
        "FILES",
        "Save as Files",
        "Maps are saved as EXR files (in a vr_maps folder beside the .blend, or where the "
        "extension's preferences say)",
    ),
)
MAP_FOLDER_ITEMS = (
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

# What the preferences hold when the add-on is not an enabled extension (tests, scripts).
DEFAULTS = SimpleNamespace(
    combine="REPLACE", resolution="AUTO", map_storage="PACK", map_folder="BLEND", table_cache_mb=512
)
DEFAULT_WIDTH = 1024  # Auto without an object to measure


def addon_preferences(context=None):
    """The extension's preferences, or `DEFAULTS` when it is not an enabled add-on."""
    preferences = getattr(context or bpy.context, "preferences", None)
    addon = preferences.addons.get(ADDON) if preferences is not None else None
    if addon is None or addon.preferences is None:
        return DEFAULTS
    return addon.preferences


def map_width(resolution: str, extent=None) -> int:
    """The lat-long width for the resolution setting ("AUTO" or a width as text): with Auto,
    the engine's rule for an object ``extent`` render pixels across (W = pi x extent, a power
    of two from 256 to 4096; the one the accuracy study measured), 1024 without an extent."""
    if resolution != "AUTO":
        return int(resolution)
    return DEFAULT_WIDTH if extent is None else auto_map_width(extent)
