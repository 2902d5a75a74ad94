"""Camera View against the paper's method, in the same run: a 1920 x 1080 plate -> a
1024 x 512 lat-long, medians of --repeat runs.

    .venv/bin/python -m benchmarks.camera_bench [--repeat 5]

Cases: a new camera (table built), the object moved (the paper builds a new table, Camera View
reuses its camera's), a new frame (the table applied to a new plate).
"""

import argparse
import statistics
import time

import numpy as np

from virtual_reflections import Params, environment_map
from virtual_reflections.table import _camera_table, lookup_table

BOX = (800.0, 400.0, 1100.0, 700.0)


def timed(plate, box, params):
    t = time.perf_counter()
    environment_map(plate, box, params, "latlong", 1024)
    return 1000 * (time.perf_counter() - t)


def measure(params, plate, repeat):
    cold, moved, frame = [], [], []
    for i in range(repeat):
        lookup_table.cache_clear()
        _camera_table.cache_clear()
        cold.append(timed(plate, BOX, params))
        box = (BOX[0] + 10 * (i + 1), BOX[1], BOX[2] + 10 * (i + 1), BOX[3])
        moved.append(timed(plate, box, params))
        other = plate[::-1].copy()
        frame.append(timed(other, box, params))
    return [statistics.median(x) for x in (cold, moved, frame)]


def main():
    p = argparse.ArgumentParser(allow_abbrev=False)
    p.add_argument("--repeat", type=int, default=5)
    args = p.parse_args()
    plate = np.random.default_rng(1).random((1080, 1920, 3), dtype=np.float32)
    rows = {
        "paper (2004)": measure(Params(), plate, args.repeat),
        "camera view": measure(Params(method="camera", hfov=50.0), plate, args.repeat),
    }
    print(f"{'method':<14} {'new camera':>11} {'moved':>9} {'new frame':>10}   (ms, medians)")
    for name, (cold, moved, frame) in rows.items():
        print(f"{name:<14} {cold:11.0f} {moved:9.0f} {frame:10.0f}")
    (pc, pm, pf), (cc, cm, cf) = rows.values()
    print(f"camera / paper: new camera {cc / pc:.2f}, moved {cm / pm:.2f}, new frame {cf / pf:.2f}")


if __name__ == "__main__":
    main()
