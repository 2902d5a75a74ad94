"""Virtual Reflections engine: the environment map of Ropinski, Wachenfeld & Hinrichs (2004)
built from a plate and an object's screen-space bounds. NumPy and OpenImageIO, never bpy.

Frames (docs/conventions.md): plate pixels origin top-left, y down; directions in the camera
frame, +Z the viewing direction, +Y up, +X the plate's left; lat-long and cube layouts as
OpenEXR's ImfEnvmap. Colour: scene-linear Rec.709 throughout.
"""

from . import cache
from .envmap import DEFAULT_SIZE, apply_table, environment_map
from .params import Params
from .segmentation import Rect, Segmentation, segment
from .table import LookupTable, build_table, lookup_table

__all__ = [
    "DEFAULT_SIZE",
    "LookupTable",
    "Params",
    "Rect",
    "Segmentation",
    "apply_table",
    "cache",
    "build_table",
    "environment_map",
    "lookup_table",
    "segment",
]
