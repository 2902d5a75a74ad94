"""Frame ranges in the headless batch: --frames, or a plate that is an image sequence or a movie.

Per frame: the plate of that frame, the maps rebuilt with smoothed bounds (sequence.update, as
Update Every Frame does), a render, the CG element <name>_render.<frame:04d>.exr and the
composite <name>.<frame:04d>.<ext>, and the JSON report rewritten (report.py). Every
file appears at once (written under a temporary name in the output folder, then renamed),
frames already complete and made from the same inputs are skipped (resume, record.py),
bad input is refused before anything is written, and a run locks the frames it writes
(lock.py). A plate frame that cannot be read whole fails its frame (exit 1, named in
the report) instead of rendering half grey.
"""

import contextlib
import os
import time
import tomllib
from dataclasses import dataclass, field

import bpy

from ...virtual_reflections import backends
from ...virtual_reflections.atomic_files import (
    ImageError,
    held_stderr,
    remove_stale_temps,
    temp_path,
)
from ...virtual_reflections.frames import is_movie_path, is_pattern, parse_frames, pattern_path
from ...virtual_reflections.imagefiles import check_complete, write_rgba
from ...virtual_reflections.movies import frames_text, whole_frames
from .. import compositor, generate, interreflect, pipeline, sequence
from ..scene import plate
from ..scene.composite import over, resize_nearest
from . import record
from .lock import OutputLock
from .options import BatchOptions
from .render import (
    BatchError,
    artist_compositor,
    check_folder,
    check_plate_file,
    configure,
    not_a_plate,
    render_rgba,
    render_settings,
    render_size,
    shot_name,
    shot_objects,
    write_image,
)
from .report import (
    check_report_path,
    one_line,
    pass_report,
    read_report,
    report_file,
    run_report,
    write_json,
)
from .signals import raise_if_signalled

FORMATS = {"exr": "OPEN_EXR", "png": "PNG"}  # BatchOptions.format -> Blender's file format


class PlateSource:
    """--plate: a still image, an image sequence pattern (``plate.####.exr``,
    ``plate.%04d.jpg``: frame f of the scene reads the file of number f) or a movie (frame f
    of the scene shows the movie's frame f, counted from 1)."""

    def __init__(self, text):
        self.text = text
        if is_pattern(text) and not os.path.isfile(text):  # take#3.exr that exists: a still
            self.kind = "sequence"
        elif is_movie_path(text):
            self.kind = "movie"
        else:
            self.kind = "still"
        self.image = None
        self._whole = None  # a movie's whole frames: ((path, inode, size, time), count)

    def file(self, frame):
        if self.kind == "sequence":
            return os.path.abspath(pattern_path(self.text, frame))
        return os.path.abspath(self.text)

    def check(self, frames):
        """Refuse, before anything is written, frames whose plate is missing, a sequence
        whose frames differ in size (bounds smoothed across sizes would mix coordinates),
        plate files Blender would misread (`check_plate_file`) and a still plate that cannot
        be read whole (before Blender prints its own lines about it)."""
        if self.kind == "sequence":
            first = None
            for frame in frames:
                path = self.file(frame)
                if not os.path.exists(path):  # a folder: check_plate_file says so
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
        if os.path.isdir(path):
            raise ValueError(f"plate is a folder, not an image file: {path}")
        if not os.path.isfile(path):
            raise ValueError(f"plate not found: {path}")
        if self.kind == "still":  # read whole now: Blender's own lines would come first
            check_plate_file(path)
            check_complete(path, "plate")
        if self.kind == "movie":
            self.check_movie(path, frames)

    def check_movie(self, path, frames):
        """ValueError (one line: the movie, the frames it has, the frames asked) for frames
        the movie does not hold whole: beyond the count its header says, or beyond the frames
        whose bytes are in the file (a movie cut short: Blender would show its last whole
        frame for each of them, `movies.whole_frames`)."""
        with held_stderr():  # Blender's own lines on a movie it cannot open
            image = self.load(frames[0])
            readable = image.size[0] > 0 and image.size[1] > 0
        count = image.frame_duration if readable else 0
        whole = self.whole_frames(path)
        have = count if whole is None else min(count, whole)
        outside = [f for f in frames if not 1 <= f <= have]
        if not outside:
            return
        asked = f"plate frame{'s' if len(outside) > 1 else ''} {frames_text(outside)}"
        if have == 0:
            raise ValueError(
                f"{asked}: the movie {path} has no whole frame (damaged or cut short?)"
            )
        cut = f" whole (its header says {count}: cut short?)" if have < count else ""
        raise ValueError(f"{asked}: not in the movie {path}, which has frames 1-{have}{cut}")

    def whole_frames(self, path):
        """`movies.whole_frames` of ``path``, counted again only when the file changed."""
        st = os.stat(path)
        key = (path, st.st_ino, st.st_size, st.st_mtime_ns)
        if self._whole is None or self._whole[0] != key:
            self._whole = (key, whole_frames(path))
        return self._whole[1]

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


