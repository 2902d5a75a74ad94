"""Compile the optional kernels (kernels.py, Numba) ahead of time, into the user's cache.

A first map in a fresh environment compiles every kernel it meets (about 10 s); later
processes load them from the cache (backends.cache_folder()). `tools/setup-env` runs this
once after installing Numba, so the first Generate of `tools/render-sample` or of a test run
does not pay it. Every kernel is reached through the engine's own calls, on small inputs of
the dtypes real maps use (a kernel compiled for other dtypes would be compiled again).

    python -m virtual_reflections.warmup      # prints the kernels cached; exit 1 if one failed

Without Numba there is nothing to compile: it says so and exits 0.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

from . import backends
from .envmap import environment_map
from .mipmap import build_pyramid
from .params import Params


def _maps() -> None:
    """One small map per table kind: every kernel a map of any method runs."""
    rng = np.random.default_rng(0)
    plate = rng.random((48, 64, 3), dtype=np.float32)
    bbox = (20, 14, 44, 34)
    environment_map(plate, bbox, Params(method="camera", hfov=60.0), size=64)
    environment_map(plate, bbox, Params(method="paper", triangles=32), size=64)
    environment_map(plate, bbox, Params(method="paper"), layout="cube", size=16)
    ground = Params(method="ground", hfov=60.0, ground=(0.0, -0.5, 6.0, 1.0), up=(0.0, 1.0, 0.0))
    environment_map(plate, bbox, ground, size=64)
    build_pyramid(rng.random((50, 70, 3), dtype=np.float32), first=3)  # halving level by level


def cached_kernels() -> list[str]:
    """Names of the kernels whose compiled code is in the cache folder."""
    names = set()
    for _root, _dirs, files in os.walk(backends.cache_folder()):
        names.update(f.split(".")[1].rsplit("-", 1)[0] for f in files if f.endswith(".nbi"))
    return sorted(names)


def compiled_kernels() -> list[str]:
    """Names of the kernels kernels.py caches (its ``cache=True`` functions)."""
    module = backends.kernels()
    if module is None:
        return []
    return sorted(
        name
        for name, value in vars(module).items()
        if getattr(value, "_cache", None) is not None
        and not name.startswith("_")
        and type(value._cache).__name__ != "NullCache"
    )


def main() -> int:
    if os.environ.get("VR_GATHER", "").strip().lower() in ("numpy", "opencv"):
        print("warmup: VR_GATHER leaves the compiled kernels out; nothing to compile")
        return 0
    if backends.kernels() is None:
        print("warmup: Numba is not installed; the engine runs on NumPy, nothing to compile")
        return 0
    started = time.perf_counter()
    _maps()
    wanted, cached = compiled_kernels(), cached_kernels()
    missing = sorted(set(wanted) - set(cached))
    seconds = time.perf_counter() - started
    if missing:
        print(f"warmup: error: not cached after the warm-up: {', '.join(missing)}", file=sys.stderr)
        return 1
    print(f"warmup: {len(cached)} kernels cached in {backends.cache_folder()} ({seconds:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
