"""Benchmark: a saved map, Blender's ``Image.save`` (before issue 12) vs the engine's EXR.

A smooth 2048 x 1024 lat-long map (values up to 4) is written both ways; printed per file:
size, pixel type, compression, the colour space OpenImageIO reads, the texture format (the
``envmap`` attribute), and the largest difference between the file's values and the map's
scene-linear values; then the median time of `maps.store_map` into a folder.

    .venv/bin/python benchmarks/map_file_bench.py [--runs 5]
    .venv313/bin/python benchmarks/map_file_bench.py
"""

import argparse
import os
import statistics
import sys
import tempfile
import time

import bpy
import numpy as np
import OpenImageIO as oiio

sys.path.insert(
    0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "blender")
)
from shots import addon_part  # noqa: E402

maps = addon_part("operators.scene.maps")
images = addon_part("operators.scene.images")


def describe(path, env):
    h, w = env.shape[:2]
    image = oiio.ImageInput.open(path)
    spec = image.spec()
    pixels = np.asarray(image.read_image(0, 0, 0, 3, "float")).reshape(h, w, 3)
    image.close()
    print(
        f"{bpy.app.version_string:12} {os.path.basename(path):18} "
        f"{os.path.getsize(path) / 1e6:6.1f} MB {str(spec.format):5} "
        f"{spec.getattribute('compression') or 'none':5} "
        f"{spec.getattribute('oiio:ColorSpace')!s:20} {spec.getattribute('textureformat')!s:20} "
        f"max |file - map| {float(np.abs(pixels - env).max()):.2g}"
    )


def main():
    parser = argparse.ArgumentParser(allow_abbrev=False)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    bpy.ops.wm.read_homefile(use_empty=True)
    w, h = 2048, 1024
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    env = np.stack([x / w * 4, y / h, 0.2 + 0.05 * np.sin(x / 7)], -1).astype(np.float32)
    with tempfile.TemporaryDirectory() as out:
        old = images.own_image("old", w, h, "map")
        images.write_pixels(old, env)
        old.file_format = "OPEN_EXR"
        old.filepath_raw = os.path.join(out, "image_save.exr")
        old.save()
        describe(old.filepath_raw, env)
        seconds = []
        for _ in range(args.runs):
            t = time.perf_counter()
            maps.store_map("VR Map new", env, out)
            seconds.append(time.perf_counter() - t)
        describe(os.path.join(out, "VR_Map_new.exr"), env)
        print(
            f"store_map into a folder: median {statistics.median(seconds):.3f} s ({args.runs} runs)"
        )


if __name__ == "__main__":
    main()
