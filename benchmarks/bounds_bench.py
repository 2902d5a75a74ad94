"""Benchmark: screen-space bounds of a 1,000,000-vertex mesh (bpy module).

    .venv/bin/python benchmarks/bounds_bench.py

Prints medians of 20 calls to operators.scene.bounds.object_bounds, for a grid entirely in front of
the camera and for one that straddles the near plane (its 2M edges are read and clipped).
"""

import importlib.util
import pathlib
import statistics
import time

import bpy

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    spec = importlib.util.spec_from_file_location("vr_bounds", ROOT / "operators/scene/bounds.py")
    bounds = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bounds)
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0, 0, 10)
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=999, y_subdivisions=999, size=4)
    grid = bpy.context.active_object
    print(f"Blender {bpy.app.version_string}; grid of {len(grid.data.vertices)} vertices")
    for label, z, tilt in (
        ("in front of the camera", 0.0, 0.0),
        ("straddling the near plane", 9.5, 1.5),
    ):
        grid.location.z, grid.rotation_euler.x = z, tilt
        depsgraph = bpy.context.evaluated_depsgraph_get()
        times = []
        for _ in range(20):
            t = time.perf_counter()
            box = bounds.object_bounds(grid, depsgraph, scene)
            times.append(time.perf_counter() - t)
        print(
            f"  {label:26s}: median {1000 * statistics.median(times):6.1f} ms "
            f"(visible {box.visible}, box {box.x0:.0f} {box.y0:.0f} {box.x1:.0f} {box.y1:.0f})"
        )


if __name__ == "__main__":
    main()
