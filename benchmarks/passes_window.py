"""How long Render Inter-Reflections holds Blender's window: the blocking run (a script's
EXEC_DEFAULT) against the run from the button (INVOKE_DEFAULT: the maps' engine work in a
thread, each render as Blender's render job). A timer ticking every 10 ms measures the longest
gap between two ticks, i.e. the longest time the window could not draw.

    xvfb-run -a blender --factory-startup --python benchmarks/passes_window.py -- . [SAMPLES]

Two mirror spheres over a 1920 x 1080 plate, a 960 x 540 Cycles render (SAMPLES samples, 64 by
default, no denoising), 2 passes. Prints one line; the figures are in docs/benchmarks.md."""

import importlib
import importlib.util
import json
import sys
import time

import bpy
import numpy as np

args = sys.argv[sys.argv.index("--") + 1 :]
root = args[0]
samples = int(args[1]) if len(args) > 1 else 64
spec = importlib.util.spec_from_file_location(
    "vr_bench_addon", root + "/__init__.py", submodule_search_locations=[root]
)
addon = importlib.util.module_from_spec(spec)
sys.modules[spec.name] = addon
spec.loader.exec_module(addon)
addon.register()
generate = importlib.import_module("vr_bench_addon.operators.generate")

ticks = []
results = {"samples": samples}


stages = []  # (time, the stage under way) at each tick


def tick():
    ticks.append(time.perf_counter())
    job = generate.running()
    stages.append((ticks[-1], job.stage if job else None))
    return 0.01


def context():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    return bpy.context.temp_override(window=win, area=area)


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
    bpy.app.timers.register(tick, first_interval=0.01)
    bpy.app.timers.register(blocking, first_interval=0.5)


def longest_gap(since):
    t = [x for x in ticks if x >= since]
    return max(np.diff(t)) if len(t) > 1 else float("nan")


def blocking():
    started = time.perf_counter()
    with context():
        bpy.ops.vr.render_passes("EXEC_DEFAULT", passes=2)
    results["blocking_total_s"] = time.perf_counter() - started
    bpy.ops.vr.remove()
    bpy.app.timers.register(lambda: measure_blocking(started), first_interval=0.1)


def measure_blocking(started):
    results["blocking_longest_gap_s"] = longest_gap(started - 0.02)
    results["_started"] = time.perf_counter()
    with context():
        bpy.ops.vr.render_passes("INVOKE_DEFAULT", passes=2)
    bpy.app.timers.register(wait, first_interval=0.05)


def wait():
    if generate.running() is not None:
        return 0.05
    started = results.pop("_started")
    results["window_total_s"] = time.perf_counter() - started
    results["window_longest_gap_s"] = longest_gap(started)
    results["ratio_gap"] = results["blocking_longest_gap_s"] / results["window_longest_gap_s"]
    seen = [(t, st) for t, st in stages if t >= started]
    spent = {}
    for a, b in zip(seen, seen[1:], strict=False):
        spent[a[1]] = spent.get(a[1], 0.0) + b[0] - a[0]
    for stage, seconds in sorted(spent.items(), key=lambda x: -x[1])[:8]:
        print(f"STAGE {seconds:7.2f} s  {stage}", flush=True)
    print("RESULT=" + json.dumps({k: round(v, 3) for k, v in results.items()}), flush=True)
    bpy.ops.wm.quit_blender()


bpy.app.timers.register(setup, first_interval=0.5)
