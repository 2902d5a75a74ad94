"""Benchmark: finding the floor under the reflective objects (operators/scene/floor.py), which
Camera View + Ground does at every Generate and every Live Update rebuild.

    .venv/bin/python benchmarks/floor_bench.py [--objects 3000] [--repeat 20]

A scene of N cubes on a grid (none under the sphere), a ground plane and a sphere floating
over it. Prints the median time of `floor.floor_under` and, as its peer in the same run, of the
scan for a shadow catcher that `floor.ground_of` already made before it (one pass over the
scene's objects, reading one property each), and their ratio.
"""

import argparse
import pathlib
import statistics
import sys
import time

import bpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from generate_bench import load_addon  # noqa: E402


def median_ms(call, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        call()
        times.append(time.perf_counter() - t0)
    return 1000.0 * statistics.median(times)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("--objects", type=int, default=3000)
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    addon = load_addon()
    try:
        floor = sys.modules[f"{addon.__name__}.operators.scene.floor"]
        bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
        scene = bpy.context.scene
        cube = bpy.data.meshes.new("Cube")
        cube.from_pydata(
            [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)],
            [],
            [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
        )
        for i in range(args.objects):
            obj = bpy.data.objects.new(f"Cube {i}", cube)
            obj.location = (3 + 2 * (i % 60), 3 + 2 * (i // 60), 0)
            scene.collection.objects.link(obj)
        bpy.ops.mesh.primitive_plane_add(size=500.0)
        ground = bpy.context.active_object
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 0.0, 1.5))
        ball = bpy.context.active_object
        depsgraph = bpy.context.evaluated_depsgraph_get()
        assert floor.floor_under(scene, depsgraph, [ball]) == ground

        def catcher_scan():
            return next((o for o in scene.objects if o.is_shadow_catcher), None)

        found = median_ms(lambda: floor.floor_under(scene, depsgraph, [ball]), args.repeat)
        scan = median_ms(catcher_scan, args.repeat)
        count = len(scene.objects)
        print(
            f"Blender {bpy.app.version_string}, {count} objects, medians of {args.repeat}:\n"
            f"  floor_under        : {found:7.2f} ms ({1000 * found / count:.2f} us an object)\n"
            f"  shadow-catcher scan: {scan:7.2f} ms ({1000 * scan / count:.2f} us an object)\n"
            f"  ratio              : {found / scan:.1f}x"
        )
    finally:
        addon.unregister()


if __name__ == "__main__":
    main()