def render_frames(options: BatchOptions, started, source):
    """Render a frame range: per frame its plate, maps, render and composite; see the module
    docstring. Returns 0; raises ValueError (one line) for bad input before writing."""
    scene = bpy.context.scene
    frames = _frames(options, scene)
    fmt = options.format
    out = os.path.abspath(options.out)
    name = shot_name(options)
    report_path = report_file(options.report, out, name)
    sequence = source.text if source.kind == "sequence" else None
    inputs = [bpy.data.filepath, None if sequence else source.file(0)]
    check_report_path(report_path, out, name, inputs, sequence)
    source.check(frames)
    outputs = {f: os.path.join(out, f"{name}.{f:04d}.{fmt}") for f in frames}
    elements = {f: element_path(out, name, f) for f in frames}
    plates = {source.file(f) for f in frames} if source.kind == "sequence" else {source.file(0)}
    not_a_plate([*outputs.values(), *elements.values(), report_path], plates)
    check_folder(out)
    if os.path.dirname(report_path) != out:
        check_folder(os.path.dirname(report_path))
    with OutputLock(out, name, frames):
        return _render_frames(options, started, source, frames, outputs, report_path)


def element_path(out, name, frame):
    """The CG element of ``frame``, kept beside its composite: the render alone, RGBA
    scene-linear float EXR, ``<name>_render.<frame:04d>.exr`` (a sequence of its own)."""
    return os.path.join(out, f"{name}_render.{frame:04d}.exr")


def _frames(options: BatchOptions, scene):
    """The frames to render (BatchOptions refused --frame with --frames)."""
    if options.frames is not None:
        return parse_frames(options.frames)
    if options.frame is not None:
        return [options.frame]
    return list(range(scene.frame_start, scene.frame_end + 1, max(1, scene.frame_step)))


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


def _extension_version():
    """The extension's version, from its blender_manifest.toml ("unknown" without one)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        with open(os.path.join(root, "blender_manifest.toml"), "rb") as f:
            return str(tomllib.load(f).get("version", "unknown"))
    except (OSError, ValueError):
        return "unknown"


def _blender():
    """The Blender that renders: its version and build (a frame made by another is made again)."""
    build = bpy.app.build_hash
    build = build.decode(errors="replace") if isinstance(build, bytes) else str(build)
    return {"version": bpy.app.version_string, "build_hash": build}


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
    """What makes every frame of this run, besides its plate (record.py): the shot, the
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
            "surroundings",
            "contact_shadow",
        )
        if hasattr(settings, key)
    }
    if reflections.get("surroundings") == "CUSTOM":  # only then do they shape the maps
        reflections["sky_brightness"] = settings.sky_brightness
        reflections["sky_tint"] = [round(v, 6) for v in settings.sky_tint]
    texture = pipeline.scene_sky_texture(settings)
    if texture > 0:  # off, the records are those made before it (a flat sky)
        reflections["sky_texture"] = texture
    reflections = {k: round(v, 6) if isinstance(v, float) else v for k, v in reflections.items()}
    reflections["ground_object"] = ground.name if ground is not None else None
    reflections["objects"] = sorted(o.name for o in objects)
    if scene.render.engine == "CYCLES":
        samples = scene.cycles.samples
    else:
        samples = getattr(scene.eevee, "taa_render_samples", None)
    return {
        "extension_version": _extension_version(),
        "blender": _blender(),
        "shot": record.file_identity(bpy.data.filepath) if bpy.data.filepath else None,
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
    plate_file = record.file_identity(source.file(frame))
    if source.kind == "movie":
        plate_file["frame"] = frame
    return {**run_inputs, "plate": plate_file}


def _resume(paths, size, inputs, overwrite):
    """(skip, why): skip a frame only when its outputs ``paths`` are complete and their record
    says ``inputs`` made them; ``why`` says why a complete frame is rendered again."""
    if overwrite or not all(_complete(p, size) for p in paths):
        return False, None
    why = record.stale(paths[0], inputs)
    return why is None, why


def _run_header(scene, options, source, name, out, size, own, use_passes):
    """What the report says of the whole run (report.run_report puts the frames after
    it): the shot, plate, outputs and their colour, the render and the reflections."""
    settings = scene.virtual_reflections
    fmt = options.format
    passes = options.passes
    return {
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
            "back_end": backends.backend(),  # the engine's gathers: numba, opencv or numpy
            "passes": passes if use_passes else 1,
            "passes_requested": passes,
            "smoothing": settings.smoothing,
            "resolution": settings.resolution,
            "combine": settings.combine,
        },
    }


