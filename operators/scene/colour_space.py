"""Colour spaces through Blender's own OpenColorIO configuration: the file's working space and
conversions between any two of the config's spaces, for plates whose pixels Blender does not
convert itself.

Why: a byte (8-bit) image's ``pixels`` are its file's codes / 255 in the image's colour space
(sRGB, Display P3, Rec.1886, ...); Blender converts only float buffers to the working space
on load. In 5.x the working space is per file (``bpy.data.colorspace.working_space``: Linear
Rec.709, Linear Rec.2020 or ACEScg); in 4.5 it is Linear Rec.709. A plate must be in the
working space, or its reflections come out with the wrong primaries (an sRGB plate read as
ACEScg is ~35 % more saturated).

How: PyOpenColorIO ships with Blender. In Blender it imports as it is; in the ``bpy`` module it
sits in the wheel's bundled ``python/lib/pythonX.Y/site-packages`` and is loaded from there by
path (no ``sys.path`` edit). The config is the one Blender reads: ``$OCIO`` when set, else
``datafiles/colormanagement/config.ocio``. Some Blender builds ship without PyOpenColorIO
(Linux distributions' packages); then `convert` falls back to `convert_blender`: Blender's own
colour-management API (``mathutils.Color.from_*_to_scene_linear``, which use the same config)
gives the 3x3 matrices between the linear spaces it names, and the sRGB curve decodes the
encoded ones (sRGB, Display P3); other spaces raise ValueError.
"""

import functools
import importlib.util
import os
import sys

import bpy
import mathutils
import numpy as np

from ...virtual_reflections.colour import DISPLAY_P3_TO_XYZ_D65, linear_to_srgb, srgb_to_linear

REC709 = "Linear Rec.709"


def working_space() -> str:
    """The file's scene-linear working space: per file in 5.x, Linear Rec.709 in 4.5."""
    settings = getattr(bpy.data, "colorspace", None)
    return getattr(settings, "working_space", None) or REC709


@functools.cache
def ocio():
    """The PyOpenColorIO module Blender ships, or None (then `convert` uses NumPy)."""
    try:
        import PyOpenColorIO  # inside Blender: on its Python's path

        return PyOpenColorIO
    except ImportError:
        pass
    version = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    root = bpy.utils.resource_path("LOCAL")
    folder = os.path.join(root, "python", "lib", version, "site-packages", "PyOpenColorIO")
    init = os.path.join(folder, "__init__.py")
    if not os.path.isfile(init):
        return None
    spec = importlib.util.spec_from_file_location(
        "PyOpenColorIO", init, submodule_search_locations=[folder]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["PyOpenColorIO"] = module  # its __init__ imports its own .so relatively
    try:
        spec.loader.exec_module(module)
    except ImportError:
        del sys.modules["PyOpenColorIO"]
        return None
    return module


@functools.cache
def config():
    """Blender's OCIO config (``$OCIO`` when set, as Blender does), or None without OCIO."""
    module = ocio()
    if module is None:
        return None
    path = os.environ.get("OCIO") or os.path.join(
        bpy.utils.resource_path("LOCAL"), "datafiles", "colormanagement", "config.ocio"
    )
    return module.Config.CreateFromFile(path)


@functools.cache
def _processor(source, target):
    return config().getProcessor(source, target).getDefaultCPUProcessor()


def convert(pixels: np.ndarray, source: str, target: str) -> np.ndarray:
    """(H, W, 3) float32 values in colour space ``source`` -> the same in ``target`` (names as
    Blender's colour-space menu has them). ValueError (one line) for a space neither OCIO
    nor the NumPy fallback knows."""
    rgb = np.ascontiguousarray(pixels, dtype=np.float32)
    if source == target:
        return rgb
    if config() is not None:
        try:
            processor = _processor(source, target)
        except Exception as exc:  # PyOpenColorIO.Exception: an unknown space
            raise ValueError(f"colour space {source!r} -> {target!r}: {exc}") from exc
        out = rgb.copy()
        processor.applyRGB(out)
        return out
    return convert_blender(rgb, source, target)


# Blender's API: linear spaces -> the working space ("scene linear"), by mathutils.Color method.
_TO_SCENE = {
    "Linear Rec.709": "from_rec709_linear_to_scene_linear",
    "Linear Rec.2020": "from_rec2020_linear_to_scene_linear",  # 4.4+
    "ACEScg": "from_acescg_to_scene_linear",  # 4.4+
    "ACES2065-1": "from_aces_to_scene_linear",
    "Linear CIE-XYZ D65": "from_xyz_d65_to_scene_linear",
}
# Encoded spaces the fallback knows: (the linear space they encode, extra matrix to it or None).
_ENCODED = {"sRGB": ("Linear Rec.709", None), "Display P3": ("Linear CIE-XYZ D65", "P3")}


def _to_scene(space) -> np.ndarray:
    """(3, 3) float64 matrix: linear ``space`` -> the working space, by Blender's API."""
    method = _TO_SCENE.get(space)
    if method is None or not hasattr(mathutils.Color, method):
        raise ValueError(
            f"colour space {space!r}: PyOpenColorIO is not available and Blender's API "
            "does not convert it"
        )
    columns = [getattr(mathutils.Color(e), method)() for e in np.eye(3)]
    return np.array(columns, dtype=np.float64).T


def convert_blender(pixels: np.ndarray, source: str, target: str) -> np.ndarray:
    """`convert` without PyOpenColorIO: between the linear spaces of `_TO_SCENE` and the
    working space, and from sRGB or Display P3 (the sRGB curve, then their primaries).
    ValueError (one line) for another space."""
    rgb = np.asarray(pixels, dtype=np.float32)
    if source in _ENCODED:
        rgb = srgb_to_linear(rgb)
        source, extra = _ENCODED[source]
        matrix = _to_scene(source) @ (DISPLAY_P3_TO_XYZ_D65 if extra else np.eye(3))
    else:
        matrix = _to_scene(source)
    if target != working_space():
        matrix = np.linalg.inv(_to_scene(target)) @ matrix
    return (rgb @ matrix.T.astype(np.float32)).astype(np.float32)


def to_srgb(linear: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 in the working space -> sRGB-encoded [0, 1] for an 8-bit display
    (previews): through OCIO from a wide working space (its primaries), else the sRGB curve."""
    working = working_space()
    if working != REC709:
        linear = convert(linear, working, REC709)
    return linear_to_srgb(np.clip(linear, 0.0, 1.0))
