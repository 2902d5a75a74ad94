"""The headless path behind render_shot.py: one frame with reflections, and its composites.

One frame (`render_shot` without --frames and with a still plate) writes <name>_render.exr and
<name>_composite.png/.exr; a frame range (--frames, or a plate that is an image sequence or a
movie) goes to ranges.render_frames. The steps both share are in render.py, Ctrl-C
and SIGTERM in signals.py.

Nothing a user had is lost (issue 14, docs/failures.md): every output, one frame or a range,
is written under this process's temporary name, read back whole (`atomic_files.commit`) and
only then renamed over the previous file; an output that would replace a plate is refused;
a run locks the outputs it writes (lock.py), so a second run on the same frames is
refused instead of deleting the first's temporary files.

Rendering uses Blender's own renderer; the final composite (render over plate) is computed in
NumPy from the saved RGBA render, so it does not depend on the compositor's API, which differs
between Blender 4.5 and 5.x, unless the shot has its own compositor.
"""

import os
import time

import bpy

from ...virtual_reflections.atomic_files import (
    ImageError,
    held_stderr,
    remove_stale_temps,
    temp_path,
)
from ...virtual_reflections.frames import parse_frames
from ...virtual_reflections.imagefiles import write_rgba
from .. import compositor, generate, interreflect
from ..scene import plate
from ..scene.composite import over, resize_nearest
from .lock import OutputLock
from .options import BatchOptions, check_name
from .ranges import PlateSource, render_frames
from .render import (
    BatchError,
    artist_compositor,
    check_folder,
    configure,
    load_plate,
    not_a_plate,
    render_rgba,
    render_settings,
    render_size,
    shot_name,
    shot_objects,
    write_image,
)
from .report import check_report_path, report_file, run_report, write_json
from .signals import raise_if_signalled


def render_shot(options: BatchOptions, started):
    """The batch entry: one frame (the historical outputs) or a frame range (`render_frames`).
    Returns the exit code; raises ValueError/OSError/RuntimeError (one line) on bad input."""
    if not isinstance(options, BatchOptions):
        raise TypeError(f"render_shot takes a BatchOptions, not {type(options).__name__}")
    scene = bpy.context.scene
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no camera")
    check_up_front(scene, options)
    source = PlateSource(options.plate)
    if options.frames is not None or source.kind != "still":
        return render_frames(options, started, source)
    settings = scene.virtual_reflections
    if options.frame is not None:
        scene.frame_set(options.frame)
    image = load_plate(options.plate)
    settings.plate_image = image
    compositor.plate_for_batch(scene, image)  # the artist's set-up kept
    configure(scene, options)
    render_size(scene)
    name = shot_name(options)
    outs = [
        os.path.abspath(os.path.join(options.out, f"{name}{suffix}"))
        for suffix in ("_render.exr", "_composite.png", "_composite.exr")
    ]
    out = os.path.abspath(options.out)
    report = report_file(options.report, out, name)
    check_report_path(report, out, name, [bpy.data.filepath, os.path.abspath(options.plate)])
    not_a_plate([*outs, report], [options.plate])
    check_folder(options.out)
    if os.path.dirname(report) != out:
        check_folder(os.path.dirname(report))
    with OutputLock(out, name):
        remove_stale_temps(out, [os.path.splitext(os.path.basename(o))[0] for o in outs], True)
        remove_stale_temps(os.path.dirname(report), [os.path.splitext(os.path.basename(report))[0]])
        try:
            entry = _one_frame(scene, options, image, name, started)
        except OSError as exc:  # a write failed (a full disk): not bad input
            raise BatchError(f"{exc.strerror or exc}: {exc.filename or options.out}") from exc
        entry.update(frame=scene.frame_current, plate=os.path.abspath(options.plate), outputs=outs)
        header = _one_frame_header(scene, options, name, out)
        frames = [scene.frame_current]
        write_json(report, run_report(header, {frames[0]: entry}, frames, [], started, True))
        return 0


def check_up_front(scene, options):
    """What both modes refuse before anything is opened or written (exit code 2): a default
    name (the .blend's) that --name would refuse, frames outside Blender's range (it would
    render its last frame instead), and --passes with Combine World (the shot's or
    --combine)."""
    if options.name is None:
        check_name(shot_name(options), "the shot's name (the default --name)")
    frame = bpy.types.Scene.bl_rna.properties["frame_current"]
    low, high = frame.hard_min, frame.hard_max
    if options.frames is not None:
        frames, what = parse_frames(options.frames), "--frames"
    else:
        frames, what = ([] if options.frame is None else [options.frame]), "--frame"
    for f in frames[:1] + frames[-1:]:
        if not low <= f <= high:
            raise ValueError(f"{what}: frame {f} is outside Blender's frames {low} to {high}")
    if not options.no_reflections and options.passes != 1:
        combine = options.combine or scene.virtual_reflections.combine
        try:
            interreflect.check_combine(
                combine, options.passes, options.max_passes or interreflect.R_MAX
            )
        except ValueError as exc:
            raise ValueError(f"--passes {options.passes}: {exc} (--combine)") from None


