"""The headless path behind render_shot.py: frames with reflections, and their composites.

One frame (`render_shot` without --frames and with a still plate) writes <name>_render.exr and
<name>_composite.png/.exr as it always did. A frame range (--frames, or a plate that is an
image sequence or a movie) goes through `render_frames`: per frame the plate of that frame,
the maps rebuilt with smoothed bounds (sequence.update, as Update Every Frame does), a render, the
composite <name>.<frame:04d>.<ext>, and the JSON report rewritten. Every file appears at once
(written under a temporary name in the output folder, then os.replace), frames already
complete are skipped (resume), and bad input is refused before anything is written.

Nothing a user had is lost (issue 14, docs/failures.md): every output, one frame or a range,
is written under this process's temporary name, read back whole (`imagefiles.commit`) and
only then renamed over the previous file; an output that would replace a plate is refused;
a run locks the outputs it writes (batch_lock.py), so a second run on the same frames is
refused instead of deleting the first's temporary files; a plate frame that cannot be read
whole fails its frame (exit 1, named in the report) instead of rendering half grey.

Rendering uses Blender's own renderer; the final composite (render over plate) is computed in
NumPy from the saved RGBA render, so it does not depend on the compositor's API, which differs
between Blender 4.5 and 5.x. Images are written through Blender (save_render with the scene's
colour management), so no extra Python package is needed inside Blender.
"""

import contextlib
import gc
import json
import os
import signal
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass

import bpy
import numpy as np

from ..virtual_reflections.composite import over, resize_nearest
from ..virtual_reflections.frames import is_movie_path, is_pattern, parse_frames, pattern_path
from ..virtual_reflections.imagefiles import (
    HALF_MAX,
    ImageError,
    check_complete,
    commit,
    held_stderr,
    read_channels,
    read_header,
    read_rgba,
    remove_stale_temps,
    same_file,
    temp_path,
    write_rgba,
)
from ..virtual_reflections.memory import check_fits, plate_job_bytes
from . import batch_record, compositor, generate, interreflect, plate, sequence, shading
from .batch_lock import OutputLock
from .batch_options import BatchOptions

ENGINES = {"CYCLES": ("CYCLES",), "EEVEE": ("BLENDER_EEVEE_NEXT", "BLENDER_EEVEE")}


# --- Ctrl-C and SIGTERM ---------------------------------------------------------------------------


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (exit code 130) or SIGTERM (143): the run stops where it is, its temporary
    files are removed on the way out, finished frames stay."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum
        self.exit_code = 143 if signum == signal.SIGTERM else 130


_signalled = []  # signals received while a run is on


def _on_signal(signum, frame):
    _signalled.append(signum)
    raise Interrupted(signum)


def _raise_if_signalled():
    """A signal that arrived during a render: Blender's render catches the exception the
    handler raised (and prints it), so raise it again here."""
    if _signalled:
        # Blender printed the exception the handler raised in the render engine and keeps it
        # (sys.last_*), with the engine's frame: let the engine go now, while stderr is held.
        for name in ("last_exc", "last_type", "last_value", "last_traceback"):
            if hasattr(sys, name):
                setattr(sys, name, None)
        gc.collect()
        raise Interrupted(_signalled[-1])


@contextlib.contextmanager
def stop_on_signals():
    """Ctrl-C and SIGTERM raise Interrupted while the block runs (main thread only)."""
    _signalled.clear()
    previous = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, _on_signal)
    except ValueError:  # not the main thread
        pass
    try:
        yield
    finally:
        for sig, handler in previous.items():
            if handler is not None:  # None: a handler set outside Python (Blender's)
                signal.signal(sig, handler)


def _set_engine(scene, name):
    """Cycles is an add-on engine, so it is missing from the built-in enum: just try the ids."""
    for ident in ENGINES[name]:
        try:
            scene.render.engine = ident
            return
        except TypeError:
            continue
    raise ValueError(f"render engine {name} is not available in this Blender")


