"""The map pipeline: the one way every feature turns the plate into an object's map.

    the camera (bounds.camera_projection) -> plate scale and the method's Params (`view`)
      -> each object's screen box in plate pixels (`object_boxes`) -> their union per map
      -> the map's width (choices.map_width) -> the engine's cached lookup table and one
         gather (`build_map`) -> (H, W, 3) float32 scene-linear map pixels

Each caller keeps only what differs: Generate stores the map and attaches it (generate.py),
Update Every Frame smooths the boxes over frames and writes in place (sequence.py), Live
Update builds a reduced map while the object moves (live.py), the inter-reflection passes
build from the previous composite (interreflect.py).
"""

import contextlib
import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..virtual_reflections import Params, lookup_table, methods
from ..virtual_reflections.envmap import apply_table, prior_parts
from ..virtual_reflections.fill import sky_in_view
from ..virtual_reflections.ggx_lobe import dominant_shift
from ..virtual_reflections.params import sky_prior_for, sky_texture_for
from ..virtual_reflections.prefilter import SHARP, prefilter_latlong
from ..virtual_reflections.probe import with_probe
from .node_trees import shading, world_probe
from .node_trees.ground_nodes import GroundLookup
from .scene import bounds, plate
from .scene.composite import scale_box
from .scene.floor import ground_height, objects_box, objects_centre

LARGE_SHARE = 0.4  # an object covering more of the plate leaves little to reflect
SHADED_GROUND = methods.PER_OBJECT_LOOKS  # looks whose material reads the ground itself
SHARP_GROUND = 0.1  # roughness under which the ground is read per shading point (sharp)
ALL_FRAMES = 1048574  # Blender's longest frame range: an image user mapping frame n to n


@dataclass
class Report:
    """What a run did, for the operator's report, the panel and the batch log.

    done: names of what was made (objects, or maps); warnings: one line each; timings: stage
    -> seconds, summed over objects; plate: what was read as the plate; tables: lookup tables
    built / reused from the engine's cache.
    """

    done: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    plate: str = ""
    tables: dict = field(default_factory=lambda: {"built": 0, "reused": 0})

    def time(self, stage, seconds):
        self.timings[stage] = self.timings.get(stage, 0.0) + seconds

    @contextlib.contextmanager
    def timed(self, stage):
        """Add the time spent inside the block to ``stage``."""
        started = time.perf_counter()
        try:
            yield
        finally:
            self.time(stage, time.perf_counter() - started)

    def summary(self):
        stages = ", ".join(f"{k} {1000 * v:.0f} ms" for k, v in self.timings.items())
        total = 1000 * sum(self.timings.values())
        return f"{len(self.done)} reflection(s) in {total:.0f} ms ({stages})"

    def outcome(self):
        """The plain line for the status bar: who reflects now (no timings: `summary`)."""
        if len(self.done) == 1:
            return f"{self.done[0]} reflects the plate"
        return f"{len(self.done)} objects reflect the plate"


MIN_HEIGHT = 1e-3  # scene units: an object's centre at least this far above the ground


def params(settings, intrinsics=None) -> Params:
    """The engine's Params for a scene's settings. ``intrinsics`` (fx, fy, cx, cy) in plate
    pixels select the camera-view method when Camera View or Camera View + Ground is chosen
    (the ground is added per map: `map_params`); without them (an orthographic camera, the
    segmentation previews) it is the paper's. The sky prior's gain (used by Camera View +
    Ground) is the one for the surroundings the artist named (``settings.surroundings``), its
    texture the artist's Sky Texture."""
    n = 0 if settings.front == "CONTINUOUS" else 4 * max(1, round(settings.triangles / 4))
    method = methods.view_method(settings.method, perspective=intrinsics is not None)
    camera = methods.uses_camera(method)
    return Params(
        enlarge=settings.enlarge / 100.0,
        border=settings.border / 100.0,
        triangles=n,
        method=method,
        intrinsics=tuple(intrinsics) if camera else None,
        **scene_sky_prior(settings),
        sky_tint=scene_sky_tint(settings),
        sky_texture=scene_sky_texture(settings),
    )


