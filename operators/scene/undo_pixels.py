"""Undo and redo bring the maps' pixels back.

Blender's undo keeps a datablock's data, not the pixels of an image made in memory (a
generated image, or a packed one whose pixels changed since it was packed): after Ctrl+Z and
Ctrl+Shift+Z such an image comes back with its generated, black pixels, and every object
reflecting it renders black. So each write of a map's pixels gets a token, stored on the
image (a custom property, which undo does keep), and the pixels are remembered under it in
this session; after an undo or a redo step every image whose token is remembered gets its
pixels back. The pixels are remembered up to `BUDGET_BYTES`, the least recently written going
first (an image whose pixels were dropped keeps what undo gave it).
"""

import itertools
import os
from collections import OrderedDict

import bpy
import numpy as np

from . import images

TOKEN = "vr_pixels"  # on images: which remembered pixels they hold
BUDGET_BYTES = 1 << 30

_session = os.urandom(4).hex()  # tokens of another session (a reopened file) never match
_count = itertools.count(1)
_kept = OrderedDict()  # token -> (H, W, 3) float32 pixels, least recently written first


def remember(image, pixels: np.ndarray, new: bool = True):
    """Remember a copy of the (H, W, 3) float32 ``pixels`` just written into ``image``. new:
    under a new token (an operator's write, an undo step of its own); False: replace the
    pixels under the image's token (a write in place between undo steps: a frame change)."""
    token = image.get(TOKEN)
    if new or token not in _kept:
        token = f"{_session}-{next(_count)}"
        image[TOKEN] = token
    _kept.pop(token, None)
    _kept[token] = np.array(pixels, dtype=np.float32, copy=True)
    total = sum(a.nbytes for a in _kept.values())
    while total > BUDGET_BYTES and len(_kept) > 1:
        _, dropped = _kept.popitem(last=False)
        total -= dropped.nbytes


def restore() -> int:
    """Write the remembered pixels back into every image whose token is remembered; returns
    how many."""
    count = 0
    for image in bpy.data.images:
        pixels = _kept.get(image.get(TOKEN)) if images.created(image) else None
        if pixels is None:
            continue
        images.write_pixels(image, pixels)
        image.update()
        count += 1
    return count


def forget():
    _kept.clear()


# Modes whose undo steps are their own (a mesh, a sculpt): they reload no image.
OWN_UNDO = ("EDIT", "SCULPT", "PAINT", "PARTICLE")


@bpy.app.handlers.persistent
def _after_undo(*_args):
    if not bpy.context.mode.startswith(OWN_UNDO):
        restore()


@bpy.app.handlers.persistent
def _after_load(*_args):
    forget()


_HANDLERS = (("undo_post", _after_undo), ("redo_post", _after_undo), ("load_post", _after_load))


def register():
    for name, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if handler not in handlers:
            handlers.append(handler)


def unregister():
    for name, handler in _HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if handler in handlers:
            handlers.remove(handler)
    forget()
