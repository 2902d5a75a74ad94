"""The batch's steps on one scene (shot.py's one frame and ranges.py's share them):
the command line's settings on the scene, the objects that reflect, the plate file's checks,
the output folder, a render read back as arrays, and an image written whole through Blender.

Images are written through Blender (save_render with the scene's colour management), so no
extra Python package is needed inside Blender; every output goes to a temporary file, is read
back whole (`atomic_files.commit`) and only then renamed over the previous file.
"""

import json
import os
import tempfile
import time

import bpy
import numpy as np

from ...virtual_reflections.atomic_files import (
    ImageError,
    commit,
    held_stderr,
    same_file,
    temp_path,
)
from ...virtual_reflections.imagefiles import (
    HALF_MAX,
    check_complete,
    plain_rgb_command,
    read_channels,
    read_header,
    read_rgba,
)
from ...virtual_reflections.memory import check_fits, plate_job_bytes, render_job_bytes
from .. import compositor, sequence
from ..node_trees import shading, world_probe
from ..scene import floor, maps, plate
from .options import BatchOptions
from .signals import raise_if_signalled


class BatchError(RuntimeError):
    """A frame failed after the run started writing (a render error, a full disk): exit code
    1, worth another try, unlike bad input (2). The frames written so far are complete."""

    exit_code = 1


ENGINES = {"CYCLES": ("CYCLES",), "EEVEE": ("BLENDER_EEVEE_NEXT", "BLENDER_EEVEE")}


def _set_engine(scene, name):
    """Cycles is an add-on engine, so it is missing from the built-in enum: just try the ids."""
    for ident in ENGINES[name]:
        try:
            scene.render.engine = ident
            return
        except TypeError:
            continue
    raise ValueError(f"render engine {name} is not available in this Blender")


def configure(scene, options: BatchOptions):
    """The render and reflection settings from the command line (both paths). Maps saved as
    files go under --out (OUT/vr_maps/<name>/), never beside the shot."""
    settings = scene.virtual_reflections
    out = os.path.abspath(options.out)
    maps.save_under(scene, os.path.join(out, "vr_maps", shot_name(options)))
    if options.scale:
        scene.render.resolution_percentage = options.scale
    if options.combine is not None:
        settings.combine = options.combine
    if options.resolution is not None:
        settings.resolution = str(options.resolution)
    if options.method:
        settings.method = options.method.upper()
    if options.ground_object:
        ground = scene.objects.get(options.ground_object)
        if ground is None:
            raise ValueError(
                f"--ground-object: no object named {options.ground_object!r} in scene "
                f"{scene.name!r}"
            )
        settings.ground_object = ground
    if options.surroundings:
        settings.surroundings = options.surroundings.upper()
    if options.contact_shadow is not None:
        settings.contact_shadow = options.contact_shadow
    if options.sky_texture is not None:
        settings.sky_texture = options.sky_texture
    if options.sky_brightness is not None:  # the artist's own sky: Surroundings Custom
        settings.surroundings = "CUSTOM"
        settings.sky_brightness = options.sky_brightness
    if options.sky_tint is not None:
        settings.surroundings = "CUSTOM"
        settings.sky_tint = options.sky_tint
    if options.surroundings == "world":  # asked for by name: a world it cannot read is an error
        try:
            world_probe.environment_node(world_probe.user_world(scene))
        except ValueError as exc:
            reason = str(exc).removeprefix("Surroundings World HDRI: ")
            raise ValueError(f"--surroundings world: {reason}") from None
    if options.triangles is not None:
        settings.front = "CONTINUOUS" if options.triangles == 0 else "TRIANGLES"
        settings.triangles = max(4, options.triangles)
    if options.smoothing is not None:
        settings.smoothing = options.smoothing
    if options.engine:
        _set_engine(scene, options.engine)
    if options.samples and scene.render.engine == "CYCLES":
        scene.cycles.samples = options.samples
    elif options.samples:
        for attr in ("taa_render_samples",):
            if hasattr(scene.eevee, attr):
                setattr(scene.eevee, attr, options.samples)


def shot_objects(scene, names):
    if names:
        missing = [n for n in names if n not in scene.objects]
        if missing:
            raise ValueError(f"no object named {missing[0]!r} in scene {scene.name!r}")
        return [scene.objects[n] for n in names]
    marked = [
        o for o in scene.objects if o.type in shading.REFLECTABLE and o.virtual_reflections.enabled
    ]
    if marked:
        return marked
    visible = [o for o in scene.objects if o.type in shading.REFLECTABLE and o.visible_get()]
    ground = floor.grounds_among(scene, bpy.context.evaluated_depsgraph_get(), visible)
    return [o for o in visible if o not in ground]  # the shadow catcher, the floor: not mirrors