def _render_frames(options, started, source, frames, outputs, report_path):
    """render_frames once the run owns its frames' outputs (OutputLock)."""
    scene = bpy.context.scene
    out = os.path.abspath(options.out)
    name = shot_name(options)
    image, use_passes, own, size, header = _prepare(
        scene, options, source, frames, outputs, report_path, out, name
    )
    previous = read_report(report_path)
    objects, warnings = _shot_objects(scene, options, use_passes)
    run_inputs = {**_run_inputs(scene, options, objects, size, use_passes), "compositor": own}
    entries = {}
    filters = {}
    step = max(1, frames[1] - frames[0]) if len(frames) > 1 else 1
    job = FrameJob(scene, source, options.format, objects, filters, step, use_passes, options, own)

    def write_report():
        write_json(report_path, run_report(header, entries, frames, warnings, started))

    with sequence.suspended():
        if objects and not use_passes:
            warnings += job.attach(image, frames[0])
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
                entry["fingerprint"] = record.digest(inputs)
                if objects and not use_passes:
                    job.step_through(frame)
                entries[frame] = entry
                done = os.path.basename(path)
                print(f"frame {i}/{len(frames)} [{frame}] skipped: {done} is complete")
                write_report()
                continue
            if why:
                print(f"frame {i}/{len(frames)} [{frame}] rendered again: {why}", flush=True)
            try:
                entry = _render_one(job, frame, path, element, inputs, why)
            except (ValueError, OSError, RuntimeError) as exc:  # after frames were written
                error = f"frame {frame}: {one_line(exc)}"
                entries[frame] = {"frame": frame, "status": "failed", "error": error}
                with contextlib.suppress(OSError, ValueError):
                    write_report()
                raise BatchError(error) from exc
            entries[frame] = entry
            write_report()
            entry_seconds = time.perf_counter() - t0
            print(
                f"frame {i}/{len(frames)} [{frame}] {os.path.basename(path)}: plate "
                f"{os.path.basename(entry['plate'])}, {entry['summary']}, {entry_seconds:.2f} s",
                flush=True,
            )
    report = run_report(header, entries, frames, warnings, started, complete=True)
    write_json(report_path, report)
    totals = report["totals"]
    print(
        f"done: {totals['rendered']} rendered, {totals['skipped']} skipped, "
        f"{totals['wall_seconds']:.2f} s; report {report_path}"
    )
    return 0


def _prepare(scene, options, source, frames, outputs, report_path, out, name):
    """The scene set up from the first frame's plate (the artist's compositor kept), the dead
    runs' temporary files of this run's outputs removed, the run's header made and its first
    lines printed. Returns (the first plate's image, whether passes run, the shot's own
    compositor or None, the render size, the header)."""
    settings = scene.virtual_reflections
    scene.frame_set(frames[0])
    image = source.load(frames[0])
    settings.plate_image = image
    compositor.plate_for_batch(scene, image)  # the artist's set-up kept
    configure(scene, options)
    use_passes = not options.no_reflections and options.passes != 1
    own = None if use_passes else artist_compositor(scene)  # passes composite in NumPy
    render_settings(scene, own is not None)
    size = render_size(scene)
    # This run owns its frames' outputs (the lock): any temporary file of theirs is a dead
    # run's. The report may be shared with a live run on other frames: only dead runs' go.
    owned = [*outputs.values(), *(element_path(out, name, f) for f in outputs)]
    records = [os.path.basename(record.record_path(p))[1:] for p in outputs.values()]
    remove_stale_temps(out, _stems(owned) + records, live_ok=True)
    remove_stale_temps(os.path.dirname(report_path), _stems([report_path]))
    header = _run_header(scene, options, source, name, out, size, own, use_passes)
    print(
        f"frames {len(frames)} ({frames[0]}-{frames[-1]}), plate {source.kind} {source.text}, "
        f"render {size[0]}x{size[1]} with {scene.render.engine}, out {out}"
    )
    print(f"composites: {header['colour']['over']}; {header['colour']['composite']}")
    return image, use_passes, own, size, header


