"""The headless path behind render_shot.py: frames with reflections, and their composites.

One frame (`render_shot` without --frames and with a still plate) writes <name>_render.exr and
<name>_composite.png/.exr as it always did. A frame range (--frames, or a plate that is an
image sequence or a movie) goes through `render_frames`: per frame the plate of that frame,
the maps rebuilt with smoothed bounds (sequence.update, as Update Every Frame does), a render, the
composite <name>.<frame:04d>.<ext>, and the JSON report rewritten. Every file appears at once
(written under a temporary name in the output folder, then os.replace), frames already
complete are skipped (resume), and bad input is refused before anything is written.

Rendering uses Blender's own renderer; the final composite (render over plate) is computed in
NumPy from the saved RGBA render, so it does not depend on the compositor's API, which differs
between Blender 4.5 and 5.x. Images are written through Blender (save_render with the scene's
colour management), so no extra Python package is needed inside Blender.
"""

import json
import os
import re
import tempfile
import time
from dataclasses import dataclass

import bpy
import numpy as np

from ..virtual_reflections.composite import over, resize_nearest
from ..virtual_reflections.frames import is_movie_path, is_pattern, parse_frames, pattern_path
from ..virtual_reflections.imagefiles import read_rgba, write_rgba
from . import compositor, generate, interreflect, plate, sequence, shading
from .batch_options import BatchOptions

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


def load_plate(path):
    if not os.path.isfile(path):
        raise ValueError(f"plate not found: {path}")
    image = bpy.data.images.load(os.path.abspath(path), check_existing=True)
    plate.image_pixels(image)  # raises a clear ValueError for unreadable plates
    return image


def _save(scene, pixels_rgb, path, fmt):
    """Save (H, W, 3) linear pixels through Blender: EXR linear, PNG with the scene's view."""
    h, w = pixels_rgb.shape[:2]
    image = bpy.data.images.new("VR batch output", w, h, alpha=False, float_buffer=True)
    try:
        rgba = np.ones((h, w, 4), np.float32)
        rgba[..., :3] = pixels_rgb[::-1]
        image.pixels.foreach_set(rgba.ravel())
        settings = scene.render.image_settings
        previous = (settings.file_format, settings.color_mode, settings.color_depth)
        settings.file_format = fmt
        settings.color_mode = "RGB"
        settings.color_depth = "16" if fmt == "OPEN_EXR" else "8"
        try:
            image.save_render(path, scene=scene)
        finally:
            settings.file_format, settings.color_mode, settings.color_depth = previous
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
    stamp = lambda: f"{time.perf_counter() - started:6.2f} s"  # noqa: E731
    if options.frame is not None:
        scene.frame_set(options.frame)
    image = load_plate(options.plate)
    settings.plate_image = image
    compositor.setup_from_plate(scene, image)
    _configure(scene, options)
    os.makedirs(options.out, exist_ok=True)
    name = _shot_name(options)
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
    _render_settings(scene)
    scene.render.filepath = render_path
    bpy.ops.render.render(write_still=True, scene=scene.name)
    print(f"[{stamp()}] rendered {render_path} in {time.perf_counter() - t:.2f} s")

    t = time.perf_counter()
    rgba = read_rgba(render_path)
    pixels, _ = plate.pixels(scene, image)
    comp = over(rgba, resize_nearest(pixels, *rgba.shape[:2]))
    _save_composite(scene, comp, options.out, name, stamp, t)
    return 0


def _render_settings(scene):
    """A transparent RGBA float EXR of the render; the composite is made in NumPy, the same
    in 4.5 and 5.x."""
    scene.render.use_compositing = False
    scene.render.film_transparent = True
    settings_img = scene.render.image_settings
    settings_img.file_format, settings_img.color_mode = "OPEN_EXR", "RGBA"
    settings_img.color_depth = "32"


