"""How long Render Inter-Reflections holds Blender's window: the blocking run (a script's
EXEC_DEFAULT) against the run from the button (INVOKE_DEFAULT: the maps' engine work in a
thread, each render as Blender's render job). A timer ticking every 10 ms measures the longest
gap between two ticks, i.e. the longest time the window could not draw.

    xvfb-run -a blender --factory-startup --python benchmarks/passes_window.py -- . [SAMPLES]

Two mirror spheres over a 1920 x 1080 plate, a 960 x 540 Cycles render (SAMPLES samples, 64 by
default, no denoising), 2 passes. Prints one line; the figures are in docs/benchmarks.md."""

import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from window_probe import Ticker, load_addon, view3d_context, window_figures  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1 :]
root = args[0]
samples = int(args[1]) if len(args) > 1 else 64
generate = load_addon(root)
ticker = Ticker(generate)
results = {"samples": samples}


def setup():
    scene = bpy.context.scene
    bpy.data.objects.remove(bpy.data.objects["Cube"])
    for name, x in (("Left", -1.1), ("Right", 1.1)):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.9, location=(x, 0, 0))
        bpy.context.active_object.name = name
    bpy.ops.object.select_all(action="DESELECT")
    for name in ("Left", "Right"):
        bpy.data.objects[name].select_set(True)
    plate = bpy.data.images.new("Plate", 1920, 1080)
    y, x = np.mgrid[0:1080, 0:1920] / np.array([1080.0, 1920.0])[:, None, None]
    rgba = np.stack([x, y, 1 - x, np.ones_like(x)], -1).astype(np.float32)
    plate.pixels.foreach_set(rgba.ravel())
    settings = scene.virtual_reflections
    settings.plate_image = plate
    settings.resolution = "1024"
    settings.combine = "REPLACE"
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = 960, 540
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    ticker.start()
    bpy.app.timers.register(blocking, first_interval=0.5)


def blocking():
    started = time.perf_counter()
    with view3d_context():
        bpy.ops.vr.render_passes("EXEC_DEFAULT", passes=2)
    results["blocking_total_s"] = time.perf_counter() - started
    bpy.ops.vr.remove()
    bpy.app.timers.register(lambda: measure_blocking(started), first_interval=0.1)


def measure_blocking(started):
    results["blocking_longest_gap_s"] = ticker.longest_gap(started - 0.02)
    results["_started"] = time.perf_counter()
    with view3d_context():
        bpy.ops.vr.render_passes("INVOKE_DEFAULT", passes=2)
    bpy.app.timers.register(wait, first_interval=0.05)


def wait():
    if generate.running() is not None:
        return 0.05
    started = results.pop("_started")
    window_figures(results, ticker, started)
    spent = ticker.spent(started)
    for stage, seconds in sorted(spent.items(), key=lambda x: -x[1])[:8]:
        print(f"STAGE {seconds:7.2f} s  {stage}", flush=True)
    print("RESULT=" + json.dumps({k: round(v, 3) for k, v in results.items()}), flush=True)
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(setup, first_interval=0.5)
