"""OpenCV, optional: a faster back end for the gather and the pyramid when `cv2` imports.

Blender does not bundle OpenCV and the extension never requires it: every step it speeds up
has a NumPy path that stays the reference (tests compare the two). VR_GATHER=numpy forces
the NumPy path.
"""

from __future__ import annotations

import os

_module = []


def cv2():
    """The cv2 module, or None when it does not import (imported once)."""
    if not _module:
        try:
            import cv2 as module  # optional: never required
        except Exception:  # not installed, or broken: the NumPy path, never an error
            module = None
        _module.append(module)
    return _module[0]


def backend() -> str:
    """'opencv' when cv2 imports and VR_GATHER is not 'numpy', else 'numpy'."""
    if os.environ.get("VR_GATHER", "").strip().lower() == "numpy":
        return "numpy"
    return "opencv" if cv2() is not None else "numpy"