def scene_sky_prior(settings, roughness: float = 0.0) -> dict:
    """The sky prior the scene's ``settings`` ask for, seen by a surface of ``roughness``
    (params.sky_prior_for: Params' sky_gain, sky_source and sky_tint_share): the named
    Surroundings', or with Custom the artist's Sky Brightness."""
    kind = settings.surroundings.lower()
    custom = settings.sky_brightness if kind == "custom" else None
    return sky_prior_for(kind, roughness, custom)


def contact_shadow(settings) -> float:
    """The contact shadow's strength the scene's ``settings`` ask for (0..1), rounded so that
    a slider's float noise builds no new table or node tree."""
    return round(float(settings.contact_shadow), 4)


def scene_sky_texture(settings) -> float:
    """How much of the plate's own texture the unseen sky takes (Params.sky_texture, 0..1)
    the scene's ``settings`` ask for, rounded so that a slider's float noise builds no new
    table. Under World HDRI the on-set HDRI replaces the textured sky where it can be read."""
    return round(float(settings.sky_texture), 4)


def scene_sky_tint(settings) -> tuple:
    """The sky prior's colour the scene's ``settings`` ask for (Params.sky_tint): with
    Surroundings Custom the artist's Sky Tint (a black one is taken as neutral), else neutral."""
    tint = tuple(round(float(v), 4) for v in settings.sky_tint)
    if settings.surroundings != "CUSTOM" or max(tint) <= 0:
        return (1.0, 1.0, 1.0)
    return tint


@dataclass(frozen=True)
class View:
    """The camera and the plate at one moment: how render pixels map to plate pixels.

    projection: the render camera (bounds.CameraProjection); scale: (sx, sy) render -> plate
    pixels; params: the engine's Params for the scene's settings and this camera; plate_shape:
    (H, W) of the plate.
    """

    projection: bounds.CameraProjection
    scale: tuple
    params: Params
    plate_shape: tuple

    def warnings(self, settings) -> list:
        """Advice about the set-up: no camera view method for an orthographic camera, a plate
        whose aspect differs from the render's."""
        out = []
        if methods.uses_camera(settings.method) and self.params.intrinsics is None:
            out.append(
                "orthographic camera: the camera-view method needs a perspective camera; "
                "used the paper's method"
            )
        sx, sy = self.scale
        if abs(sx - sy) > 0.01 * max(sx, sy):
            ph, pw = self.plate_shape
            out.append(
                f"plate {pw}x{ph} and render {self.projection.width}x{self.projection.height} "
                "differ in aspect: use Set Up From Plate"
            )
        return out


def view(scene, plate_shape, depsgraph=None) -> View:
    """The View of ``scene``'s camera for a plate of ``plate_shape`` (H, W, ...). With a
    ``depsgraph``, the camera as evaluated there (during a render the original objects still
    hold the frame the viewport showed before). ValueError without a usable camera."""
    camera = scene.camera
    if camera is not None and depsgraph is not None:
        camera = camera.evaluated_get(depsgraph)
    projection = bounds.camera_projection(scene, camera)
    sx, sy = projection.plate_scale(plate_shape)
    shape = tuple(plate_shape[:2])
    return View(
        projection,
        (sx, sy),
        params(scene.virtual_reflections, projection.intrinsics(sx, sy)),
        shape,
    )


def camera_sky(scene) -> float | None:
    """The share of the camera's frame rows that reach above the world's horizon (engine
    fill.sky_in_view): 0 when the camera sees no sky, so Camera View + Ground's sky is its
    prior alone and naming the Surroundings matters most. None without a usable perspective
    camera."""
    try:
        projection = bounds.camera_projection(scene)
    except ValueError:
        return None
    intrinsics = projection.intrinsics(1.0, 1.0)
    if intrinsics is None:
        return None
    up = bounds.to_engine_frame(projection, vector=(0.0, 0.0, 1.0))
    return sky_in_view(intrinsics, projection.width, projection.height, up)


