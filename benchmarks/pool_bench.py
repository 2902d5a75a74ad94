"""Benchmark: the engine's blocks of rows (`parallel.for_blocks`, its own daemon threads)
against the standard library's ThreadPoolExecutor doing the same blocks, in the same run.

The work is the map image's copy into Blender's layout (operators/scene/images.py
`_rgba_bottom_up`): rows bottom-up, alpha 1, channel by channel, in blocks of 8-16 rows,
on maps of 1024 x 512 (resolution 1024) and 4096 x 2048. Printed: the median of each, and
the ratio of for_blocks to the executor.

    .venv/bin/python benchmarks/pool_bench.py [--repeat 41]
"""

import argparse
import os
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from virtual_reflections import parallel  # noqa: E402


def executor_blocks(pool, fn, rows, min_rows, max_rows):
    """The same blocks as for_blocks, handed to a ThreadPoolExecutor (one future each)."""
    n = min(parallel.workers(), max(1, rows // min_rows))
    count = max(n, -(-rows // max_rows))
    bounds = [rows * i // count for i in range(count + 1)]
    for future in [pool.submit(fn, a, b) for a, b in zip(bounds, bounds[1:])]:
        future.result()


def copy_rows(pixels, rgba):
    h = pixels.shape[0]

    def rows(a, b):
        dst, src = rgba[a:b], pixels[h - b : h - a][::-1]
        dst[..., 3] = 1.0
        for c in range(3):
            dst[..., c] = src[..., c]

    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    p.add_argument("--repeat", type=int, default=41)
    args = p.parse_args()
    print(
        f"{parallel.workers()} threads (VR_THREADS overrides); {args.repeat} runs each, interleaved"
    )
    with ThreadPoolExecutor(max_workers=parallel.workers()) as pool:
        for w, h in ((1024, 512), (4096, 2048)):
            pixels = np.random.default_rng(0).random((h, w, 3), dtype=np.float32)
            rgba = np.empty((h, w, 4), np.float32)
            rows = copy_rows(pixels, rgba)
            runs = {"for_blocks": [], "ThreadPoolExecutor": []}
            repeat = args.repeat if h <= 512 else max(5, args.repeat // 4)
            for _ in range(repeat + 1):  # the first of each warms up (threads, pages)
                started = time.perf_counter()
                parallel.for_blocks(rows, h, min_rows=8, max_rows=16)
                runs["for_blocks"].append(time.perf_counter() - started)
                started = time.perf_counter()
                executor_blocks(pool, rows, h, 8, 16)
                runs["ThreadPoolExecutor"].append(time.perf_counter() - started)
            medians = {k: statistics.median(v[1:]) * 1e3 for k, v in runs.items()}
            print(
                f"{w} x {h}: for_blocks {medians['for_blocks']:.2f} ms, "
                f"ThreadPoolExecutor {medians['ThreadPoolExecutor']:.2f} ms, "
                f"ratio {medians['for_blocks'] / medians['ThreadPoolExecutor']:.2f}"
            )


if __name__ == "__main__":
    main()
