"""The headless path behind render_shot.py: one frame with reflections, and its composite.

Rendering uses Blender's own renderer; the final composite (render over plate) is computed in
NumPy from the saved RGBA render, so it does not depend on the compositor's API, which differs
between Blender 4.5 and 5.x. Images are written through Blender (save_render with the scene's
colour management), so no extra Python package is needed inside Blender.
"""

import os
import time

import bpy
import numpy as np

from . import compositor, generate

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
        o for o in scene.objects if o.type in generate.REFLECTABLE and o.virtual_reflections.enabled
    ]
    if marked:
        return marked
    return [o for o in scene.objects if o.type in generate.REFLECTABLE and o.visible_get()]


class _Context:
    """The bits of bpy.context that generate() reads, for a given scene."""

    def __init__(self, scene):
        self.scene = scene

    def evaluated_depsgraph_get(self):
        return bpy.context.evaluated_depsgraph_get()


def load_plate(path):
    if not os.path.isfile(path):
        raise ValueError(f"plate not found: {path}")
    image = bpy.data.images.load(os.path.abspath(path), check_existing=True)
    compositor.plate_image_pixels(image)  # raises a clear ValueError for unreadable plates
    return image


def _read_rgba(path):
    image = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = image.size
        buf = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(buf)
    finally:
        bpy.data.images.remove(image)
    return buf.reshape(h, w, 4)[::-1]


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


def render_shot(args, started):
    scene = bpy.context.scene
    if scene.camera is None:
        raise ValueError(f"scene {scene.name!r} has no camera")
    settings = scene.virtual_reflections
    stamp = lambda: f"{time.perf_counter() - started:6.2f} s"  # noqa: E731
    if args.frame is not None:
        scene.frame_set(args.frame)
    image = load_plate(args.plate)
    settings.plate_image = image
    compositor.setup_from_plate(scene, image)
    if args.scale:
        scene.render.resolution_percentage = args.scale
    for key in ("combine", "resolution"):
        value = getattr(args, key)
        if value is not None:
            setattr(settings, key, str(value) if key == "resolution" else value)
    if args.triangles is not None:
        settings.front = "CONTINUOUS" if args.triangles == 0 else "TRIANGLES"
        settings.triangles = max(4, args.triangles)
    if args.engine:
        _set_engine(scene, args.engine)
    if args.samples and scene.render.engine == "CYCLES":
        scene.cycles.samples = args.samples
    elif args.samples:
        for attr in ("taa_render_samples",):
            if hasattr(scene.eevee, attr):
                setattr(scene.eevee, attr, args.samples)
    os.makedirs(args.out, exist_ok=True)
    name = args.name or os.path.splitext(os.path.basename(bpy.data.filepath or "shot"))[0]
    print(
        f"[{stamp()}] plate {image.name} {image.size[0]}x{image.size[1]}, "
        f"render {scene.render.resolution_x}x{scene.render.resolution_y} "
        f"at {scene.render.resolution_percentage}% with {scene.render.engine}"
    )

    if not args.no_reflections:
        objects = _objects(scene, args.objects)
        if not objects:
            raise ValueError("no object to reflect the plate (use --objects or mark objects)")
        report = generate.generate(_Context(scene), objects)
        for warning in report.warnings:
            print(f"[{stamp()}] warning: {warning}")
        if not report.done:
            raise ValueError("no reflection generated: " + "; ".join(report.warnings))
        print(f"[{stamp()}] reflections: {report.summary()}")

    t = time.perf_counter()
    render_path = os.path.abspath(os.path.join(args.out, f"{name}_render.exr"))
    scene.render.use_compositing = False  # the composite is made below, the same in 4.5 and 5.x
    scene.render.film_transparent = True
    settings_img = scene.render.image_settings
    settings_img.file_format, settings_img.color_mode = "OPEN_EXR", "RGBA"
    settings_img.color_depth = "32"
    scene.render.filepath = render_path
    bpy.ops.render.render(write_still=True, scene=scene.name)
    print(f"[{stamp()}] rendered {render_path} in {time.perf_counter() - t:.2f} s")

    t = time.perf_counter()
    rgba = _read_rgba(render_path)
    plate, _ = generate.plate_pixels(scene, image)
    if plate.shape[:2] != rgba.shape[:2]:  # resolution percentage: scale the plate to match
        ys = (np.arange(rgba.shape[0]) + 0.5) * plate.shape[0] / rgba.shape[0]
        xs = (np.arange(rgba.shape[1]) + 0.5) * plate.shape[1] / rgba.shape[1]
        plate = plate[ys.astype(int)][:, xs.astype(int)]
    comp = compositor.composite_over_plate(rgba, plate)
    for ext, fmt in ((".png", "PNG"), (".exr", "OPEN_EXR")):
        _save(scene, comp, os.path.abspath(os.path.join(args.out, f"{name}_composite{ext}")), fmt)
    print(
        f"[{stamp()}] composite {os.path.join(args.out, name + '_composite.png')} "
        f"in {time.perf_counter() - t:.2f} s"
    )
    return 0
