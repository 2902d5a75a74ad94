"""Virtual objects reflecting each other: the paper's multi-pass rendering (§3.3, Listing 1).

Listing 1 renders r passes; in each one every object gets a map built from the current screen
S, and the captured screen becomes S for the next. r = 1 shows the plate on every object,
r = 2 the objects in each other, r = 3 those reflections again, and so on. Here, improved:

- Pass 1 is Generate (`generate.generate`): every reflective object's map from the plate, then
  ONE render of all of them (so the number of renders is r, whatever the number of objects).
  The composite (render over plate) is the next plate.
- In pass k > 1 each object's map is built from the previous composite, but with the object's
  own pixels put back to the plate first, so an object never reflects its own previous image
  (the paper's two mirrors "will not reflect themselves in the mirror shown in their own
  reflection"). The masks come from the object-index pass: each reflective object gets a
  unique ``pass_index`` for the duration. Cycles' object index is not antialiased (it is the
  first sample's object), so each mask is grown by a pixel to take in the object's edge.
- Passes after the first re-render only the region covering the reflective objects (a render
  border, not cropped) and paste it into the previous full render: between passes only the
  maps change, and a map is seen only on its object. (What the objects' new maps would change
  elsewhere -- their mirror images in other glossy virtual objects, the glow of a Replace-mode
  emission on the ground -- stays as the first pass rendered it.)
- In pass k > 1 the other reflective objects are also placed in each map where they stand
  (`_place_neighbours`): a map built from the composite alone puts a neighbour where the camera
  saw it, near the view direction for the camera-view methods.
- Later passes build each map with Generate itself, given the masked composite as the plate
  (``generate.generate(..., pixels=...)``): the same bounds, map size and settings as pass 1, so
  the engine's cached lookup table is found again, the map image is updated in place
  (`maps.store_map`) and the material copies are rewired, not multiplied (`shading.attach`
  first takes off what it attached before).

Frames and sizes: plate pixels (docs/conventions.md: origin top-left, y down). The plate has its own
size (H, W); the render has the scene's (h, w), after the resolution percentage. Maps are
always built at the plate's size, as Generate builds them -- the render is scaled up (nearest)
and put over the full plate -- so later passes keep the plate's detail; the composites this
module returns are at the render's size, over the plate scaled down (nearest), as the batch
entry composites. Everything is scene-linear Rec.709 float32.

Rendering: each pass ends in a render step (`generate.Step` with ``render``): from the
window Blender's own render job (as F12: the render view fills in, the window works, Esc or
the job's cancel stops the run once the render ends), else a blocking render. The render is
written as a multilayer EXR (Combined and the object index of the
depsgraph's view layer), uncompressed, into a temporary folder and read with NumPy alone
(the engine's plainexr.py: no OpenImageIO, which some Blender packages lack). Everything
changed for that -- output format and path, border, compositing, film, persistent data (the
bpy 4.5 module's Cycles does not see map updates with it), the object index pass, the
objects' pass indices, Update Every Frame -- is restored afterwards, also on errors.
"""

import contextlib
import math
import os
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from ..virtual_reflections import methods
from ..virtual_reflections.layouts import latlong_directions
from ..virtual_reflections.plainexr import read_channels
from . import generate, traced_pass
from .node_trees import shading
from .scene import bounds, images, maps
from .scene.composite import nearest_rows, over, resize_nearest
from .scene.plate import NO_PLATE, scene_plate

R_MAX = 8  # the most passes "auto" renders unless told otherwise
TOLERANCE = 1.0 / 255.0  # "auto" stops when a pass changes the objects' pixels less than this
MASK_GROW = 1  # px added around each object's index mask (the index is not antialiased)
REGION_PAD = 2  # px around the objects that later passes replace (the pixel filter's reach)
BORDER_PAD = 2  # px rendered around that region, so the border's rounding never leaves a gap
INDEX_PASSES = ("IndexOB", "Object Index")  # the object index pass: 4.5, 5.x


