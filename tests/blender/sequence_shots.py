"""Small plates, movies and shots for the sequence and batch tests (bpy module)."""

import pathlib

import bpy
import numpy as np
from shots import add_camera, addon_part

COLOURS = ((1.0, 0.1, 0.1), (0.1, 1.0, 0.1), (0.1, 0.1, 1.0))  # frames 1, 2, 3
SIZE = (64, 32)


def plate_pixels(colour, size=SIZE):
    """(H, W, 4) float32, top row first: the colour fading in from the left (0.25 -> 1)."""
    w, h = size
    ramp = 0.25 + 0.75 * (np.arange(w, dtype=np.float32) + 0.5) / w
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = ramp[None, :, None] * np.asarray(colour, np.float32)
    return rgba


def write_plates(folder, colours=COLOURS, size=SIZE, first=1, name="plate"):
    """PNG plates name.0001.png ... (sRGB 8-bit); returns their paths."""
    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, colour in enumerate(colours, first):
        image = bpy.data.images.new("plate", *size, alpha=False)
        image.pixels.foreach_set(plate_pixels(colour, size)[::-1].ravel())
        path = folder / f"{name}.{i:04d}.png"
        image.filepath_raw = str(path)
        image.file_format = "PNG"
        image.save()
        bpy.data.images.remove(image)
        paths.append(path)
    return paths


def write_movie(folder, plates):
    """A lossless movie (FFV1 in Matroska) of the plates through the sequencer, or None when
    this Blender cannot write one. Leaves an empty file behind (read_homefile)."""
    if not bpy.app.ffmpeg.supported:
        return None
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    w, h = SIZE
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, len(plates)
    editor = scene.sequence_editor_create()
    strips = editor.strips if hasattr(editor, "strips") else editor.sequences
    strip = strips.new_image("plates", str(plates[0]), 1, 1)
    for path in plates[1:]:
        strip.elements.append(pathlib.Path(path).name)
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # 5.x: movies are a media type
        settings.media_type = "VIDEO"
    settings.file_format = "FFMPEG"
    scene.render.ffmpeg.format = "MKV"
    scene.render.ffmpeg.codec = "FFV1"
    scene.render.use_sequencer = True
    scene.render.filepath = str(pathlib.Path(folder) / "movie_")
    bpy.ops.render.render(animation=True)
    movies = sorted(pathlib.Path(folder).glob("movie_*.mkv"))
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    return movies[0] if movies else None


def build_scene(radius=0.6, frames=3):
    """Camera looking at a sphere (radius, at the origin) and a light, in the current (empty)
    file; tiny deterministic Cycles. Returns the sphere."""
    scene = bpy.context.scene
    add_camera(scene)
    light = bpy.data.objects.new("Light", bpy.data.lights.new("Light", "POINT"))
    light.data.energy = 300.0
    light.location = (2.0, -3.0, 2.0)
    scene.collection.objects.link(light)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=16, ring_count=8)
    sphere = bpy.context.active_object
    if hasattr(sphere, "virtual_reflections"):  # registered: mark it (the batch finds it anyway)
        sphere.virtual_reflections.enabled = True
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 2
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 1
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.view_settings.view_transform = "Standard"
    scene.frame_start, scene.frame_end = 1, frames
    return sphere


def mean_rgb(image):
    """The mean RGB of a Blender image's pixels."""
    buf = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(buf)
    return buf.reshape(-1, 4)[:, :3].mean(0)


def read(path):
    """(H, W, 4) float32 pixels of an image file, top row first (the batch entry's reader)."""
    return addon_part("virtual_reflections.imagefiles").read_rgba(str(path))
