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
``datafiles/colormanagement/config.ocio``. Without PyOpenColorIO, `convert` falls back to the
engine's pure-NumPy transfer curves and matrices (`virtual_reflections.colour`) for the spaces
it knows (sRGB, the linear working spaces) and raises ValueError for the others.
"""

import functools
import importlib.util
import os
import sys

import bpy
import numpy as np

from ..virtual_reflections.colour import LINEAR_REC709_TO, linear_to_srgb, srgb_to_linear

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
    # Fallback without PyOpenColorIO: the sRGB curve and 3x3 matrices out of Linear Rec.709.
    if source == "sRGB":
        rgb, source = srgb_to_linear(rgb), REC709
    if source != REC709 or target not in LINEAR_REC709_TO:
        raise ValueError(
            f"colour space {source!r} -> {target!r} needs PyOpenColorIO, which is not available"
        )
    return (rgb @ LINEAR_REC709_TO[target].T).astype(np.float32)


def to_srgb(linear: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 in the working space -> sRGB-encoded [0, 1] for an 8-bit display
    (previews): through OCIO from a wide working space (its primaries), else the sRGB curve."""
    working = working_space()
    if working != REC709:
        linear = convert(linear, working, REC709)
    return linear_to_srgb(np.clip(linear, 0.0, 1.0))