@dataclass
class PassReport:
    """One pass of `render_passes`.

    index: 1 for the first pass. seconds: the whole pass. change: mean |composite - previous
    composite| over the reflective objects' pixels and the three channels, scene-linear (pass
    1: against the bare plate). border: the re-rendered region (x0, y0, x1, y1) in render pixels
    (origin top-left, y down, x1/y1 exclusive), None for the full frame. maps_seconds: building
    and storing the maps (pass 1: all of Generate). render_seconds: Blender's render call.
    warnings: Generate's, on pass 1.
    """

    index: int
    seconds: float
    change: float
    border: tuple | None
    maps_seconds: float
    render_seconds: float
    warnings: tuple = ()

    def line(self):
        region = "full frame"
        if self.border is not None:
            x0, y0, x1, y1 = self.border
            region = f"border {x1 - x0}x{y1 - y0}"
        return (
            f"pass {self.index}: {self.seconds:.2f} s (maps {self.maps_seconds:.2f} s, "
            f"render {self.render_seconds:.2f} s, {region}), change {self.change:.5f}"
        )


def render_passes(
    scene,
    depsgraph,
    objects,
    pixels,
    passes=1,
    tolerance=TOLERANCE,
    r_max=R_MAX,
    progress=None,
    *,
    self_mask=True,
    neighbours=True,
):
    """Render ``objects`` with r-level inter-reflections; returns ``(composite, rgba, reports)``.

    depsgraph: the evaluated depsgraph of the view layer to render (its object index pass is
    read). pixels: the scene's plate, (H, W, 3) float32 scene-linear, as `plate.pixels` gives
    it (pass 1 is Generate, which reads the scene's plate itself). passes: r, an int >= 1, or
    "auto": passes until one changes the objects' pixels by less than ``tolerance`` (mean
    absolute, scene-linear), at most ``r_max``. progress: called with the number of passes
    done, a float (0 .. the pass limit) that grows as the passes advance.
    composite: (h, w, 3) float32, the last render over the plate; rgba: (h, w, 4) float32
    premultiplied, the last render (later passes pasted into the first); reports: one
    `PassReport` per pass. ``self_mask=False`` follows Listing 1 literally: objects see their
    own previous image too. ``neighbours=False`` leaves each map as Generate builds it from
    the composite (`_place_neighbours`). Raises ValueError (one line) when nothing can be
    rendered.

    The blocking run of `pass_steps` (the same arguments): scripts, ``blender -b``, the batch.
    """
    limit = _pass_limit(passes, r_max)
    run = pass_steps(
        scene, depsgraph, objects, pixels, passes, tolerance, r_max,
        self_mask=self_mask, neighbours=neighbours,
    )  # fmt: skip
    return generate.drive(run, (lambda done: progress(done * limit)) if progress else None)


def pass_steps(
    scene,
    depsgraph,
    objects,
    pixels,
    passes=1,
    tolerance=TOLERANCE,
    r_max=R_MAX,
    *,
    self_mask=True,
    neighbours=True,
):
    """`render_passes` as a generator of `generate.Step`s, returning what it returns: the
    operator runs it step by step from the window (generate.Job), the maps' engine work in a
    thread and each render as Blender's render job. ``done`` counts passes: pass k runs from
    (k - 1) / limit to k / limit of the whole (limit: r, or ``r_max`` for "auto").

    Closed between steps (Esc), it restores the render settings and removes its temporary
    files; what pass 1 (Generate) and later passes changed in the maps stays: the caller
    restores that (`reflection_snapshot`).
    """
    limit = _pass_limit(passes, r_max)
    plate = _checked_plate(scene, pixels)
    check_combine(scene.virtual_reflections.combine, passes, r_max)
    layer = depsgraph.view_layer
    with tempfile.TemporaryDirectory(prefix="vr-passes-") as folder:
        run = _Run(scene, depsgraph, layer, os.path.join(folder, "pass.exr"), passes, limit, plate)
        # Pass 1: Generate, then one full render.
        started = time.perf_counter()
        generated = yield from generate.within(
            generate.steps(scene, depsgraph, objects), 0.0, 0.6 / limit, run.label(1)
        )
        maps_seconds = time.perf_counter() - started
        by_name = {obj.name: obj for obj in objects}
        done = [by_name[name] for name in generated.done]
        if not done:
            raise ValueError("no reflection generated: " + "; ".join(generated.warnings))
        with _render_state(scene, layer, run.path, done) as ids:
            first = yield from _first_render(run, ids, done, generated, started, maps_seconds)
            reports = [first.report]
            if limit == 1:
                return first.composite, first.rgba, reports
            size = first.rgba.shape[:2]
            border = _border(done, first.coverage, plate.shape, size)
            _set_border(scene.render, border, size)
            if neighbours and self_mask and traced_pass.applies(scene, done):
                composite, report = yield from _traced_second_pass(run, done, first, border)
                return composite, first.rgba, [*reports, report]
            composite = yield from _later_passes(
                run, done, first, border, reports, tolerance, self_mask, neighbours
            )
    return composite, first.rgba, reports