def _objects(scene, names):
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
    return [o for o in scene.objects if o.type in shading.REFLECTABLE and o.visible_get()]


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
    check_fits(
        plate_job_bytes(header.width, header.height, 4096 * 2048),
        f"the {header.width}x{header.height} plate {path}",
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


def _save(scene, pixels_rgb, path, fmt):
    """Save (H, W, 3) linear pixels through Blender (EXR linear half floats, clamped to
    +-65504; PNG with the scene's view), atomically: a temporary file, read back whole, then
    renamed. WriteError (exit 1) if it cannot be written whole; ``path`` is then untouched."""
    h, w = pixels_rgb.shape[:2]
    temp = temp_path(path)
    try:
        with held_stderr():
            _save_image(scene, pixels_rgb, temp, fmt)
        commit(temp, path, w, h)
    finally:
        if os.path.exists(temp):
            os.remove(temp)


def _save_image(scene, pixels_rgb, path, fmt):
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


def _configure(scene, options: BatchOptions):
    """The render and reflection settings from the command line (both paths)."""
    settings = scene.virtual_reflections
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


def _shot_name(options: BatchOptions):
    return options.name or os.path.splitext(os.path.basename(bpy.data.filepath or "shot"))[0]


def _render_size(scene):
    """The render's (w, h) in pixels; ValueError (one line) when under one pixel."""
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
    return size


def _not_a_plate(outputs, plates):
    """ValueError (one line) when an output would replace a plate file."""
    for output in outputs:
        for plate_file in plates:
            if same_file(output, plate_file):
                raise ValueError(
                    f"output {output} is the plate itself: choose another --out or --name"
                )


def _render_rgba(scene, temp, use_compositor=False):
    """Render the scene into the EXR ``temp`` and read it back: ((h, w, 4) float32 RGBA of the
    render, (h, w, 3) float32 result of the shot's own compositor or None, seconds of the
    render call). Blender's own error lines are held back (the tool says it); a signal
    received during the render is raised once it returns."""
    scene.render.filepath = temp
    with held_stderr():
        started = time.perf_counter()
        bpy.ops.render.render(write_still=True, scene=scene.name)
        seconds = time.perf_counter() - started
        _raise_if_signalled()
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


def _render_to(scene, path, use_compositor=False):
    """Render the scene; its RGBA (scene-linear) goes to ``path`` (an RGBA float EXR, written
    atomically). Returns (rgba, the compositor's result or None)."""
    temp = os.path.splitext(temp_path(path, "render"))[0] + ".exr"
    try:
        rgba, comp, _ = _render_rgba(scene, temp, use_compositor)
        write_rgba(path, rgba)
    except ImageError as exc:
        raise BatchError(str(exc).replace(temp, path)) from exc
    finally:
        if os.path.exists(temp):
            os.remove(temp)
    return rgba, comp


def render_shot(options: BatchOptions, started):
    """The batch entry: one frame (the historical outputs) or a frame range (`render_frames`).
    Returns the exit code; raises ValueError/OSError/RuntimeError (one line) on bad input."""
    if not isinstance(options, BatchOptions):
        raise TypeError(f"render_shot takes a BatchOptions, not {type(options).__name__}")
    scene = bpy.context.scene
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no camera")
    source = PlateSource(options.plate)
    if options.frames is not None or source.kind != "still":
        return render_frames(options, started, source)
    settings = scene.virtual_reflections
    if options.frame is not None:
        scene.frame_set(options.frame)
    image = load_plate(options.plate)
    settings.plate_image = image
    compositor.setup_from_plate(scene, image)
    _configure(scene, options)
    _render_size(scene)
    name = _shot_name(options)
    outs = [
        os.path.abspath(os.path.join(options.out, f"{name}{suffix}"))
        for suffix in ("_render.exr", "_composite.png", "_composite.exr")
    ]
    _not_a_plate(outs, [options.plate])
    _check_folder(options.out)
    with OutputLock(os.path.abspath(options.out), name):
        remove_stale_temps(
            os.path.abspath(options.out),
            [os.path.splitext(os.path.basename(o))[0] for o in outs],
            live_ok=True,
        )
        try:
            return _one_frame(scene, options, image, name, started)
        except OSError as exc:  # a write failed (a full disk): not bad input
            raise BatchError(f"{exc.strerror or exc}: {exc.filename or options.out}") from exc


def _one_frame(scene, options, image, name, started):
    """One frame's render and composites (render_shot without --frames)."""
    stamp = lambda: f"{time.perf_counter() - started:6.2f} s"  # noqa: E731
    print(
        f"[{stamp()}] plate {image.name} {image.size[0]}x{image.size[1]}, "
        f"render {scene.render.resolution_x}x{scene.render.resolution_y} "
        f"at {scene.render.resolution_percentage}% with {scene.render.engine}"
    )

    # --- inter-reflections (paper §3.3, operators/interreflect.py) -------------------------------
    # --passes N|auto: generate, render and composite in passes instead of the one pass below.
    passes = options.passes
    if not options.no_reflections and passes != 1:
        render_path = os.path.abspath(os.path.join(options.out, f"{name}_render.exr"))
        comp = _render_shot_passes(
            scene,
            _objects(scene, options.objects),
            passes,
            render_path,
            log=lambda line: print(f"[{stamp()}] {line}"),
        )
        _save_composite(scene, comp, options.out, name, stamp, time.perf_counter())
        return 0

    if not options.no_reflections:
        objects = _objects(scene, options.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        report = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), objects)
        for warning in report.warnings:
            print(f"[{stamp()}] warning: {warning}")
        if not report.done:
            raise ValueError("no reflection generated: " + "; ".join(report.warnings))
        print(f"[{stamp()}] reflections: {report.summary()}")

    t = time.perf_counter()
    render_path = os.path.abspath(os.path.join(options.out, f"{name}_render.exr"))
    own = artist_compositor(scene)
    _render_settings(scene, own is not None)
    rgba, comp = _render_to(scene, render_path, own is not None)
    print(f"[{stamp()}] rendered {render_path} in {time.perf_counter() - t:.2f} s")

    t = time.perf_counter()
    if own is not None:
        print(f"[{stamp()}] composite: the shot's own compositor ({own}) over the plate")
    else:
        pixels, _ = plate.pixels(scene, image)
        comp = over(rgba, resize_nearest(pixels, *rgba.shape[:2]))
    _save_composite(scene, comp, options.out, name, stamp, t)
    return 0