@dataclass(frozen=True)
class ReflectRequest:
    """One map to build and where it goes, decided once per run (`reflect_request`).

    name: the map's label in the steps and the warnings ("World" or the object's name);
    obj: the object the map is for, None for the World look's one map of every object;
    box: the objects' box in plate pixels (their union); width: the lat-long map's width;
    roughness: the roughness the map is pre-filtered for (`map_roughness`, 0: sharp);
    params: the engine's Params of the map (`map_params`); ground: what the material needs to
    read the ground per shading point (`ground_lookup`, None: it does not);
    shift: where it reads the pre-filtered map (`lobe_shift`, None: the mirror direction).
    """

    name: str
    obj: object | None
    box: tuple
    width: int
    roughness: float
    params: Params
    ground: GroundLookup | None = None
    shift: tuple | None = None


def reflect_request(
    view, scene, depsgraph, objects, box, width, *, obj=None, image=None, centre=None
) -> ReflectRequest:
    """The ReflectRequest of the map ``objects`` share (``obj``: the one object it is for),
    of ``box`` (plate pixels) and ``width``: their roughness taken and the floor under them
    searched once, here, for the Params, the per-point ground on the plate ``image`` (when
    given) and the lobe's shift. ``centre``: their centre smoothed over frames (Update Every
    Frame), else the centre of their bounding box."""
    settings = scene.virtual_reflections
    roughness = map_roughness(settings, objects)
    found = _floor(view, scene, depsgraph, objects, centre)
    ground = None
    if image is not None and per_point_ground(settings, roughness):
        ground = ground_lookup(view, scene, image, found)
    return ReflectRequest(
        name="World" if obj is None else obj.name,
        obj=obj,
        box=box,
        width=width,
        roughness=roughness,
        params=map_params(view, settings, depsgraph, objects, found, roughness),
        ground=ground,
        shift=lobe_shift(roughness),
    )


def _floor(view, scene, depsgraph, objects, centre=None):
    """(the ground's world height, the objects' world centre) when Camera View + Ground applies
    to ``objects``, else None: another method, no perspective camera, the centre not above
    the ground, or a "ground" at or above the camera (the objects stand on a column or a table
    above it: no ground the plate could show)."""
    settings = scene.virtual_reflections
    if not methods.reads_ground(settings.method) or view.params.method != "camera" or not objects:
        return None
    centre = objects_centre(depsgraph, objects) if centre is None else np.asarray(centre)
    floor = ground_height(scene, depsgraph, objects)
    camera_z = float(np.linalg.inv(view.projection.world_to_camera)[2, 3])
    if float(centre[2]) - floor < MIN_HEIGHT or camera_z <= floor + MIN_HEIGHT:
        return None
    return floor, centre


def map_roughness(settings, objects) -> float:
    """The roughness the map of ``objects`` is pre-filtered for: in the Mix look (Glossy: the
    map over the material's own surface) the roughest object's surface (shading.roughness);
    0 in the others: Replace and Modulate are the paper's mirror modes (chrome, car paint),
    and in the World look the renderer's own BSDF blurs the world."""
    if settings.combine != "MIX":
        return 0.0
    return max((shading.roughness(o) for o in objects), default=0.0)


def sky_roughness(settings, objects, roughness) -> float:
    """The roughness whose view of the unseen sky the map of ``objects`` holds
    (params.sky_prior_for): in the Mix look the ``roughness`` it is pre-filtered for
    (`map_roughness`); in the World look the smoothest object's surface — the renderer's own
    BSDF blurs the world, and a rough surface's lobe gathers a light's energy that a mirror
    rarely meets, so a world for rough surfaces only holds the brighter sky they see (a mirror
    among them keeps the mirror's); 0 in Replace and Modulate, the mirror modes."""
    if settings.combine == "WORLD":
        return min((shading.roughness(o) for o in objects), default=0.0)
    return roughness


def lobe_shift(roughness) -> tuple | None:
    """Where a material reads a map pre-filtered for ``roughness`` (`map_roughness`): the
    lobe's centre, ggx_lobe.dominant_shift (None: the mirror direction, for a map that is not
    pre-filtered)."""
    return dominant_shift(round(roughness, 4)) if roughness > SHARP else None


