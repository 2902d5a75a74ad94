"""The headless path behind render_shot.py: one frame with reflections, and its composites.

One frame (`render_shot` without --frames and with a still plate) writes <name>_render.exr and
<name>_composite.png/.exr; a frame range (--frames, or a plate that is an image sequence or a
movie) goes to batch_frames.render_frames. The steps both share are in batch_render.py, Ctrl-C
and SIGTERM in batch_signals.py.

Nothing a user had is lost (issue 14, docs/failures.md): every output, one frame or a range,
is written under this process's temporary name, read back whole (`atomic_files.commit`) and
only then renamed over the previous file; an output that would replace a plate is refused;
a run locks the outputs it writes (batch_lock.py), so a second run on the same frames is
refused instead of deleting the first's temporary files.

Rendering uses Blender's own renderer; the final composite (render over plate) is computed in
NumPy from the saved RGBA render, so it does not depend on the compositor's API, which differs
between Blender 4.5 and 5.x, unless the shot has its own compositor.
"""

import os
import time

import bpy

from ..virtual_reflections.atomic_files import (
    ImageError,
    held_stderr,
    remove_stale_temps,
    temp_path,
)
from ..virtual_reflections.composite import over, resize_nearest
from ..virtual_reflections.imagefiles import write_rgba
from . import compositor, generate, interreflect, plate
from .batch_frames import PlateSource, render_frames
from .batch_lock import OutputLock
from .batch_options import BatchOptions
from .batch_render import (
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
from .batch_signals import raise_if_signalled


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
    compositor.plate_for_batch(scene, image)  # the artist's set-up kept
    configure(scene, options)
    render_size(scene)
    name = shot_name(options)
    outs = [
        os.path.abspath(os.path.join(options.out, f"{name}{suffix}"))
        for suffix in ("_render.exr", "_composite.png", "_composite.exr")
    ]
    not_a_plate(outs, [options.plate])
    check_folder(options.out)
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
            shot_objects(scene, options.objects),
            passes,
            render_path,
            log=lambda line: print(f"[{stamp()}] {line}"),
        )
        _save_composite(scene, comp, options.out, name, stamp, time.perf_counter())
        return 0

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
    return 0


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
    Returns the (h, w, 3) float32 composite."""
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
    return composite


def _save_composite(scene, comp, out, name, stamp, t):
    for ext, fmt in ((".png", "PNG"), (".exr", "OPEN_EXR")):
        write_image(scene, comp, os.path.abspath(os.path.join(out, f"{name}_composite{ext}")), fmt)
    print(
        f"[{stamp()}] composite {os.path.join(out, name + '_composite.png')} "
        f"in {time.perf_counter() - t:.2f} s"
    )