def _render_settings(scene, use_compositor=False):
    """A transparent RGBA float EXR of the render; the composite is made in NumPy, the same
    in 4.5 and 5.x, unless the shot has its own compositor (``use_compositor``): then it
    runs (over the plate, as compositor.setup_from_plate set it up) and the render is a
    multilayer EXR holding both the view layer and the compositor's result."""
    scene.render.use_compositing = use_compositor
    scene.render.film_transparent = True
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


def _render_shot_passes(scene, objects, passes, render_path, log=print):
    """``--passes`` for one frame: `interreflect.render_passes` on the scene's plate, the last
    render written to ``render_path`` (RGBA float EXR, scene-linear), one log line per pass.
    Returns the (h, w, 3) float32 composite."""
    if not objects:
        raise ValueError("no object to reflect the plate (use --objects or mark objects)")
    pixels, _ = plate.pixels(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    with held_stderr():
        composite, rgba, reports = interreflect.render_passes(
            scene, depsgraph, objects, pixels, passes
        )
        _raise_if_signalled()
    for warning in reports[0].warnings:
        log(f"warning: {warning}")
    for report in reports:
        log(report.line())
    log(f"{len(reports)} pass(es) in {sum(r.seconds for r in reports):.2f} s")
    write_rgba(render_path, rgba)
    return composite


def _save_composite(scene, comp, out, name, stamp, t):
    for ext, fmt in ((".png", "PNG"), (".exr", "OPEN_EXR")):
        _save(scene, comp, os.path.abspath(os.path.join(out, f"{name}_composite{ext}")), fmt)
    print(
        f"[{stamp()}] composite {os.path.join(out, name + '_composite.png')} "
        f"in {time.perf_counter() - t:.2f} s"
    )


# --- frame ranges --------------------------------------------------------------------------------


class BatchError(RuntimeError):
    """A frame failed after the run started writing (a render error, a full disk): exit code
    1, worth another try, unlike bad input (2). The frames written so far are complete."""

    exit_code = 1


FORMATS = {"exr": "OPEN_EXR", "png": "PNG"}  # BatchOptions.format -> Blender's file format


class PlateSource:
    """--plate: a still image, an image sequence pattern (``plate.####.exr``,
    ``plate.%04d.jpg``: frame f of the scene reads the file of number f) or a movie (frame f
    of the scene shows the movie's frame f, counted from 1)."""

    def __init__(self, text):
        self.text = text
        if is_pattern(text):
            self.kind = "sequence"
        elif is_movie_path(text):
            self.kind = "movie"
        else:
            self.kind = "still"
        self.image = None

    def file(self, frame):
        if self.kind == "sequence":
            return os.path.abspath(pattern_path(self.text, frame))
        return os.path.abspath(self.text)

    def check(self, frames):
        """Refuse, before anything is written, frames whose plate is missing, a sequence
        whose frames differ in size (bounds smoothed across sizes would mix coordinates),
        and plate files Blender would misread (`check_plate_file`)."""
        if self.kind == "sequence":
            first = None
            for frame in frames:
                path = self.file(frame)
                if not os.path.isfile(path):
                    raise ValueError(f"plate frame {frame} is missing: {path}")
                header = check_plate_file(path, f"plate frame {frame}")
                size = (header.width, header.height)
                if first is None:
                    first = (frame, size)
                elif size != first[1]:
                    raise ValueError(
                        f"plate frame {frame} is {size[0]}x{size[1]}, frame {first[0]} is "
                        f"{first[1][0]}x{first[1][1]}: the frames of a sequence must have one "
                        f"size ({path})"
                    )
            return
        path = self.file(frames[0])
        if not os.path.isfile(path):
            raise ValueError(f"plate not found: {path}")
        if self.kind == "still":
            check_plate_file(path)
        if self.kind == "movie":
            image = self.load(frames[0])
            count = image.frame_duration
            outside = [f for f in frames if not 1 <= f <= count]
            if outside:
                raise ValueError(
                    f"plate frame {outside[0]} is missing: the movie {path} has frames 1-{count}"
                )

    def load(self, frame):
        """The Blender image of the scene's plate, showing ``frame``'s plate: one datablock
        for the whole run (a sequence's frames are loaded into it in turn)."""
        path = self.file(frame)
        if self.image is None:
            self.image = bpy.data.images.load(path, check_existing=False)
            self.image.name = "VR Batch Plate"
            if self.kind == "movie":
                self.image.source = "MOVIE"
        elif self.kind == "sequence" and bpy.path.abspath(self.image.filepath) != path:
            self.image.filepath = path  # loads this frame's file
        return self.image


def _frames(options: BatchOptions, scene):
    """The frames to render (BatchOptions refused --frame with --frames)."""
    if options.frames is not None:
        return parse_frames(options.frames)
    if options.frame is not None:
        return [options.frame]
    return list(range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step)))