def _render_shot_passes(scene, objects, passes, render_path, log=print):
    """``--passes`` for one frame: `interreflect.render_passes` on the scene's plate, the last
    render written to ``render_path`` (RGBA float EXR, scene-linear), one log line per pass.
    Returns the (h, w, 3) float32 composite."""
    if not objects:
        raise ValueError("no object to reflect the plate (use --objects or mark objects)")
    pixels, _ = plate.pixels(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    composite, rgba, reports = interreflect.render_passes(scene, depsgraph, objects, pixels, passes)
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
        """Refuse, before anything is written, frames whose plate is missing."""
        if self.kind == "sequence":
            for frame in frames:
                path = self.file(frame)
                if not os.path.isfile(path):
                    raise ValueError(f"plate frame {frame} is missing: {path}")
            return
        path = self.file(frames[0])
        if not os.path.isfile(path):
            raise ValueError(f"plate not found: {path}")
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


def _temp(path, tag="tmp"):
    """A temporary name beside ``path`` for an atomic write: hidden, this process's."""
    folder, base = os.path.split(path)
    stem, ext = os.path.splitext(base)
    return os.path.join(folder, f".{stem}.{os.getpid()}.{tag}{ext}")


def _remove_stale(out, names):
    """Delete temporary files a killed run left for these outputs (never another file)."""
    stems = {os.path.splitext(os.path.basename(n))[0] for n in names}
    pattern = re.compile(r"^\.(.+)\.\d+\.(?:tmp|render)(\.\w+)?$")
    for entry in os.listdir(out):
        m = pattern.match(entry)
        if m and m.group(1) in stems:
            os.remove(os.path.join(out, entry))


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
    temp = _temp(path)
    with open(temp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=_plain)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(temp, path)


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
    settings = scene.virtual_reflections
    frames = _frames(options, scene)
    fmt = options.format
    passes = options.passes
    out = os.path.abspath(options.out)
    name = _shot_name(options)
    report_path = os.path.abspath(options.report or os.path.join(out, f"{name}.report.json"))
    source.check(frames)
    _check_folder(out)
    if os.path.dirname(report_path) != out:
        _check_folder(os.path.dirname(report_path))

    # The scene, from the first frame's plate.
    scene.frame_set(frames[0])
    image = source.load(frames[0])
    settings.plate_image = image
    compositor.setup_from_plate(scene, image)
    _configure(scene, options)
    _render_settings(scene)
    size = (
        scene.render.resolution_x * scene.render.resolution_percentage // 100,
        scene.render.resolution_y * scene.render.resolution_percentage // 100,
    )
    outputs = {f: os.path.join(out, f"{name}.{f:04d}.{fmt}") for f in frames}
    _remove_stale(out, [*outputs.values(), report_path])
    use_passes = not options.no_reflections and passes != 1
    header = {
        "version": 1,
        "shot": bpy.data.filepath,
        "scene": scene.name,
        "name": name,
        "plate": source.text,
        "plate_kind": source.kind,
        "out": out,
        "format": fmt,
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
    previous = _read_report(report_path)
    objects = []
    warnings = []
    if not options.no_reflections:
        objects = _objects(scene, options.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        if use_passes:
            warnings.append("--passes: pass 1 is Generate, so bounds are not smoothed over frames")

    entries = {}
    filters = {}
    step = max(1, frames[1] - frames[0]) if len(frames) > 1 else 1
    job = FrameJob(scene, source, fmt, objects, filters, step, use_passes, options)
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
            if not options.overwrite and _complete(path, size):
                entry = dict(previous.get(frame, {"frame": frame, "outputs": [path]}))
                entry["status"] = "skipped"
                if objects and not use_passes:
                    scene.frame_set(frame)
                    depsgraph = bpy.context.evaluated_depsgraph_get()
                    sequence.advance(scene, depsgraph, filters, frame, step, plate_shape)
                entries[frame] = entry
                done = os.path.basename(path)
                print(f"frame {i}/{len(frames)} [{frame}] skipped: {done} is complete")
                _write_json(report_path, _report(header, entries, frames, warnings, started))
                continue
            try:
                entry = job.render(frame, path)
            except (ValueError, OSError, RuntimeError) as exc:  # after frames were written
                raise BatchError(f"frame {frame}: {exc}") from exc
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

    def render(self, frame, path):
        """One frame: plate, maps, render, composite written atomically; returns its report
        entry."""
        scene, source, objects, options = self.scene, self.source, self.objects, self.options
        times = {}
        warnings = []

        def timed(stage, t):
            times[stage] = round(times.get(stage, 0.0) + time.perf_counter() - t, 4)

        t = time.perf_counter()
        scene.frame_set(frame)
        timed("frame_set", t)
        t = time.perf_counter()
        image = source.load(frame)
        pixels, info = plate.pixels(scene, image)
        plate_file = source.file(frame)
        timed("plate", t)
        entry = {"frame": frame, "status": "rendered", "plate": plate_file}
        changes = {}
        pass_reports = []
        if self.use_passes:
            t = time.perf_counter()
            comp, rgba, reports = interreflect.render_passes(
                scene,
                bpy.context.evaluated_depsgraph_get(),
                objects,
                pixels,
                options.passes,
                options.tolerance or interreflect.TOLERANCE,
                options.max_passes or interreflect.R_MAX,
            )
            timed("passes", t)
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
            render_path = os.path.splitext(_temp(path, "render"))[0] + ".exr"
            scene.render.filepath = render_path
            try:
                bpy.ops.render.render(write_still=True, scene=scene.name)
                timed("render", t)
                t = time.perf_counter()
                rgba = read_rgba(render_path)
            finally:
                if os.path.exists(render_path):
                    os.remove(render_path)
            comp = over(rgba, resize_nearest(pixels, *rgba.shape[:2]))
            timed("composite", t)
        t = time.perf_counter()
        temp = _temp(path)
        try:
            _save(scene, comp, temp, FORMATS[self.format])
            os.replace(temp, path)
        finally:
            if os.path.exists(temp):
                os.remove(temp)
        timed("write", t)
        times["total"] = round(sum(v for k, v in times.items()), 4)
        entry.update(
            {
                "outputs": [path],
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