def _shot_objects(scene, options, use_passes):
    """The objects that reflect the plate (none with --no-reflections; ValueError when there
    are none to reflect it) and the run's first warnings."""
    objects = []
    warnings = []
    if not options.no_reflections:
        objects = shot_objects(scene, options.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        if use_passes:
            warnings.append("--passes: pass 1 is Generate, so bounds are not smoothed over frames")
    return objects, warnings


def _render_one(job, frame, path, element, inputs, why):
    """Render ``frame`` (its old record forgotten first: it must not vouch for new files) and
    record its inputs; returns its report entry."""
    record.forget(path)  # the old record must not vouch for new files
    entry = job.render(frame, path, element)
    entry["fingerprint"] = record.write(path, inputs)
    if why:
        entry["rendered_again"] = why
    return entry


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
    plate_shape: list = field(default_factory=list)  # the plate's (H, W, 3), once attached

    def attach(self, image, first):
        """Generate once at the first frame (before any is rendered), so skipped and
        pre-rolled frames can step the bounds filters: a resumed run and a farm chunk then
        match one uninterrupted run. Returns Generate's warnings."""
        scene = self.scene
        pixels, _ = plate.pixels(scene, image)
        self.plate_shape[:] = pixels.shape
        attached = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), self.objects)
        if not attached.done:
            raise ValueError("no reflection generated: " + "; ".join(attached.warnings))
        count = sequence.preroll(scene.virtual_reflections.smoothing)
        for frame in range(first - count * self.step, first, self.step):
            if frame >= scene.frame_start:
                self.step_through(frame)
        return list(attached.warnings)

    def step_through(self, frame):
        """A frame not rendered here (pre-roll, or skipped as complete): the bounds filters
        still step through it."""
        self.scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        shape = tuple(self.plate_shape)
        sequence.advance(self.scene, depsgraph, self.filters, frame, self.step, shape)

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
        else:  # a frame the movie has lost since the run began fails, as a damaged file does
            source.check_movie(plate_file, [frame])
            with held_stderr():
                pixels, info = plate.pixels(scene, source.load(frame))
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
                raise_if_signalled()
            timed("passes", t)
            write_rgba(element, rgba)
            pass_reports = [pass_report(r) for r in reports]
            for r in reports:
                warnings += list(r.warnings)
            summary = f"{len(reports)} pass(es)"
        else:
            changes, summary = {}, "no reflections"
            if objects:
                changes, more = self._update_maps(frame, plate_file, pixels, info, times)
                warnings += more
                summary = f"{len(changes['maps_updated'])} map(s) updated"
            comp = self._render_element(frame, path, element, pixels, times)
        t = time.perf_counter()
        write_image(scene, comp, path, FORMATS[self.format])  # atomic and verified
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

    def _update_maps(self, frame, plate_file, pixels, info, times):
        """The maps of ``frame`` from its plate (sequence.update, the bounds smoothed over the
        run's frames); its stage timings added to ``times``. Returns (the report's changes,
        warnings)."""
        identity = (plate_file, frame if self.source.kind == "movie" else None)
        update = sequence.update(
            self.scene,
            bpy.context.evaluated_depsgraph_get(),
            filters=self.filters,
            frame=frame,
            step=self.step,
            plate_frame=plate.PlateFrame(pixels, info, plate_file, identity),
        )
        for stage, seconds in update.timings.items():
            times[stage] = round(times.get(stage, 0.0) + seconds, 4)
        changes = {
            "maps_updated": update.maps,
            "maps_unchanged": update.unchanged,
            "tables_built": update.tables["built"],
            "tables_reused": update.tables["reused"],
            "bounds": {k: list(v) for k, v in update.boxes.items()},
            "raw_bounds": {k: [round(x, 3) for x in v] for k, v in update.raw.items()},
        }
        return changes, list(update.warnings)

    def _render_element(self, frame, path, element, pixels, times):
        """Render ``frame``, keep the render as the CG element ``element`` and return the
        composite: the shot's own compositor's, or the render over the plate ``pixels``."""
        t = time.perf_counter()
        render_path = os.path.splitext(temp_path(path, "render"))[0] + ".exr"
        try:
            own = self.compositor is not None
            rgba, comp, seconds = render_rgba(self.scene, render_path, own)
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
        times["composite"] = round(times.get("composite", 0.0) + time.perf_counter() - t, 4)
        return comp