def _check_folder(out):
    """Create the output folder and check that files can be made in it (ValueError if not)."""
    try:
        os.makedirs(out, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".vr-probe-", dir=out)
        os.close(fd)
        os.remove(probe)
    except OSError as exc:
        raise ValueError(f"output folder not writable: {out} ({exc.strerror or exc})") from exc


def _stems(paths):
    return [os.path.splitext(os.path.basename(p))[0] for p in paths]


def _complete(path, size):
    """True when ``path`` is an image Blender reads, of ``size`` (w, h)."""
    if not os.path.isfile(path) or os.path.getsize(path) == 0:
        return False
    image = bpy.data.images.load(path, check_existing=False)
    try:
        return tuple(image.size) == tuple(size) and image.has_data
    finally:
        bpy.data.images.remove(image)


def _write_json(path, data):
    temp = temp_path(path)
    with open(temp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=_plain)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(temp, path)


def _one_line(exc):
    lines = [line for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__


def _plain(value):
    """JSON for what json does not know: NumPy scalars and arrays, anything else as text."""
    return value.tolist() if hasattr(value, "tolist") else str(value)


def _read_report(path):
    """The per-frame entries of an earlier report at ``path`` by frame, or {}."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
        return {e["frame"]: e for e in data.get("frames", []) if isinstance(e, dict)}
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        return {}


def _pass_report(report):
    if hasattr(report, "__dataclass_fields__"):
        return {k: getattr(report, k) for k in report.__dataclass_fields__}
    return report if isinstance(report, dict) else str(report)


def _totals(entries, wall):
    rendered = [e for e in entries if e.get("status") == "rendered"]
    seconds = {}
    for entry in rendered:
        for stage, value in entry.get("times", {}).items():
            seconds[stage] = round(seconds.get(stage, 0.0) + value, 4)
    return {
        "frames": len(entries),
        "rendered": len(rendered),
        "skipped": sum(e.get("status") == "skipped" for e in entries),
        "warnings": sum(len(e.get("warnings", [])) for e in entries),
        "seconds": seconds,
        "wall_seconds": round(wall, 3),
    }


def render_frames(options: BatchOptions, started, source):
    """Render a frame range: per frame its plate, maps, render and composite; see the module
    docstring. Returns 0; raises ValueError (one line) for bad input before writing."""
    scene = bpy.context.scene
    frames = _frames(options, scene)
    fmt = options.format
    out = os.path.abspath(options.out)
    name = _shot_name(options)
    report_path = os.path.abspath(options.report or os.path.join(out, f"{name}.report.json"))
    if os.path.isdir(report_path):
        raise ValueError(f"--report is a folder, not a file: {report_path}")
    source.check(frames)
    outputs = {f: os.path.join(out, f"{name}.{f:04d}.{fmt}") for f in frames}
    elements = {f: element_path(out, name, f) for f in frames}
    plates = {source.file(f) for f in frames} if source.kind == "sequence" else {source.file(0)}
    _not_a_plate([*outputs.values(), *elements.values(), report_path], plates)
    _check_folder(out)
    if os.path.dirname(report_path) != out:
        _check_folder(os.path.dirname(report_path))
    with OutputLock(out, name, frames):
        return _render_frames(options, started, source, frames, outputs, report_path)


def element_path(out, name, frame):
    """The CG element of ``frame``, kept beside its composite: the render alone, RGBA
    scene-linear float EXR, ``<name>_render.<frame:04d>.exr`` (a sequence of its own)."""
    return os.path.join(out, f"{name}_render.{frame:04d}.exr")


def _extension_version():
    """The extension's version, from its blender_manifest.toml ("unknown" without one)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        with open(os.path.join(root, "blender_manifest.toml"), "rb") as f:
            return str(tomllib.load(f).get("version", "unknown"))
    except (OSError, ValueError):
        return "unknown"


def _view(scene):
    """The colour management a PNG is written through (the scene's view transform)."""
    view = scene.view_settings
    return {
        "display": scene.display_settings.display_device,
        "view_transform": view.view_transform,
        "look": view.look,
        "exposure": round(view.exposure, 6),
        "gamma": round(view.gamma, 6),
    }


def _run_inputs(scene, options, objects, size, use_passes):
    """What makes every frame of this run, besides its plate (batch_record): the shot, the
    effective settings (after the command line's), passes, render and output."""
    settings = scene.virtual_reflections
    ground = getattr(settings, "ground_object", None)
    reflections = {
        key: getattr(settings, key)
        for key in (
            "method",
            "combine",
            "resolution",
            "front",
            "triangles",
            "enlarge",
            "border",
            "strength",
            "ior",
            "smoothing",
        )
        if hasattr(settings, key)
    }
    reflections = {k: round(v, 6) if isinstance(v, float) else v for k, v in reflections.items()}
    reflections["ground_object"] = ground.name if ground is not None else None
    reflections["objects"] = sorted(o.name for o in objects)
    if scene.render.engine == "CYCLES":
        samples = scene.cycles.samples
    else:
        samples = getattr(scene.eevee, "taa_render_samples", None)
    return {
        "extension_version": _extension_version(),
        "shot": batch_record.file_identity(bpy.data.filepath) if bpy.data.filepath else None,
        "scene": scene.name,
        "reflections": reflections if not options.no_reflections else None,
        "passes": {
            "passes": options.passes if use_passes else 1,
            "tolerance": options.tolerance or interreflect.TOLERANCE,
            "max_passes": options.max_passes or interreflect.R_MAX,
        }
        if use_passes
        else 1,
        "render": {"engine": scene.render.engine, "size": list(size), "samples": samples},
        "format": options.format,
        "view": _view(scene) if options.format == "png" else "scene-linear",
    }


def _frame_inputs(run_inputs, source, frame):
    """``run_inputs`` and the plate of ``frame`` (its file's size and time; a movie's frame)."""
    plate_file = batch_record.file_identity(source.file(frame))
    if source.kind == "movie":
        plate_file["frame"] = frame
    return {**run_inputs, "plate": plate_file}


def _resume(paths, size, inputs, overwrite):
    """(skip, why): skip a frame only when its outputs ``paths`` are complete and their record
    says ``inputs`` made them; ``why`` says why a complete frame is rendered again."""
    if overwrite or not all(_complete(p, size) for p in paths):
        return False, None
    why = batch_record.stale(paths[0], inputs)
    return why is None, why


def _render_frames(options, started, source, frames, outputs, report_path):
    """render_frames once the run owns its frames' outputs (OutputLock)."""
    scene = bpy.context.scene
    settings = scene.virtual_reflections
    fmt = options.format
    passes = options.passes
    out = os.path.abspath(options.out)
    name = _shot_name(options)

    # The scene, from the first frame's plate.
    scene.frame_set(frames[0])
    image = source.load(frames[0])
    settings.plate_image = image
    compositor.setup_from_plate(scene, image)
    _configure(scene, options)
    use_passes = not options.no_reflections and options.passes != 1
    own = None if use_passes else artist_compositor(scene)  # passes composite in NumPy
    _render_settings(scene, own is not None)
    size = _render_size(scene)
    # This run owns its frames' outputs (the lock): any temporary file of theirs is a dead
    # run's. The report may be shared with a live run on other frames: only dead runs' go.
    owned = [*outputs.values(), *(element_path(out, name, f) for f in outputs)]
    records = [os.path.basename(batch_record.record_path(p))[1:] for p in outputs.values()]
    remove_stale_temps(out, _stems(owned) + records, live_ok=True)
    remove_stale_temps(os.path.dirname(report_path), _stems([report_path]))
    header = {
        "version": 1,
        "shot": bpy.data.filepath,
        "scene": scene.name,
        "name": name,
        "plate": source.text,
        "plate_kind": source.kind,
        "out": out,
        "format": fmt,
        "colour": {
            "element": "scene-linear Rec.709, float RGBA EXR (premultiplied)",
            "composite": "scene-linear Rec.709, half-float EXR"
            if fmt == "exr"
            else "the scene's view transform: {view_transform}, look {look}, exposure "
            "{exposure}, gamma {gamma}, display {display}".format(**_view(scene)),
            "over": f"the shot's own compositor ({own}), over the plate"
            if own
            else "the render over the plate (premultiplied alpha over, in NumPy)",
        },
        "requested": options.frames,
        "blender": bpy.app.version_string,
        "render": {
            "engine": scene.render.engine,
            "size": list(size),
            "samples": scene.cycles.samples if scene.render.engine == "CYCLES" else None,
        },
        "reflections": {
            "enabled": not options.no_reflections,
            "passes": passes if use_passes else 1,
            "passes_requested": passes,
            "smoothing": settings.smoothing,
            "resolution": settings.resolution,
            "combine": settings.combine,
        },
    }
    print(
        f"frames {len(frames)} ({frames[0]}-{frames[-1]}), plate {source.kind} {source.text}, "
        f"render {size[0]}x{size[1]} with {scene.render.engine}, out {out}"
    )
    print(f"composites: {header['colour']['over']}; {header['colour']['composite']}")
    previous = _read_report(report_path)
    objects = []
    warnings = []
    if not options.no_reflections:
        objects = _objects(scene, options.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        if use_passes:
            warnings.append("--passes: pass 1 is Generate, so bounds are not smoothed over frames")

    run_inputs = {**_run_inputs(scene, options, objects, size, use_passes), "compositor": own}
    entries = {}
    filters = {}
    step = max(1, frames[1] - frames[0]) if len(frames) > 1 else 1
    job = FrameJob(scene, source, fmt, objects, filters, step, use_passes, options, own)
    with sequence.suspended():
        if objects and not use_passes:
            # Attach first (at the first frame), so skipped and pre-rolled frames can step the
            # bounds filters: a resumed run and a farm chunk then match one uninterrupted run.
            pixels, _ = plate.pixels(scene, image)
            plate_shape = pixels.shape
            attached = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), objects)
            warnings += attached.warnings
            if not attached.done:
                raise ValueError("no reflection generated: " + "; ".join(attached.warnings))
            first = frames[0]
            count = sequence.preroll(settings.smoothing)
            for frame in range(first - count * step, first, step):
                if frame >= scene.frame_start:
                    scene.frame_set(frame)
                    depsgraph = bpy.context.evaluated_depsgraph_get()
                    sequence.advance(scene, depsgraph, filters, frame, step, plate_shape)
        for i, frame in enumerate(frames, 1):
            t0 = time.perf_counter()
            path = outputs[frame]
            element = element_path(out, name, frame)
            inputs = _frame_inputs(run_inputs, source, frame)
            skip, why = _resume([path, element], size, inputs, options.overwrite)
            if skip:
                entry = dict(previous.get(frame, {"frame": frame, "outputs": [path, element]}))
                entry["status"] = "skipped"
                entry.pop("rendered_again", None)
                entry["fingerprint"] = batch_record.digest(inputs)
                if objects and not use_passes:
                    scene.frame_set(frame)
                    depsgraph = bpy.context.evaluated_depsgraph_get()
                    sequence.advance(scene, depsgraph, filters, frame, step, plate_shape)
                entries[frame] = entry
                done = os.path.basename(path)
                print(f"frame {i}/{len(frames)} [{frame}] skipped: {done} is complete")
                _write_json(report_path, _report(header, entries, frames, warnings, started))
                continue
            if why:
                print(f"frame {i}/{len(frames)} [{frame}] rendered again: {why}", flush=True)
            try:
                batch_record.forget(path)  # the old record must not vouch for new files
                entry = job.render(frame, path, element)
                entry["fingerprint"] = batch_record.write(path, inputs)
                if why:
                    entry["rendered_again"] = why
            except (ValueError, OSError, RuntimeError) as exc:  # after frames were written
                error = f"frame {frame}: {_one_line(exc)}"
                entries[frame] = {"frame": frame, "status": "failed", "error": error}
                with contextlib.suppress(OSError, ValueError):
                    _write_json(report_path, _report(header, entries, frames, warnings, started))
                raise BatchError(error) from exc
            entries[frame] = entry
            _write_json(report_path, _report(header, entries, frames, warnings, started))
            entry_seconds = time.perf_counter() - t0
            print(
                f"frame {i}/{len(frames)} [{frame}] {os.path.basename(path)}: plate "
                f"{os.path.basename(entry['plate'])}, {entry['summary']}, {entry_seconds:.2f} s",
                flush=True,
            )
    report = _report(header, entries, frames, warnings, started, complete=True)
    _write_json(report_path, report)
    totals = report["totals"]
    print(
        f"done: {totals['rendered']} rendered, {totals['skipped']} skipped, "
        f"{totals['wall_seconds']:.2f} s; report {report_path}"
    )
    return 0


