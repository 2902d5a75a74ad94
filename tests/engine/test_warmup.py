"""`python -m virtual_reflections.warmup` (run by tools/setup-env): every compiled kernel is
cached ahead of time, so a real map afterwards compiles nothing (issue 42: the first Generate
of tools/render-sample took 10.6 s compiling)."""

import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
PLATE = ROOT / "sample_scenes/plates/courtyard.jpg"


def run(*args, cache):
    env = {k: v for k, v in os.environ.items() if k != "VR_GATHER"}
    env["NUMBA_CACHE_DIR"] = str(cache)
    return subprocess.run(
        [sys.executable, *map(str, args)], cwd=ROOT, env=env, capture_output=True, text=True,
        timeout=900,
    )


def test_warmup_caches_every_kernel_a_map_uses(tmp_path):
    pytest.importorskip("numba")  # requirements/*.txt install it: CI runs this
    cache = tmp_path / "cache"
    r = run("-m", "virtual_reflections.warmup", cache=cache)
    assert r.returncode == 0, r.stderr
    listed = run(
        "-c", "from virtual_reflections import warmup; print(*warmup.compiled_kernels())",
        cache=cache,
    )
    kernels = listed.stdout.split()
    assert len(kernels) >= 7, listed.stdout + listed.stderr
    assert f"{len(kernels)} kernels cached" in r.stdout
    files = {p.name for p in cache.rglob("*") if p.is_file()}
    assert all(any(f.startswith(f"kernels.{k}-") for f in files) for k in kernels), files

    # A real map of every method, on a real plate: nothing new compiled into the cache.
    script = (
        "import sys, numpy as np; from virtual_reflections import Params, environment_map;"
        "from virtual_reflections.imagefiles import read_plate;"
        "plate = read_plate(sys.argv[1]).pixels;"
        "box = (500, 300, 780, 600);"
        "environment_map(plate, box, Params(method='camera', hfov=60.0), size=256);"
        "environment_map(plate, box, Params(method='paper', triangles=64), size=256);"
        "environment_map(plate, box, Params(method='ground', hfov=60.0, ground=(0, -0.5, 6, 1),"
        " up=(0, 1, 0)), size=256)"
    )
    env_run = run("-c", script, PLATE, cache=cache)
    assert env_run.returncode == 0, env_run.stderr[-2000:]
    after = {p.name for p in cache.rglob("*") if p.is_file()}
    assert after == files, sorted(after - files)


def test_warmup_without_the_compiled_back_end_says_so(tmp_path):
    env = dict(os.environ, VR_GATHER="numpy")
    r = subprocess.run([sys.executable, "-m", "virtual_reflections.warmup"], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "nothing to compile" in r.stdout, r.stdout + r.stderr