@dataclass(frozen=True)
class _Run:
    """What every pass of one run shares: the scene and the view layer rendered, the render's
    file, ``passes`` as asked, their ``limit`` and the plate ((H, W, 3) float32)."""

    scene: object
    depsgraph: object
    layer: object
    path: str
    passes: object
    limit: int
    plate: np.ndarray

    def label(self, k):
        """The steps' label of pass ``k``."""
        if self.passes != "auto":
            return f"Pass {k} of {self.limit}: "
        return f"Pass {k} (at most {self.limit}): "


@dataclass(frozen=True)
class _FirstPass:
    """Pass 1's render and what later passes read of it: ``rgba`` (h, w, 4) (later passes
    paste their region into it), its ``composite`` over ``plate_small`` (the plate at the
    render's size), each object's index mask grown (``own``) and shrunk (``core``), their
    union (``coverage``) and the pass's report."""

    rgba: np.ndarray
    composite: np.ndarray
    plate_small: np.ndarray
    own: dict
    core: dict
    coverage: np.ndarray
    report: PassReport


def _checked_plate(scene, pixels):
    """``pixels`` as float32, checked to be the scene's plate ((H, W, 3) of its size);
    ValueError (one line) without a plate or with other pixels."""
    plate = np.asarray(pixels, dtype=np.float32)
    image = scene_plate(scene)
    if image is None:
        raise ValueError(NO_PLATE)
    if plate.ndim != 3 or plate.shape[2] != 3 or plate.shape[1::-1] != tuple(image.size):
        raise ValueError(
            f"the plate must be the scene's plate pixels ({image.size[0]}x{image.size[1]}x3), "
            f"got shape {plate.shape}"
        )
    return plate


def _first_render(run, ids, done, generated, started, maps_seconds):
    """Pass 1's render step (``ids``: {object: pass index}); returns its `_FirstPass`."""
    rendered = time.perf_counter()
    yield generate.Step(
        run.label(1) + "rendering", 0.6 / run.limit, render=(run.scene.name, run.layer.name)
    )
    rgba, index = _read_render(run.scene, run.layer, run.path)
    render_seconds = time.perf_counter() - rendered
    h, w = rgba.shape[:2]
    plate_small = resize_nearest(run.plate, h, w)
    composite = over(rgba, plate_small)
    own = {obj: _grow(index == i, MASK_GROW) for obj, i in ids.items()}
    # ... and shrunk, for reading a neighbour: its edge pixels are mixed with the plate
    core = {obj: ~_grow(index != i, MASK_GROW) for obj, i in ids.items()}
    coverage = np.logical_or.reduce(list(own.values()))
    notes = _method_note(run.scene.virtual_reflections, run.limit, len(done))
    report = PassReport(
        1,
        time.perf_counter() - started,
        _change(composite, plate_small, coverage),
        None,
        maps_seconds,
        render_seconds,
        tuple(generated.warnings) + notes,
    )
    return _FirstPass(rgba, composite, plate_small, own, core, coverage, report)


def _traced_second_pass(run, done, first, border):
    """Camera View + Ground under Cycles: pass 2 ray traces every level at once (in the
    region ``border``); returns (its composite, its report)."""
    started = time.perf_counter()
    with traced_pass.traced(run.scene, done):
        render_seconds = yield from _render_region(
            run.scene, run.layer, run.path, run.label(2) + "rendering (ray traced)",
            1.6 / run.limit, first.rgba, border,
        )  # fmt: skip
    composite = over(first.rgba, first.plate_small)
    note = (TRACED_NOTE,) if run.limit > 2 and run.passes != "auto" else ()
    change = _change(composite, first.composite, first.coverage)
    seconds = time.perf_counter() - started
    return composite, PassReport(2, seconds, change, border, 0.0, render_seconds, note)