def check_plate_file(path, what="plate"):
    """A plate file as the batch reads it (through Blender): refuse, one line, what Blender
    would misread (an EXR whose data window is not its display window: Blender reads the
    data window, so the bounds would land elsewhere), what cannot fit in memory, and what
    is not a picture. Returns its PlateHeader."""
    if os.path.isdir(path):
        raise ValueError(f"{what} is a folder, not an image file: {path}")
    if not os.path.isfile(path):
        raise ValueError(f"plate not found: {path}")
    try:
        header = read_header(path)
    except ImageError as exc:
        raise ValueError(f"{what}: {exc}") from exc
    if header.layers:
        raise ValueError(
            f"{what} {path} has layers ({', '.join(header.layers)}): Blender reads such an EXR "
            "as render passes, not a picture; save its colour as a plain R, G, B file first "
            f"(e.g. {plain_rgb_command(path, header.channels, header.colour)})"
        )
    check_fits(
        plate_job_bytes(
            header.width, header.height, 4096 * 2048, stored_pixels=header.stored_pixels
        ),
        f"the {header.width}x{header.height} plate {path}{header.stored_note}",
    )
    if header.data != (0, 0, header.width, header.height):
        x, y, w, h = header.data
        raise ValueError(
            f"{what} {path}: its data window ({w}x{h} at {x},{y}) is not its display window "
            f"({header.width}x{header.height}); crop or pad it to the display window first "
            "(e.g. oiiotool IN --fullpixels -o OUT)"
        )
    return header


def load_plate(path):
    check_plate_file(path)
    check_complete(path, "plate")
    image = bpy.data.images.load(os.path.abspath(path), check_existing=True)
    plate.image_pixels(image)  # raises a clear ValueError for unreadable plates
    return image


def shot_name(options: BatchOptions):
    return options.name or os.path.splitext(os.path.basename(bpy.data.filepath or "shot"))[0]


def render_size(scene):
    """The render's (w, h) in pixels; ValueError (one line) when under one pixel,
    MemoryLimitError (one line, exit 1) when its render cannot fit in memory (a render that
    runs out of it aborts the process without a word)."""
    percent = scene.render.resolution_percentage
    size = (
        scene.render.resolution_x * percent // 100,
        scene.render.resolution_y * percent // 100,
    )
    if min(size) < 1:
        raise ValueError(
            f"the render would be {size[0]}x{size[1]} pixels "
            f"({scene.render.resolution_x}x{scene.render.resolution_y} at {percent}%): "
            "under one pixel; raise --scale"
        )
    check_fits(
        render_job_bytes(*size, render_passes(scene), scene.render.use_compositing),
        f"the {size[0]}x{size[1]} render ({scene.render.resolution_x}x"
        f"{scene.render.resolution_y} at {percent}%, lower --scale)",
    )
    return size


def render_passes(scene):
    """How many render passes a render of ``scene`` holds: each view layer's (Combined, the
    enabled passes, Cycles' own, AOVs), at least one."""
    count = 0
    for layer in (v for v in scene.view_layers if v.use):
        for owner in (layer, getattr(layer, "cycles", None)):
            if owner is not None:
                count += sum(
                    1
                    for key in dir(owner)
                    if key.startswith("use_pass_") and getattr(owner, key, False) is True
                )
        count += len(getattr(layer, "aovs", ()))
    return max(1, count)


def not_a_plate(outputs, plates):
    """ValueError (one line) when an output would replace a plate file."""
    for output in outputs:
        for plate_file in plates:
            if same_file(output, plate_file):
                raise ValueError(
                    f"output {output} is the plate itself: choose another --out or --name"
                )


def check_folder(out):
    """Create the output folder and check that files can be made in it (ValueError if not)."""
    try:
        os.makedirs(out, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".vr-probe-", dir=out)
        os.close(fd)
        os.remove(probe)
    except OSError as exc:
        raise ValueError(f"output folder not writable: {out} ({exc.strerror or exc})") from exc


def render_settings(scene, use_compositor=False):
    """A transparent RGBA float EXR of the render; the composite is made in NumPy, the same
    in 4.5 and 5.x, unless the shot has its own compositor (``use_compositor``): then it
    runs (over the plate, as compositor.setup_from_plate set it up) and the render is a
    multilayer EXR holding both the view layer and the compositor's result."""
    scene.render.use_compositing = use_compositor
    scene.render.film_transparent = True
    sequence.keep_maps_fresh(scene.render)  # 4.5 would render the first frame's maps
    settings_img = scene.render.image_settings
    if use_compositor:
        if hasattr(settings_img, "media_type"):  # 5.x: multilayer is a media type
            settings_img.media_type = "MULTI_LAYER_IMAGE"
        settings_img.file_format = "OPEN_EXR_MULTILAYER"
    else:
        if hasattr(settings_img, "media_type"):
            settings_img.media_type = "IMAGE"
        settings_img.file_format = "OPEN_EXR"
    settings_img.color_mode = "RGBA"
    settings_img.color_depth = "32"


