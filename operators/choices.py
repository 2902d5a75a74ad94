"""The choices an artist makes, as Blender enum items, and the add-on's preferences as values.

The scene settings (ui/properties.py) and the preferences (preferences.py) both offer these
items, and the map pipeline reads the preferences here, so this module sits at the bottom of
the Blender layer: it imports nothing of the add-on but the engine.
"""

from types import SimpleNamespace

import bpy

from ..virtual_reflections.mapsize import WIDTHS, auto_map_width
from ..virtual_reflections.params import SKY_GAINS

ADDON = __package__.rpartition(".")[0]  # the extension's package (preferences' bl_idname)

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
METHOD_ITEMS = (
    (
        "GROUND",
        "Camera View + Ground",
        "Camera View, and the ground the objects stand on seen from each object: what a mirror "
        "shows below it comes from where the photo shows that ground (the ground: the Ground "
        "object, else a shadow catcher, else the objects' lowest point; docs/ground.md)",
    ),
    (
        "CAMERA",
        "Camera View",
        "Place the plate exactly by the camera's field of view, everything taken as distant; "
        "where the photo saw nothing, extend its edges into the sky, ground and sides it "
        "suggests (docs/accuracy.md)",
    ),
    (
        "PAPER",
        "Paper (2004)",
        "Ropinski et al.: the plate cut into regions around the object's bounds and folded "
        "onto a cube (neighbouring objects show on the sides facing them)",
    ),
)
SURROUNDINGS_ITEMS = (  # the sky prior's gain for each: virtual_reflections.params.SKY_GAINS
    (
        "AUTO",
        "Auto",
        "Nothing said of the shot: the sky the photo does not show is taken as a neutral "
        f"grey {SKY_GAINS['auto']:g} times the ground's brightness in the photo (learnt from "
        "HDRIs of every kind)",
    ),
    (
        "OPEN",
        "Open Sky",
        "Outdoors, the sky over most of what stands around (streets, fields, a sunset): the "
        f"unseen sky is taken brighter, {SKY_GAINS['open']:g} times the ground's",
    ),
    (
        "ENCLOSED",
        "Enclosed",
        "A dim room, a studio or a yard walled in by buildings: what is above and behind the "
        f"camera is taken darker, {SKY_GAINS['enclosed']:g} times the ground's brightness (for a "
        "mirror; in the Glossy look a rough surface's map takes a brighter sky, by roughness). "
        "A brightly lit hall, lobby or workshop is closer to Auto",
    ),
    (
        "WORLD",
        "World HDRI",
        "The scene's world holds the HDRI shot on set: what the photo does not show comes "
        "from it, turned and as bright as the world is set (read, never changed)",
    ),
    (  # last: a file stores an enum by its index, so a new item goes after the others
        "CUSTOM",
        "Custom",
        "Say how bright the unseen sky is: Sky Brightness times the ground's brightness in the "
        f"photo (Auto takes {SKY_GAINS['auto']:g}; a rough surface's map takes a brighter sky by "
        "roughness, as under Auto)",
    ),
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