def _later_passes(run, done, first, border, reports, tolerance, self_mask, neighbours):
    """Passes 2 to the limit (with "auto", until one changes less than ``tolerance``): each
    object's map built again from the previous composite with its own pixels the plate's (and
    its neighbours placed), then the region ``border`` rendered again. Appends each pass's
    report to ``reports``; returns the last composite."""
    plate, rgba, composite = run.plate, first.rgba, first.composite
    h, w = rgba.shape[:2]
    x0, y0, x1, y1 = border
    # The region at the plate's size: plate rows Y0:Y1 and columns X0:X1 show the
    # render pixels `sub` (nearest).
    ys, xs = nearest_rows(h, plate.shape[0]), nearest_rows(w, plate.shape[1])
    (Y0, Y1), (X0, X1) = np.searchsorted(ys, (y0, y1)), np.searchsorted(xs, (x0, x1))
    sub = np.ix_(ys[Y0:Y1], xs[X0:X1])
    own_sub = {obj: mask[sub] for obj, mask in first.own.items()}
    # The composite at the plate's size; outside the region it stays pass 1's.
    source = over(rgba[np.ix_(ys, xs)], plate)
    inside, plate_inside = source[Y0:Y1, X0:X1], plate[Y0:Y1, X0:X1]
    for k in range(2, run.limit + 1):
        started = time.perf_counter()
        # The previous composite is the new plate ...
        inside[...] = over(rgba[sub], plate_inside)
        for n, obj in enumerate(done):
            # ... except where the object itself is: there it sees the original plate.
            # Generate builds the map exactly as in pass 1 (same bounds, size and
            # settings: the engine's cached table) and stores it in place.
            mine = own_sub[obj] if self_mask else np.zeros(inside.shape[:2], bool)
            kept = inside[mine]
            inside[mine] = plate_inside[mine]
            share = (k - 1 + 0.6 * n / len(done)) / run.limit
            yield from generate.within(
                generate.steps(run.scene, run.depsgraph, [obj], pixels=source),
                share,
                share + 0.6 / len(done) / run.limit,
                run.label(k),
            )
            if neighbours:
                others = {o: first.core[o] for o in done if o is not obj}
                _place_neighbours(run.scene, run.depsgraph, obj, others, source)
            inside[mine] = kept
        maps_seconds = time.perf_counter() - started
        render_seconds = yield from _render_region(
            run.scene, run.layer, run.path, run.label(k) + "rendering", (k - 0.4) / run.limit,
            rgba, border,
        )  # fmt: skip
        previous, composite = composite, over(rgba, first.plate_small)
        reports.append(
            PassReport(
                k,
                time.perf_counter() - started,
                _change(composite, previous, first.coverage),
                border,
                maps_seconds,
                render_seconds,
            )
        )
        if run.passes == "auto" and reports[-1].change < tolerance:
            break
    return composite


def _render_region(scene, layer, path, stage, share, rgba, border):
    """A later pass's render step: Blender renders the border, its region is pasted into
    ``rgba`` (render pixels, ``border`` as `_border`). Returns the render's seconds."""
    rendered = time.perf_counter()
    yield generate.Step(stage, share, render=(scene.name, layer.name))
    new, _ = _read_render(scene, layer, path)
    x0, y0, x1, y1 = border
    rgba[y0:y1, x0:x1] = new[y0:y1, x0:x1]
    return time.perf_counter() - rendered


TRACED_NOTE = (
    "Pass 2 was ray traced: it holds every level of inter-reflection the scene's glossy "
    "bounces allow, so later passes would not change it"
)
CAMERA_NOTE = (
    "Camera View treats the surroundings as distant, so nearby objects show little of each "
    "other; the Paper method puts a neighbour on the side of the map that faces it"
)


def _method_note(settings, limit, count) -> tuple:
    """A warning when passes would show little: several objects under Camera View."""
    if limit > 1 and count > 1 and methods.takes_all_distant(settings.method):
        return (CAMERA_NOTE,)
    return ()