def render_rgba(scene, temp, use_compositor=False):
    """Render the scene into the EXR ``temp`` and read it back: ((h, w, 4) float32 RGBA of the
    render, (h, w, 3) float32 result of the shot's own compositor or None, seconds of the
    render call). Blender's own error lines are held back (the tool says it); a signal
    received during the render is raised once it returns."""
    scene.render.filepath = temp
    with held_stderr():
        started = time.perf_counter()
        bpy.ops.render.render(write_still=True, scene=scene.name)
        seconds = time.perf_counter() - started
        raise_if_signalled()
        if not use_compositor:
            return read_rgba(temp), None, seconds
        channels = read_channels(temp)
    layer = next((v.name for v in scene.view_layers if v.use), scene.view_layers[0].name)
    try:
        rgba = np.stack([channels[f"{layer}.Combined.{c}"] for c in "RGBA"], axis=-1)
        comp = np.stack([channels[f"Composite.Combined.{c}"] for c in "RGB"], axis=-1)
    except KeyError as exc:
        raise ImageError(f"the render has no {exc.args[0]} channel") from exc
    return rgba.astype(np.float32), comp.astype(np.float32), seconds


def artist_compositor(scene):
    """What the shot's own compositor is, in a few words, when it has one beyond the plate
    set-up (`compositor.setup_from_plate` keeps it under the plate: 4.5 in the scene's tree,
    5.x nested in the "VR Composite" group); None when it has none or had compositing off."""
    plain = {"R_LAYERS", "COMPOSITE", "VIEWER", "GROUP_OUTPUT", "GROUP_INPUT", "FRAME", "REROUTE"}
    try:
        record = json.loads(scene.get(compositor.RECORD, "{}"))
    except ValueError:
        record = {}
    setup = record.get("compositor") or {}
    if record.get("use_compositing") is False or setup.get("use_nodes") is False:
        return None  # the artist had compositing off: theirs is not the shot's look
    if setup.get("previous_group"):
        tree = bpy.data.node_groups.get(setup["previous_group"])
    elif not setup.get("group"):
        tree = getattr(scene, "node_tree", None)  # 4.5: the scene's own tree
    else:
        tree = None
    if tree is None:
        return None
    own = sorted(n.name for n in tree.nodes if n.type not in plain and not n.name.startswith("VR "))
    return f"{tree.name}: {', '.join(own)}" if own else None


def write_image(scene, pixels_rgb, path, fmt):
    """Save (H, W, 3) linear pixels through Blender (EXR linear half floats, clamped to
    +-65504; PNG with the scene's view), atomically: a temporary file, read back whole, then
    renamed. WriteError (exit 1) if it cannot be written whole; ``path`` is then untouched."""
    h, w = pixels_rgb.shape[:2]
    temp = temp_path(path)
    try:
        with held_stderr():
            _save_through_blender(scene, pixels_rgb, temp, fmt)
        commit(temp, path, w, h)
    finally:
        if os.path.exists(temp):
            os.remove(temp)


def _save_through_blender(scene, pixels_rgb, path, fmt):
    h, w = pixels_rgb.shape[:2]
    image = bpy.data.images.new("VR batch output", w, h, alpha=False, float_buffer=True)
    try:
        rgba = np.ones((h, w, 4), np.float32)
        rgba[..., :3] = pixels_rgb[::-1]
        if fmt == "OPEN_EXR":
            np.clip(rgba, -HALF_MAX, HALF_MAX, out=rgba)  # a sun stays finite in half floats
        image.pixels.foreach_set(rgba.ravel())
        settings = scene.render.image_settings
        keys = ("media_type",) if hasattr(settings, "media_type") else ()  # 5.x: first
        keys += ("file_format", "color_mode", "color_depth")
        previous = {key: getattr(settings, key) for key in keys}
        if keys[0] == "media_type":
            settings.media_type = "IMAGE"
        settings.file_format = fmt
        settings.color_mode = "RGB"
        settings.color_depth = "16" if fmt == "OPEN_EXR" else "8"
        try:
            image.save_render(path, scene=scene)
        finally:
            for key in keys:
                setattr(settings, key, previous[key])
    finally:
        bpy.data.images.remove(image)