def per_point_ground(settings, roughness) -> bool:
    """Whether the materials read the ground per shading point: the Replace, Modulate and Mix
    looks of sharp surfaces (a rough one's map holds the ground seen from its centre, blurred
    by its ``roughness``, where a sharp lookup per point would not be)."""
    return settings.combine in SHADED_GROUND and roughness < SHARP_GROUND


def map_params(view, settings, depsgraph, objects, found, roughness) -> Params:
    """The Params of the map ``objects`` share: the view's, and with Camera View + Ground
    (``found``: `_floor`'s ground height and centre) the world's horizon and (in the World
    look) the ground plane seen from their centre (engine ground.py). In the Replace, Modulate
    and Mix looks the material reads the ground per shading point (`ground_lookup`), so their
    map is the camera view with the world's horizon, one table for every pose. The view's (the
    distant camera view) when the ground does not apply (``found`` None)."""
    if found is None:
        return view.params
    floor, centre = found
    up = tuple(round(v, 4) for v in bounds.to_engine_frame(view.projection, vector=(0, 0, 1)))
    # A rough surface sees a brighter sky (`sky_roughness`), without the plate's texture.
    seen_by = sky_roughness(settings, objects, roughness)
    prior = scene_sky_prior(settings, seen_by)
    prior["sky_texture"] = sky_texture_for(scene_sky_texture(settings), seen_by)
    if per_point_ground(settings, roughness):
        return dataclasses.replace(view.params, up=up, **prior)
    origin = bounds.to_engine_frame(view.projection, point=centre)
    # Rounded to a quarter of a plate pixel at the object's depth (and up to 1e-4), as the
    # boxes are rounded to whole pixels: a pose seen before finds its cached table, and a
    # jitter that moves the object by less than a pixel does not rebuild the map.
    step = 0.25 * max(origin[2], 1e-3) / view.params.intrinsics[0]
    low, high = objects_box(depsgraph, objects)
    height = float(centre[2]) - floor
    radius = min(0.5 * float(high[2] - low[2]), height)  # their contact shadow's sphere
    ground = tuple(round(v / step) * step for v in (*origin, height, radius))
    shadow = contact_shadow(settings)
    return dataclasses.replace(
        view.params, method="ground", ground=(*ground, shadow), up=up, **prior
    )


def ground_lookup(view, scene, image, found) -> GroundLookup | None:
    """What a Replace, Modulate or Mix material needs to read the ground its objects stand on
    (``found``: `_floor`'s ground height and centre) from the plate ``image`` per shading
    point (ground_nodes.py), or None when Camera View + Ground does not apply (``found``
    None)."""
    if found is None:
        return None
    fx, fy, cx, cy = view.params.intrinsics
    height, width = view.plate_shape
    frames = None
    if image.source in ("SEQUENCE", "MOVIE"):
        user = plate.background_user(scene, image)
        if user is not None and user.frame_duration > 0:
            frames = (user.frame_duration, user.frame_start, user.frame_offset, user.use_cyclic)
        else:
            frames = (ALL_FRAMES, 1, 0, False)  # the scene's frame n shows the plate's frame n
    return GroundLookup(
        image,
        found[0],
        (fx / width, fy / height),
        (cx / width, 1 - cy / height),
        width / height,
        frames,
        contact_shadow(scene.virtual_reflections),
    )


def object_boxes(view, scene, depsgraph, objects, outside="skipped", progress=None):
    """Each object's screen box in plate pixels -> ({object: (x0, y0, x1, y1)}, {object: extent
    in pixels of the full-size render}, [one-line problems]). Objects without geometry or
    outside the camera's view are left out and named in the problems ("<name> is outside the
    camera view: <outside>"). ``progress`` is called with the index of each object done.

    The extent is at Resolution 100 %: Auto sizes a map for the render it stays for, not for
    a preview at 50 % (nor for a 200 % one)."""
    boxes, extents, problems = {}, {}, []
    full_size = 100.0 / scene.render.resolution_percentage
    for i, obj in enumerate(objects):
        try:
            box = bounds.object_bounds(obj, depsgraph, scene, projection=view.projection)
        except ValueError as exc:
            problems.append(f"{obj.name}: {exc}")
            continue
        if not box.visible:
            problems.append(f"{obj.name} is outside the camera view: {outside}")
            continue
        boxes[obj] = scale_box((box.x0, box.y0, box.x1, box.y1), *view.scale)
        extents[obj] = box.extent() * full_size
        if progress:
            progress(i)
    return boxes, extents, problems


