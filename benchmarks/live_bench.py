"""Benchmark: live update driven the way a drag drives it (issue 6).

A 1920 x 1080 8-bit plate, a UV sphere of 99,602 vertices, map resolution 1024 (Replace). Each
step of the drag moves the sphere a little (a few plate pixels, so its bounds change and a new
lookup table is needed every step), lets Blender evaluate the depsgraph and call the
depsgraph_update_post handler (``view_layer.update()``), then runs the timer callback
(``live.tick``) as Blender would on its next turn. Printed:

- rebuilds per second during the drag: steps / wall time of the whole step (move, depsgraph,
  handler, timer: bounds, small table, gather, image), and medians per stage;
- the same drag rebuilding the full 1024 x 512 map every step (no small map while moving);
- the full map once the object rests (the timer's second pass);
- an unrelated edit (another object moved) and a move too small to change the rounded bounds.

    .venv/bin/python benchmarks/live_bench.py [--steps 90] [--surroundings WORLD]
    .venv313/bin/python benchmarks/live_bench.py
"""

import argparse
import math
import os
import pathlib
import platform
import statistics
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from generate_bench import load_addon, scene_with_object, world_hdri  # noqa: E402


def build_scene(generate, method="CAMERA", surroundings="AUTO", sky_texture=None):
    """generate_bench's shot (a 100k-vertex sphere, a 1080p plate, 1024-wide map) plus an
    unrelated cube, its map generated and Live Update on. Surroundings WORLD: with a world
    HDRI (`world_hdri`) read in place of the guessed sky. ``sky_texture``: the panel's Sky
    Texture (None: the add-on's default)."""
    scene, obj = scene_with_object()
    bpy.ops.mesh.primitive_cube_add(location=(4.0, 2.0, 0.0))
    other = bpy.context.active_object
    settings = scene.virtual_reflections
    settings.method = method
    settings.surroundings = surroundings
    if sky_texture is not None:
        settings.sky_texture = sky_texture
    if surroundings == "WORLD":
        world_hdri(scene)
    settings.combine = "REPLACE"
    report = generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [obj])
    assert report.done, report.warnings
    settings.live_update = True
    bpy.context.view_layer.update()
    return scene, obj, other


def drag(live, obj, steps, full, start=0):
    """Move ``obj`` along a small circle, one step at a time; returns (seconds per step,
    reports)."""
    times, reports = [], []
    for i in range(start, start + steps):
        t = time.perf_counter()
        obj.location.x = 0.6 * math.sin(0.05 * i)
        obj.location.z = 0.5 + 0.3 * math.cos(0.05 * i)
        bpy.context.view_layer.update()  # depsgraph + our handler
        live._state.last_pass = 0.0  # as if the timer's rate limit had passed
        if full:
            reports.append(live.flush(full=True))
        else:
            live.tick()
            reports.append(live._state.last_report)
        times.append(time.perf_counter() - t)
    return times, reports


def stages(reports):
    keys = [k for k in ("plate", "bounds", "table", "gather", "image") if k in reports[-1].timings]
    return ", ".join(
        f"{k} {1000 * statistics.median(r.timings.get(k, 0.0) for r in reports):.1f}" for k in keys
    )


def main():
    parser = argparse.ArgumentParser(allow_abbrev=False)
    parser.add_argument("--steps", type=int, default=90)
    parser.add_argument("--method", choices=("GROUND", "CAMERA", "PAPER"), default="GROUND")
    parser.add_argument("--surroundings", choices=("AUTO", "WORLD"), default="AUTO")
    parser.add_argument("--sky-texture", type=float, help="the panel's (default: the add-on's)")
    args = parser.parse_args()
    addon = load_addon()
    try:
        generate = sys.modules[addon.__name__ + ".operators.generate"]
        live = sys.modules[addon.__name__ + ".operators.live"]
        scene, obj, other = build_scene(generate, args.method, args.surroundings, args.sky_texture)
        print(
            f"Blender {bpy.app.version_string}, Python {platform.python_version()}, "
            f"NumPy {np.__version__}, {os.cpu_count()} cores; sphere {len(obj.data.vertices)} "
            f"vertices; plate 1920x1080 8-bit; map 1024x512, moving {live.MOVING_WIDTH}x"
            f"{live.MOVING_WIDTH // 2}; method {args.method}, surroundings {args.surroundings}, "
            f"sky texture {scene.virtual_reflections.sky_texture:g}"
        )
        drag(live, obj, 10, full=False, start=1000)  # warm up: reduced plate, pyramids, caches
        times, reports = drag(live, obj, args.steps, full=False)
        done = sum(len(r.done) for r in reports)
        total = sum(times)
        print(
            f"  drag, small map while moving : {done} rebuilds in {total:.2f} s = "
            f"{done / total:5.1f} rebuilds/s; median step {1000 * statistics.median(times):.1f} "
            f"ms ({stages(reports)} ms)"
        )
        t = time.perf_counter()
        live._state.last_change -= live.REST
        live.tick()
        rest = time.perf_counter() - t
        print(
            f"  at rest, full map            : {1000 * rest:6.1f} ms "
            f"({stages([live._state.last_report])} ms)"
        )
        times, reports = drag(live, obj, max(10, args.steps // 6), full=True, start=5000)
        done = sum(len(r.done) for r in reports)
        print(
            f"  drag, full map every step    : {done / sum(times):5.1f} rebuilds/s; median step "
            f"{1000 * statistics.median(times):.1f} ms ({stages(reports)} ms)"
        )
        quiet = []
        for i in range(20):
            t = time.perf_counter()
            other.location.y = 2.0 + 0.01 * i  # an object without a reflection
            bpy.context.view_layer.update()
            live.tick()
            quiet.append(time.perf_counter() - t)
        print(f"  unrelated edit               : {1000 * statistics.median(quiet):6.2f} ms a step")
        quiet = []
        for _ in range(20):
            t = time.perf_counter()
            obj.location.y += 1e-6  # far below a plate pixel
            bpy.context.view_layer.update()
            live._state.last_pass = 0.0
            live.tick()
            quiet.append(time.perf_counter() - t)
        print(f"  bounds unchanged (rounded)   : {1000 * statistics.median(quiet):6.2f} ms a step")
    finally:
        addon.unregister()  # the bpy 4.5 module hangs at exit while classes stay registered


if __name__ == "__main__":
    main()
