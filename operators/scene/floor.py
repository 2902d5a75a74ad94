"""Where the reflective objects stand (Camera View + Ground, docs/ground.md "The ground in
Blender"): the object whose top is their ground -- the chosen Ground object, else a shadow
catcher, else the floor under them -- or their own lowest point; the panel's line saying which;
the boxes of objects it is measured on."""

import math

import numpy as np

from . import bounds


def ground_height(scene, depsgraph, objects) -> float:
    """The world height (Z) of the ground the objects stand on: the top of `ground_of`'s
    object, else the lowest point of ``objects``."""
    ground = ground_of(scene, depsgraph, objects)
    if ground is not None:
        return float(bounds.world_box(ground, depsgraph)[1][2])
    return min(float(bounds.world_box(o, depsgraph)[0][2]) for o in objects)


def ground_of(scene, depsgraph, objects):
    """The object whose top is the ground ``objects`` stand on, or None (their lowest point
    is): the scene's ground object (``settings.ground_object``) when one is chosen, else a
    shadow catcher in the scene, else the highest floor under them (`floor_under`: a
    floating object is seen over the floor the scene holds)."""
    chosen = scene.virtual_reflections.ground_object
    if chosen is not None:
        return chosen
    catcher = next(
        (o for o in scene.objects if getattr(o, "is_shadow_catcher", False) and o.type == "MESH"),
        None,
    )
    if catcher is not None:
        return catcher
    return floor_under(scene, depsgraph, objects) if objects else None


def ground_source(scene, depsgraph, objects) -> str:
    """One line for the panel: where `ground_height` takes the ground of ``objects`` from."""
    ground = ground_of(scene, depsgraph, objects)
    if ground is None:
        return "Ground: the objects' lowest point (choose the Ground if they float)"
    if ground == scene.virtual_reflections.ground_object:
        return f"Ground: '{ground.name}', chosen"
    if getattr(ground, "is_shadow_catcher", False):
        return f"Ground: the shadow catcher '{ground.name}'"
    return f"Ground: '{ground.name}', the floor under the objects"


def grounds_among(scene, depsgraph, objects) -> list:
    """Those of ``objects`` that are the ground the others stand on, never reflective unless
    marked (the batch leaves them out when it takes every visible object): the chosen Ground
    object, every shadow catcher (Set Up's "VR Ground" among them), and the floor under the
    rest (`floor_under`), the ground `ground_of` reads."""
    chosen = scene.virtual_reflections.ground_object
    found = [o for o in objects if o == chosen or getattr(o, "is_shadow_catcher", False)]
    rest = [o for o in objects if o not in found]
    for obj in rest:
        width = max(obj.dimensions.x, obj.dimensions.y)  # cheap first: only flat ones
        others = [o for o in rest if o != obj]
        if obj.type == "MESH" and others and obj.dimensions.z <= FLAT * width:
            if floor_under(scene, depsgraph, others) == obj:
                found.append(obj)
    return found


FLAT = 0.02  # a mesh whose height is at most this share of its width is a floor
SUNK = 0.05  # share of the objects' height they may sink into a floor and still stand on it


def floor_under(scene, depsgraph, objects):
    """The floor under ``objects`` (an object), or None: of the visible meshes of the scene
    (not theirs) that reach under the centre of their box and top out below their lowest
    point (or at most SUNK of their height above it), the highest, when it is flat — its
    world box at most FLAT times as high as it is wide: a ground plane, a floor, a slab. A
    scene's ground plane that is no shadow catcher (hidden from render, or rendered as the
    floor) is so found, and an object floating over it reflects the ground where it is rather
    than at its own lowest point. When the highest is not flat (a column, a pedestal, a table
    with legs, a box) the objects stand on it: None, and their lowest point is its top."""
    low, high = objects_box(depsgraph, objects)
    x, y = 0.5 * (low[:2] + high[:2])
    ceiling = low[2] + SUNK * (high[2] - low[2])
    best, top = None, -math.inf
    for obj in scene.objects:
        if obj.type != "MESH" or obj in objects or not obj.visible_get():
            continue
        # Cheap first: a mesh's box lies within its diagonal of its origin (as a rule; one
        # that does not is missed, and the lowest point stands in, as without a floor).
        reach = obj.dimensions.length
        origin = obj.matrix_world.translation
        if math.hypot(origin.x - x, origin.y - y) > reach or origin.z - reach > ceiling:
            continue
        lo, hi = bounds.world_box(obj, depsgraph)
        if lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and top < hi[2] <= ceiling:
            best, top, box = obj, float(hi[2]), (lo, hi)
    if best is None:
        return None
    lo, hi = box
    return best if hi[2] - lo[2] <= FLAT * max(hi[0] - lo[0], hi[1] - lo[1]) else None


def objects_box(depsgraph, objects) -> tuple:
    """((3,) low, (3,) high) world-space corners of the bounding box of ``objects`` (evaluated)."""
    boxes = [bounds.world_box(o, depsgraph) for o in objects]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


def objects_centre(depsgraph, objects) -> np.ndarray:
    """(3,) world-space centre of the bounding box of ``objects`` (evaluated)."""
    low, high = objects_box(depsgraph, objects)
    return 0.5 * (low + high)
