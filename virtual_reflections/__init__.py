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

# What others may use (the add-on, the study, the benchmarks, the farm, the sample scenes): the
# names above and the modules below, imported as `from virtual_reflections.<module> import ...`
# (each loaded when imported, not with the package). The engine's other modules are its own;
# tests/test_architecture.py keeps every import from outside to this list.
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
    # modules
    "atomic_files",
    "backends",
    "camera_view",
    "cli_common",
    "colour",
    "envmap",
    "fill",
    "frames",
    "ggx_lobe",
    "imagefiles",
    "interrupts",
    "layouts",
    "mapsize",
    "memory",
    "methods",
    "mipmap",
    "movies",
    "overlay",
    "parallel",
    "params",
    "plainexr",
    "prefilter",
    "probe",
    "segmentation",
    "sky_texture",
    "table",
]