def _report(header, entries, frames, warnings, started, complete=False):
    ordered = [entries[f] for f in frames if f in entries]
    return {
        **header,
        "warnings": list(warnings),
        "frames": ordered,
        "totals": _totals(ordered, time.perf_counter() - started),
        "complete": complete and len(ordered) == len(frames),
    }


@dataclass(frozen=True, eq=False)
class FrameJob:
    """What is the same for every frame of a run; `render(frame, path)` renders one frame.

    ``filters``: the bounds filters sequence.update steps (shared with the run's pre-roll and
    skipped frames); ``objects``: empty without reflections; ``use_passes``: --passes."""

    scene: object
    source: PlateSource
    format: str  # a key of FORMATS
    objects: list
    filters: dict
    step: int
    use_passes: bool
    options: BatchOptions
    compositor: str | None = None  # the shot's own compositor (artist_compositor), if any

    def render(self, frame, path, element):
        """One frame: plate, maps, render (kept as the CG element ``element``), composite
        written atomically; returns its report entry."""
        scene, source, objects, options = self.scene, self.source, self.objects, self.options
        times = {}
        warnings = []

        def timed(stage, t):
            times[stage] = round(times.get(stage, 0.0) + time.perf_counter() - t, 4)

        t = time.perf_counter()
        scene.frame_set(frame)
        timed("frame_set", t)
        t = time.perf_counter()
        plate_file = source.file(frame)
        if source.kind != "movie":  # Blender would render a truncated file's rest grey
            check_complete(plate_file, "plate")
        image = source.load(frame)
        pixels, info = plate.pixels(scene, image)
        timed("plate", t)
        entry = {"frame": frame, "status": "rendered", "plate": plate_file}
        changes = {}
        pass_reports = []
        if self.use_passes:
            t = time.perf_counter()
            with held_stderr():
                comp, rgba, reports = interreflect.render_passes(
                    scene,
                    bpy.context.evaluated_depsgraph_get(),
                    objects,
                    pixels,
                    options.passes,
                    options.tolerance or interreflect.TOLERANCE,
                    options.max_passes or interreflect.R_MAX,
                )
                _raise_if_signalled()
            timed("passes", t)
            write_rgba(element, rgba)
            pass_reports = [_pass_report(r) for r in reports]
            for r in reports:
                warnings += list(r.warnings)
            summary = f"{len(reports)} pass(es)"
        else:
            if objects:
                identity = (plate_file, frame if source.kind == "movie" else None)
                depsgraph = bpy.context.evaluated_depsgraph_get()
                update = sequence.update(
                    scene,
                    depsgraph,
                    filters=self.filters,
                    frame=frame,
                    step=self.step,
                    plate_frame=plate.PlateFrame(pixels, info, plate_file, identity),
                )
                for stage, seconds in update.timings.items():
                    times[stage] = round(times.get(stage, 0.0) + seconds, 4)
                warnings += update.warnings
                changes = {
                    "maps_updated": update.maps,
                    "maps_unchanged": update.unchanged,
                    "tables_built": update.tables["built"],
                    "tables_reused": update.tables["reused"],
                    "bounds": {k: list(v) for k, v in update.boxes.items()},
                    "raw_bounds": {k: [round(x, 3) for x in v] for k, v in update.raw.items()},
                }
                summary = f"{len(update.maps)} map(s) updated"
            else:
                summary = "no reflections"
            t = time.perf_counter()
            render_path = os.path.splitext(temp_path(path, "render"))[0] + ".exr"
            try:
                own = self.compositor is not None
                rgba, comp, seconds = _render_rgba(scene, render_path, own)
                times["render"] = round(seconds, 4)
                t = time.perf_counter()
                write_rgba(element, rgba)
            except ImageError as exc:  # Blender could not write it whole (a full disk)
                raise BatchError(f"cannot write the render of frame {frame}: {exc}") from exc
            finally:
                if os.path.exists(render_path):
                    os.remove(render_path)
            if comp is None:
                comp = over(rgba, resize_nearest(pixels, *rgba.shape[:2]))
            timed("composite", t)
        t = time.perf_counter()
        _save(scene, comp, path, FORMATS[self.format])  # atomic and verified
        timed("write", t)
        times["total"] = round(sum(v for k, v in times.items()), 4)
        entry.update(
            {
                "outputs": [path, element],
                "times": times,
                "passes": len(pass_reports) or 1,
                "pass_reports": pass_reports,
                "changes": changes,
                "warnings": warnings,
                "summary": summary
                + f", render {times.get('render', times.get('passes', 0.0)):.2f} s",
            }
        )
        return entry
