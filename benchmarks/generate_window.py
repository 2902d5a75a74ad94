"""How long Generate holds Blender's window on a 4K plate: the blocking run (a script's
EXEC_DEFAULT, as before) against the run from the button (INVOKE_DEFAULT: steps on a timer,
the engine's work in a thread). A timer ticking every 10 ms measures the longest gap between
two ticks, i.e. the longest time the window could not draw.

    xvfb-run -a blender --factory-startup --python benchmarks/generate_window.py -- .

Prints one line per run; the figures are in docs/benchmarks.md."""

import importlib
import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from window_probe import Ticker, load_addon, view3d_context, window_figures  # noqa: E402

root = sys.argv[sys.argv.index("--") + 1]
generate = load_addon(root)
lookup_table = importlib.import_module("vr_bench_addon.virtual_reflections").lookup_table
ticker = Ticker(generate)
results = {}


def setup():
    scene = bpy.context.scene
    bpy.data.objects.remove(bpy.data.objects["Cube"])
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1)
    bpy.data.objects["Sphere"].select_set(True)
    plate = bpy.data.images.new("Plate 4K", 3840, 2160)
    rng = np.random.default_rng(0)
    plate.pixels.foreach_set(rng.random(3840 * 2160 * 4, dtype=np.float32))
    scene.virtual_reflections.plate_image = plate
    scene.virtual_reflections.resolution = "4096"
    scene.render.resolution_x, scene.render.resolution_y = 3840, 2160
    ticker.start()
    bpy.app.timers.register(blocking, first_interval=0.5)


def blocking():
    lookup_table.cache_clear()
    started = time.perf_counter()
    with view3d_context():
        bpy.ops.vr.generate("EXEC_DEFAULT")
    results["blocking_total_s"] = time.perf_counter() - started
    bpy.ops.vr.remove()
    bpy.app.timers.register(lambda: measure_blocking(started), first_interval=0.1)


def measure_blocking(started):
    results["blocking_longest_gap_s"] = ticker.longest_gap(started - 0.02)
    lookup_table.cache_clear()
    results["_started"] = time.perf_counter()
    with view3d_context():
        bpy.ops.vr.generate("INVOKE_DEFAULT")
    bpy.app.timers.register(wait, first_interval=0.05)


def wait():
    if generate.running() is not None:
        return 0.05
    started = results.pop("_started")
    window_figures(results, ticker, started)
    seen = [(t, st) for t, st in ticker.stages if t >= started]
    gaps = [(b[0] - a[0], a[1]) for a, b in zip(seen, seen[1:], strict=False)]
    print("LONGEST GAP AFTER STAGE", max(gaps, key=lambda g: g[0])[1], flush=True)
    print("RESULT=" + json.dumps({k: round(v, 3) for k, v in results.items()}), flush=True)
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(setup, first_interval=0.5)
