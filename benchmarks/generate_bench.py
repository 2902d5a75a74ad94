"""Benchmark: Generate Virtual Reflection end to end in Blender (bpy module).

One object of ~100k vertices standing on the ground 8 m in front of a camera at 1.6 m, a
1920x1080 plate, a 1024x512 map (or --plate 4k: a 3840x2160 plate; --resolution AUTO: the
map width the add-on picks for the object's size on screen, 4096 for this one on a 4K plate).
Per method (each --method given, in the same run) prints medians per stage for the first
generation with a new lens (a new camera: every table built), of a moved object (the paper's
method builds its table; Camera View's is the camera's) and for a regeneration of an
unchanged pose (the cached table: only the gather), the end-to-end time of the operator
call, and each method's moved-pose time against the first method's.

    .venv/bin/python benchmarks/generate_bench.py [--repeat N] [--method camera ground ...]
        [--plate 1080p|4k] [--resolution 1024|AUTO|...]
"""

import argparse
import importlib.util
import math
import pathlib
import statistics
import sys
import time

import bpy
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]


def load_addon():
    spec = importlib.util.spec_from_file_location(
        "vr_bench_addon", ROOT / "__init__.py", submodule_search_locations=[str(ROOT)]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    module.register()
    return module


PLATES = {"1080p": (1920, 1080), "4k": (3840, 2160)}


def scene_with_object(width=1920, height=1080, resolution="1024"):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location = (0.0, -8.0, 1.6)
    cam.rotation_euler = (math.radians(80), 0.0, 0.0)
    scene.render.resolution_x, scene.render.resolution_y = width, height
    bpy.ops.mesh.primitive_uv_sphere_add(
        segments=400, ring_count=250, radius=1.5, location=(0.0, 0.0, 1.5)
    )
    obj = bpy.context.active_object
    plate = bpy.data.images.new("Plate", width, height, alpha=False, float_buffer=False)
    rng = np.random.default_rng(1)
    px = np.ones((height, width, 4), np.float32)
    px[..., :3] = rng.random((height, width, 3), dtype=np.float32)
    plate.pixels.foreach_set(px.ravel())
    scene.virtual_reflections.plate_image = plate
    scene.virtual_reflections.resolution = resolution
    obj.select_set(True)
    return scene, obj


def world_hdri(scene):
    """One of Blender's bundled HDRIs (1024 x 512) as the scene's world, turned 30 degrees."""
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    world = bpy.data.worlds.new("On Set")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(pathlib.Path(folder) / "courtyard.exr"))
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30))
    tree.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    tree.links.new(env.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    scene.world = world


CASES = {
    "lens": "new lens (every table built)",
    "moved": "object moved",
    "same": "unchanged (cached)",
}


def measure(generate, obj, repeat, method):
    """Print the stage medians of ``method``; returns the moved pose's median seconds.

    Cases: a new focal length (a new camera: every table is built, Camera View's too), the
    object moved (the paper's method builds a new table; Camera View's is the camera's), and
    an unchanged pose (the cached table)."""
    rows = {case: [] for case in CASES}
    ends = {case: [] for case in CASES}
    camera = bpy.context.scene.camera.data
    lens = camera.lens
    for i in range(repeat):
        for case in CASES:
            if case == "lens":
                camera.lens = lens + 0.05 * (i + 1)
                bpy.context.view_layer.update()
            if case == "moved":
                shift = 0.5 if method in ("ground", "world", "flat") else 0.0
                obj.location.x = 0.01 * (i + 1) + shift
                bpy.context.view_layer.update()
            t = time.perf_counter()
            report = generate.generate(
                bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [obj]
            )
            ends[case].append(time.perf_counter() - t)
            rows[case].append(report.timings)
    camera.lens = lens
    print(f"{method}:")
    for case, label in CASES.items():
        stages = rows[case][0].keys()
        parts = ", ".join(
            f"{s} {1000 * statistics.median(r.get(s, 0.0) for r in rows[case]):.1f}" for s in stages
        )
        print(
            f"  {label:28s}: median {1000 * statistics.median(ends[case]):6.1f} ms end to end"
            f"  ({parts} ms)"
        )
    return statistics.median(ends["moved"])


def main():
    parser = argparse.ArgumentParser(allow_abbrev=False)
    parser.add_argument("--repeat", type=int, default=9)
    parser.add_argument(
        "--method",
        nargs="+",
        default=["camera", "ground"],
        choices=("camera", "ground", "paper", "world", "flat"),
        help="world: Camera View + Ground with Surroundings World HDRI (a bundled HDRI); flat: "
        "Camera View + Ground with Sky Texture 0 (the flat unseen sky)",
    )
    parser.add_argument("--plate", default="1080p", choices=sorted(PLATES))
    parser.add_argument("--resolution", default="1024", help="1024, AUTO, ... (the panel's)")
    args = parser.parse_args()
    addon = load_addon()
    generate = sys.modules[addon.__name__ + ".operators.generate"]
    width, height = PLATES[args.plate]
    scene, obj = scene_with_object(width, height, args.resolution.upper())
    generate.generate(bpy.context.scene, bpy.context.evaluated_depsgraph_get(), [obj])
    made = next(i for i in bpy.data.images if i.name != "Plate")
    print(
        f"Blender {bpy.app.version_string}; object {len(obj.data.vertices)} vertices; "
        f"plate {width}x{height} 8-bit; map {made.size[0]}x{made.size[1]} "
        f"(resolution {args.resolution})"
    )
    first = None
    texture = scene.virtual_reflections.sky_texture  # the add-on's default
    world_hdri(scene)
    for method in args.method:
        settings = scene.virtual_reflections
        settings.method = "GROUND" if method in ("world", "flat") else method.upper()
        settings.surroundings = "WORLD" if method == "world" else "AUTO"
        settings.sky_texture = 0.0 if method == "flat" else texture
        moved = measure(generate, obj, args.repeat, method)
        first = first or moved
        print(f"  {method}: moved pose {moved / first:.2f}x the {args.method[0]} method's")
    t = time.perf_counter()
    bpy.ops.vr.generate()
    print(f"  operator call (cached)      : {1000 * (time.perf_counter() - t):6.1f} ms")
    addon.unregister()  # the bpy 4.5 module hangs at exit while classes stay registered


if __name__ == "__main__":
    main()
