"""The objects' reflections as they were before a run from the window, put back when Esc
stops it (ops.py: Render Inter-Reflections).

Generate alone changes nothing before its last step (generate.steps), so a stopped Generate
needs no snapshot. The inter-reflection passes do: pass 1 attaches the maps and later passes
rewrite them, before the render that ends the run. What is kept, per object: whether it had
a reflection, its map's name and pixels, and its screen bounds. Put back: a reflection the
object did not have is taken off (its material slots restored, the copies deleted) and the
maps no object reflects any more are deleted; a map it had gets its pixels back (also in the
saved file, when maps are saved as files); the bounds are set back. A reflection the object
had keeps the wiring of the current settings (the same as before unless the combine mode,
strength or method changed since it was generated).
"""

from dataclasses import dataclass

import bpy
import numpy as np

from . import generate
from .node_trees import shading
from .scene import images, maps


@dataclass
class _Kept:
    obj: bpy.types.Object
    attached: bool
    bounds: tuple
    map_name: str | None
    pixels: np.ndarray | None  # (H, W, 3) float32 scene-linear, top row first


class Snapshot:
    """Take the reflections of ``objects`` in ``scene`` now; `restore` puts them back."""

    def __init__(self, scene, objects):
        self._scene = scene
        self._kept = []
        for obj in objects:
            image = shading.map_of(obj)
            pixels = images.read_pixels(image)[..., :3].copy() if image is not None else None
            self._kept.append(
                _Kept(
                    obj,
                    shading.is_attached(obj),
                    tuple(obj.virtual_reflections.bounds),
                    image.name if image is not None else None,
                    pixels,
                )
            )

    def restore(self) -> int:
        """Put the reflections back as they were; returns how many objects changed back."""
        try:
            save_dir = maps.save_folder(self._scene.virtual_reflections)
        except ValueError:  # maps saved beside an unsaved .blend: kept in memory, packed at save
            save_dir = None
        changed = 0
        for kept in self._kept:
            obj = kept.obj
            now = shading.map_of(obj)
            if not kept.attached:
                if shading.is_attached(obj):
                    shading.detach(obj)
                    changed += 1
            elif kept.pixels is not None and now is not None and now.name == kept.map_name:
                maps.store_map(kept.map_name, kept.pixels, save_dir)
                changed += 1
            obj.virtual_reflections.bounds = kept.bounds
        generate.remove_orphans()
        return changed