def check_combine(combine, passes, r_max=R_MAX):
    """ValueError (one line) when ``passes`` (more than one) meet Combine ``combine`` World:
    inter-reflections need a map per object. The batch checks it before its first frame."""
    if _pass_limit(passes, r_max) > 1 and combine == "WORLD":
        raise ValueError(
            "inter-reflections need a map per object: choose a combine mode other than World"
        )


def _pass_limit(passes, r_max):
    if not isinstance(r_max, int) or r_max < 1:
        raise ValueError(f"r_max must be a whole number of passes >= 1, not {r_max!r}")
    if passes == "auto":
        return r_max
    if isinstance(passes, bool) or not isinstance(passes, int) or passes < 1:
        raise ValueError(f"passes must be a whole number >= 1 or 'auto', not {passes!r}")
    return passes


# --- the neighbours in each map ------------------------------------------------------------------


def _place_neighbours(scene, depsgraph, obj, others, source):
    """Paste the other reflective objects into ``obj``'s map where they stand around it.

    A map built from the composite puts a neighbour where the camera saw it: Camera View (and
    Camera View + Ground's map) near the view direction, which a mirror shows only at its rim;
    in the 3D study the passes left the objects' pixels unchanged. Here each direction d of the
    map is followed from the point of ``obj``'s bounding sphere that reflects d toward the
    camera (a near neighbour fills more of a mirror's side than it does seen from the centre)
    and tested against the other objects (each an ellipsoid filling its own bounding box);
    where it meets one and the camera sees the meeting point on that object (its index mask),
    the map takes the composite's pixel there (nearest).

    others: {object: (h, w) bool mask at the render's size}. source: (H, W, 3) float32, the
    composite at the plate's size. The map is stored again in place (`maps.store_map`).
    Directions: the map's lat-long texels in the camera frame (docs/conventions.md), turned to
    the world by the camera's rotation.
    """
    image = shading.map_of(obj)
    camera = scene.camera.evaluated_get(depsgraph) if scene.camera else None
    if image is None or camera is None or not others:
        return
    projection = bounds.camera_projection(scene, camera)
    found = projection.intrinsics(*projection.plate_scale(source.shape))
    if found is None:  # orthographic: no single centre of projection to place them from
        return
    env = images.read_pixels(image)[..., :3].copy()
    h, w = env.shape[:2]
    if w != 2 * h:  # not a lat-long map
        return
    to_camera = projection.world_to_camera
    starts, world = _reflected_rays(obj, depsgraph, to_camera, h, w)
    nearest, which = _first_hits(starts, world, list(others), depsgraph)
    rows, cols = np.nonzero(which >= 0)
    if not len(rows):
        return
    points = starts[rows, cols] + nearest[rows, cols, None] * world[rows, cols]
    masks = list(others.values())
    Y, X, seen = _seen(points, to_camera, found, source.shape[:2], masks, which[rows, cols])
    env[rows[seen], cols[seen]] = source[Y[seen], X[seen]]
    maps.store_map(image.name, env, maps.save_folder(scene.virtual_reflections))


def _reflected_rays(obj, depsgraph, to_camera, h, w):
    """(starts, directions), each (h, w, 3) in world space: each texel's direction d of an
    (h, w) lat-long map, turned to the world by the camera's rotation (``to_camera``: world
    to camera, 4x4), and the point of ``obj``'s bounding sphere that reflects d toward the
    camera."""
    lo, hi = bounds.world_box(obj, depsgraph)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / (2 * np.sqrt(3))
    frame = latlong_directions(np.arange(w)[None, :] + 0.5, np.arange(h)[:, None] + 0.5, w)
    # camera frame -> Blender camera-local (x, y, z) = (-x, y, -z) -> world (rotation^T)
    world = (frame * (-1.0, 1.0, -1.0)) @ to_camera[:3, :3]
    eye = -to_camera[:3, :3].T @ to_camera[:3, 3]  # the camera's position
    back = (eye - centre) / max(float(np.linalg.norm(eye - centre)), 1e-9)
    normal = world + back  # the normal that reflects the view ray into d
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-9)
    return centre + radius * normal, world