def scene_probe(scene, view, report):
    """The on-set HDRI for the unseen surroundings when the artist named the world's
    (Surroundings: World HDRI, Camera View + Ground), else None. A world that cannot be read
    is one line in the report's warnings, and the guessed sky (Auto) stands in."""
    settings = scene.virtual_reflections
    if not methods.takes_world_hdri(settings.method, settings.surroundings):
        return None
    if view.params.intrinsics is None:
        return None
    try:
        return world_probe.world_probe(scene, view.projection)
    except ValueError as exc:
        report.warnings.append(f"{exc}: used Auto")
        return None


def build_map(
    pixels, box, map_params, width, report, name=None, roughness=0.0, pyramids=None, probe=None
):
    """The lat-long map of ``box`` (plate pixels) on ``pixels`` ((H, W, 3) float32 linear):
    -> ((width / 2, width, 3) float32 scene-linear map, the engine's LookupTable): `map_table`
    then `gather`."""
    table = map_table(pixels.shape, box, map_params, width, report, name)
    return gather(table, pixels, report, roughness, pyramids, probe), table


def map_table(plate_shape, box, map_params, width, report, name=None):
    """The engine's LookupTable of ``box`` (plate pixels) on a plate of ``plate_shape`` (H, W,
    ...), from the engine's cache when the plate size, box, params and width were seen before
    (counted in ``report.tables``). With a ``name``, the segmentation's advice goes into the
    report's warnings (`fit_warnings`). No bpy: may run off Blender's main thread."""
    h, w = plate_shape[:2]
    with report.timed("table"):
        misses = lookup_table.cache_info().misses
        table = lookup_table(w, h, tuple(float(v) for v in box), map_params, "latlong", width)
        report.tables["built" if lookup_table.cache_info().misses > misses else "reused"] += 1
    if name is not None:
        paper = methods.cuts_regions(map_params.method)
        report.warnings.extend(fit_warnings(name, table.segmentation, paper))
    return table


def gather(table, pixels, report, roughness=0.0, pyramids=None, probe=None):
    """(width / 2, width, 3) float32 map: one gather of ``pixels`` through ``table``, and a
    ``roughness`` over prefilter.SHARP pre-filters it for that (`map_roughness`).
    ``pyramids``: the plate's pyramids (a dict kept with the plate,
    `plate.PlateFrame.pyramids`), shared by every map of these pixels. ``probe`` (engine
    probe.Probe, `scene_probe`): the on-set HDRI in place of the guessed sky. No bpy."""
    with report.timed("gather"):
        parts = None if probe is None else prior_parts(table, pixels, pyramids)
        if parts is None:
            env = apply_table(table, pixels, pyramids)
        else:
            env = with_probe(*parts, probe.latlong(table.shape[1]))
    if roughness > 0:
        with report.timed("prefilter"):
            env = prefilter_latlong(env, roughness)
    return env


def fit_warnings(name, seg, paper=True) -> list:
    """Advice (not errors) for an object's segmentation: region X had to shrink below its
    bounds near a border (paper §3.2; only with the paper's method), or the object covers so
    much of the plate that little is left around it to reflect."""
    out = []
    if paper and seg.shrunk:
        out.append(
            f"{name} is so close to the plate's border that region X is smaller than its "
            "bounds: the reflection behind it is cropped"
        )
    b = seg.bbox
    w = min(b.x1, seg.width) - max(b.x0, 0.0)
    h = min(b.y1, seg.height) - max(b.y0, 0.0)
    share = max(w, 0.0) * max(h, 0.0) / (seg.width * seg.height)
    if share > LARGE_SHARE:
        out.append(
            f"{name} covers {share:.0%} of the plate: little is left around it to reflect "
            "(move the camera back or use a wider plate)"
        )
    return out