def _one_frame_header(scene, options, name, out):
    """What the one-frame report says of the run (the frame range's keys that apply)."""
    engine = scene.render.engine
    return {
        "version": 1,
        "shot": bpy.data.filepath,
        "scene": scene.name,
        "name": name,
        "plate": options.plate,
        "plate_kind": "still",
        "out": out,
        "format": "exr and png",
        "requested": None,
        "blender": bpy.app.version_string,
        "render": {
            "engine": engine,
            "size": list(render_size(scene)),
            "samples": scene.cycles.samples if engine == "CYCLES" else None,
        },
        "reflections": {"enabled": not options.no_reflections, "passes": options.passes},
    }


def _one_frame(scene, options, image, name, started):
    """One frame's render and composites (render_shot without --frames); returns its report
    entry (without frame, plate and outputs)."""
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
        comp, reports = _render_shot_passes(
            scene,
            shot_objects(scene, options.objects),
            passes,
            render_path,
            log=lambda line: print(f"[{stamp()}] {line}"),
        )
        _save_composite(scene, comp, options.out, name, stamp, time.perf_counter())
        return _entry(started, list(reports[0].warnings), f"{len(reports)} pass(es)")

    warnings, summary = [], "no reflections"
    if not options.no_reflections:
        objects = shot_objects(scene, options.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        report = generate.generate(scene, bpy.context.evaluated_depsgraph_get(), objects)
        for warning in report.warnings:
            print(f"[{stamp()}] warning: {warning}")
        if not report.done:
            raise ValueError("no reflection generated: " + "; ".join(report.warnings))
        print(f"[{stamp()}] reflections: {report.summary()}")
        warnings, summary = list(report.warnings), report.summary()

    t = time.perf_counter()
    render_path = os.path.abspath(os.path.join(options.out, f"{name}_render.exr"))
    own = artist_compositor(scene)
    render_settings(scene, own is not None)
    rgba, comp = _render_to(scene, render_path, own is not None)
    print(f"[{stamp()}] rendered {render_path} in {time.perf_counter() - t:.2f} s")

    t = time.perf_counter()
    if own is not None:
        print(f"[{stamp()}] composite: the shot's own compositor ({own}) over the plate")
    else:
        pixels, _ = plate.pixels(scene, image)
        comp = over(rgba, resize_nearest(pixels, *rgba.shape[:2]))
    _save_composite(scene, comp, options.out, name, stamp, t)
    return _entry(started, warnings, summary)


def _entry(started, warnings, summary):
    seconds = round(time.perf_counter() - started, 4)
    return {
        "status": "rendered",
        "times": {"total": seconds},
        "warnings": warnings,
        "summary": summary,
    }


def _render_to(scene, path, use_compositor=False):
    """Render the scene; its RGBA (scene-linear) goes to ``path`` (an RGBA float EXR, written
    atomically). Returns (rgba, the compositor's result or None)."""
    temp = os.path.splitext(temp_path(path, "render"))[0] + ".exr"
    try:
        rgba, comp, _ = render_rgba(scene, temp, use_compositor)
        write_rgba(path, rgba)
    except ImageError as exc:
        raise BatchError(str(exc).replace(temp, path)) from exc
    finally:
        if os.path.exists(temp):
            os.remove(temp)
    return rgba, comp


def _render_shot_passes(scene, objects, passes, render_path, log=print):
    """``--passes`` for one frame: `interreflect.render_passes` on the scene's plate, the last
    render written to ``render_path`` (RGBA float EXR, scene-linear), one log line per pass.
    Returns the (h, w, 3) float32 composite and the passes' reports."""
    if not objects:
        raise ValueError("no object to reflect the plate (use --objects or mark objects)")
    pixels, _ = plate.pixels(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    with held_stderr():
        composite, rgba, reports = interreflect.render_passes(
            scene, depsgraph, objects, pixels, passes
        )
        raise_if_signalled()
    for warning in reports[0].warnings:
        log(f"warning: {warning}")
    for report in reports:
        log(report.line())
    log(f"{len(reports)} pass(es) in {sum(r.seconds for r in reports):.2f} s")
    write_rgba(render_path, rgba)
    return composite, reports


def _save_composite(scene, comp, out, name, stamp, t):
    for ext, fmt in ((".png", "PNG"), (".exr", "OPEN_EXR")):
        write_image(scene, comp, os.path.abspath(os.path.join(out, f"{name}_composite{ext}")), fmt)
    print(
        f"[{stamp()}] composite {os.path.join(out, name + '_composite.png')} "
        f"in {time.perf_counter() - t:.2f} s"
    )