def _first_hits(starts, world, others, depsgraph):
    """(distance, which): along each ray (``starts`` + t ``world``) the nearest of the
    ``others`` objects it meets (each an ellipsoid filling its own bounding box): t (inf:
    none) and its index in ``others`` (-1: none)."""
    nearest = np.full(starts.shape[:2], np.inf)
    which = np.full(starts.shape[:2], -1)
    for k, other in enumerate(others):
        evaluated = other.evaluated_get(depsgraph)
        box = np.array(evaluated.bound_box, dtype=np.float64)
        middle, half = (
            (box.min(0) + box.max(0)) / 2,
            np.maximum((box.max(0) - box.min(0)) / 2, 1e-6),
        )
        inverse = np.linalg.inv(np.array(evaluated.matrix_world, dtype=np.float64))
        origin = (starts @ inverse[:3, :3].T + inverse[:3, 3] - middle) / half
        step = (world @ inverse[:3, :3].T) / half
        c = np.einsum("ijk,ijk->ij", origin, origin) - 1.0
        a = np.einsum("ijk,ijk->ij", step, step)
        b = 2.0 * np.einsum("ijk,ijk->ij", step, origin)
        disc = b * b - 4.0 * a * c
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a)
        # c <= 0: the start inside the other's ellipsoid (overlapping boxes): not placed
        hit = (c > 0.0) & (disc >= 0.0) & (t > 0.0) & (t < nearest)
        nearest[hit], which[hit] = t[hit], k
    return nearest, which


def _seen(points, to_camera, intrinsics, shape, masks, which):
    """(rows, columns, seen) of world ``points`` in a plate of ``shape`` (H, W) through the
    camera (``intrinsics``: fx, fy, cx, cy in plate pixels): seen where the point is in front
    of the camera, in the frame and on the index mask (``masks[which]``, at the render's size)
    of the object it lies on."""
    fx, fy, cx, cy = intrinsics
    local = points @ to_camera[:3, :3].T + to_camera[:3, 3]
    depth = -local[:, 2]
    H, W = shape
    front = depth > 1e-6
    px = np.where(front, cx + fx * local[:, 0] / np.where(front, depth, 1.0), -1.0)
    py = np.where(front, cy - fy * local[:, 1] / np.where(front, depth, 1.0), -1.0)
    inside = front & (px >= 0) & (px < W) & (py >= 0) & (py < H)
    mh, mw = masks[0].shape
    X, Y = np.clip(px, 0, W - 1).astype(int), np.clip(py, 0, H - 1).astype(int)
    seen = np.zeros(len(points), bool)
    for k, mask in enumerate(masks):
        mine = inside & (which == k)
        seen[mine] = mask[Y[mine] * mh // H, X[mine] * mw // W]
    return Y, X, seen


# --- the render and its files -------------------------------------------------------------------


@contextlib.contextmanager
def _render_state(scene, layer, path, objects):
    """Set the scene up for the passes and restore it afterwards; yields {object: index}.

    Each object gets a pass index no other object of the scene uses.
    """
    render, fmt = scene.render, scene.render.image_settings
    changes = [
        (render, "filepath", path),
        (render, "use_border", False),
        (render, "border_min_x", 0.0),
        (render, "border_max_x", 1.0),
        (render, "border_min_y", 0.0),
        (render, "border_max_y", 1.0),
        (render, "use_crop_to_border", False),
        (render, "use_compositing", False),  # composited here, over the plate
        (render, "use_sequencer", False),
        (render, "film_transparent", True),
        (render, "use_persistent_data", False),  # 4.5 would keep the previous maps
        (layer, "use_pass_object_index", True),
    ]
    # Update Every Frame rebuilds the maps from the plate when a render changes the frame.
    changes.append((scene.virtual_reflections, "sequence", False))
    if hasattr(fmt, "media_type"):  # 5.x: multilayer is a media type; set before the format
        changes.append((fmt, "media_type", "MULTI_LAYER_IMAGE"))
    changes += [
        (fmt, "file_format", "OPEN_EXR_MULTILAYER"),
        (fmt, "color_mode", "RGBA"),
        (fmt, "color_depth", "32"),
        (fmt, "exr_codec", "NONE"),  # a temporary file: fastest to write and read
    ]
    ours = set(objects)
    taken = {o.pass_index for o in scene.objects if o not in ours}
    free = (i for i in range(1, 32768) if i not in taken)
    ids = {obj: next(free) for obj in objects}
    changes += [(obj, "pass_index", i) for obj, i in ids.items()]
    saved = [(owner, attr, getattr(owner, attr)) for owner, attr, _ in changes]
    try:
        for owner, attr, value in changes:
            setattr(owner, attr, value)
        yield ids
    finally:
        for owner, attr, value in saved:  # in the order set: the media type before the format
            setattr(owner, attr, value)


def _set_border(render, box, size):
    """Render only ``box`` (render pixels, y down) and a margin; Blender's border is 0..1,
    y up."""
    (h, w), (x0, y0, x1, y1) = size, box
    render.border_min_x = max(x0 - BORDER_PAD, 0) / w
    render.border_max_x = min(x1 + BORDER_PAD, w) / w
    render.border_min_y = 1.0 - min(y1 + BORDER_PAD, h) / h
    render.border_max_y = 1.0 - max(y0 - BORDER_PAD, 0) / h
    render.use_border = True


def _read_render(scene, layer, path):
    """The render of the layer that the step before wrote as the multilayer EXR at ``path``
    (a `generate.Step` with ``render``: Blender's render job from the window, a blocking render
    otherwise); returns ((h, w, 4) float32 RGBA premultiplied, (h, w) int32 object index)."""
    if not os.path.isfile(path):
        raise ValueError("the render wrote no image: was it stopped?")
    channels = read_channels(path)
    os.remove(path)  # the next pass's render must not be mistaken for this one
    names = [f"{layer.name}.Combined.{c}" for c in "RGBA"]
    missing = [n for n in names if n not in channels]
    if missing:
        raise ValueError(f"the render has no {missing[0]} channel")
    found = [f"{layer.name}.{p}.X" for p in INDEX_PASSES if f"{layer.name}.{p}.X" in channels]
    index = channels[found[0]] if found else None
    if index is None:
        raise ValueError(
            f"{scene.render.engine} wrote no object index pass: inter-reflections need Cycles"
        )
    rgba = np.stack([channels[n] for n in names], axis=-1)
    return rgba, np.rint(index).astype(np.int32)


# --- pixels ------------------------------------------------------------------------------------


def _grow(mask, pixels):
    """(h, w) bool mask grown by ``pixels`` in every direction (square dilation)."""
    out = mask.copy()
    for _ in range(pixels):
        rows = out.copy()
        rows[1:] |= out[:-1]
        rows[:-1] |= out[1:]
        out = rows.copy()
        out[:, 1:] |= rows[:, :-1]
        out[:, :-1] |= rows[:, 1:]
    return out


def _change(a, b, where):
    """Mean |a - b| over the pixels ``where`` and the channels; 0 when ``where`` is empty."""
    if not where.any():
        return 0.0
    return float(np.abs(a[where] - b[where]).mean())


def _border(objects, coverage, plate_shape, render_size):
    """The render pixels (x0, y0, x1, y1) that later passes re-render: the objects' screen
    boxes (as Generate stored them, in plate pixels) and their masks (``coverage``, (h, w)
    bool), grown by REGION_PAD (pixel filter, mask growth) and cut to the frame."""
    (h, w), (H, W) = render_size, plate_shape[:2]
    boxes = [tuple(obj.virtual_reflections.bounds) for obj in objects]
    x0, x1 = min(b[0] for b in boxes) * w / W, max(b[2] for b in boxes) * w / W
    y0, y1 = min(b[1] for b in boxes) * h / H, max(b[3] for b in boxes) * h / H
    rows, cols = np.nonzero(coverage.any(1))[0], np.nonzero(coverage.any(0))[0]
    if len(rows):
        x0, x1 = min(x0, cols[0]), max(x1, cols[-1] + 1)
        y0, y1 = min(y0, rows[0]), max(y1, rows[-1] + 1)
    return (
        min(max(math.floor(x0) - REGION_PAD, 0), w),
        min(max(math.floor(y0) - REGION_PAD, 0), h),
        min(max(math.ceil(x1) + REGION_PAD, 0), w),
        min(max(math.ceil(y1) + REGION_PAD, 0), h),
    )
