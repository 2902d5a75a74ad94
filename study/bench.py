"""`python -m study bench`: median timings and a peer measured in the same run.

Figures: building the lookup table and applying it, for a 1920x1080 plate to a 1024x512
lat-long and to 6 x 512^2 cube faces; the peer is py360convert's `c2e` turning the same
plate's cube faces into a 1024x512 lat-long (warm: its sampler cache filled by a first
call). The machine is shared and noisy, so the figure that matters is the ratio of our
apply to the peer's c2e, measured in the same run with interleaved repetitions.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from virtual_reflections.envmap import apply_table
from virtual_reflections.params import Params
from virtual_reflections.segmentation import segment
from virtual_reflections.table import build_table

PLATE_W, PLATE_H = 1920, 1080
BBOX = (760.0, 400.0, 1160.0, 760.0)


def _plate() -> np.ndarray:
    """A deterministic 1920x1080 scene-linear test plate with detail at every scale."""
    rng = np.random.default_rng(2004)
    y, x = np.mgrid[0:PLATE_H, 0:PLATE_W].astype(np.float32)
    base = np.stack([x / PLATE_W, y / PLATE_H, 0.5 + 0.5 * np.sin(x / 37.0) * np.cos(y / 23.0)], -1)
    return (base + 0.1 * rng.random((PLATE_H, PLATE_W, 3), dtype=np.float32)).astype(np.float32)


def median_ms(fn, repeat: int = 3) -> float:
    """The median wall time of `repeat` calls of `fn`, in milliseconds."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1000.0 * float(np.median(times))


def _peer():
    try:
        import py360convert
        from py360convert import utils
    except ImportError:
        return None, "py360convert not installed (pip install py360convert)"
    backend = "cv2.remap" if getattr(utils, "cv2", None) is not None else "scipy map_coordinates"
    return py360convert, f"py360convert {getattr(py360convert, '__version__', '')} ({backend})"


def run_sweep(path: str, repeat: int = 7) -> dict:
    """Apply time against map size, ours and the peer's, in one run; charted into `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plate = _plate()
    seg = segment(PLATE_W, PLATE_H, BBOX, Params())
    p360, peer_name = _peer()
    widths = (256, 512, 1024, 2048)
    rows = {"build": [], "apply": [], "peer": []}
    for width in widths:
        face = width // 4
        cube = apply_table(build_table(seg, "cube", face), plate)
        faces = [cube[i * face : (i + 1) * face] for i in range(6)]
        table = build_table(seg, "latlong", width)
        rows["build"].append(median_ms(lambda t=width: build_table(seg, "latlong", t), 3))
        rows["apply"].append(median_ms(lambda t=table: apply_table(t, plate), repeat))
        if p360 is not None:
            p360.c2e(faces, width // 2, width, cube_format="list")
            rows["peer"].append(
                median_ms(
                    lambda f=faces, w=width: p360.c2e(f, w // 2, w, cube_format="list"), repeat
                )
            )
        print(
            f"  lat-long {width:5d} x {width // 2:4d}: build {rows['build'][-1]:7.1f} ms, "
            f"apply {rows['apply'][-1]:7.1f} ms"
            + (f", peer c2e {rows['peer'][-1]:7.1f} ms" if rows["peer"] else "")
        )
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    ax.plot(widths, rows["apply"], "o-", label="ours: apply table (plate -> lat-long)")
    ax.plot(widths, rows["build"], "s--", label="ours: build table (once per bounds)")
    if rows["peer"]:
        ax.plot(widths, rows["peer"], "^-", label=f"peer: {peer_name} c2e (cube -> lat-long)")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(widths, [f"{w}x{w // 2}" for w in widths])
    ax.set_xlabel("lat-long map size")
    ax.set_ylabel("median time (ms)")
    ax.set_title(f"1920x1080 plate, {os.cpu_count()} cores, medians of {repeat}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    print(f"wrote {path}")
    return rows


def run_bench(repeat: int = 15) -> dict:
    """Print and return the figures (milliseconds, medians over `repeat` runs)."""
    plate = _plate()
    seg = segment(PLATE_W, PLATE_H, BBOX, Params())
    figures = {}
    tables = {}
    for layout, size in (("latlong", 1024), ("cube", 512)):
        tables[layout] = build_table(seg, layout, size)
        figures[f"build {layout}"] = median_ms(
            lambda layout=layout, size=size: build_table(seg, layout, size), max(3, repeat // 3)
        )
    faces_strip = apply_table(tables["cube"], plate)
    faces = [faces_strip[i * 512 : (i + 1) * 512] for i in range(6)]
    # Our cube strip is OpenEXR-ordered; the peer's list order is F R B L U D. Orientation
    # does not change its cost, so the faces are passed as they are.
    p360, peer_name = _peer()
    if p360 is not None:
        p360.c2e(faces, 512, 1024, cube_format="list")  # warm its cached sampler
    ours, peer = [], []
    for _ in range(repeat):  # interleaved, so both see the same machine load
        t = time.perf_counter()
        apply_table(tables["latlong"], plate)
        ours.append(time.perf_counter() - t)
        if p360 is not None:
            t = time.perf_counter()
            p360.c2e(faces, 512, 1024, cube_format="list")
            peer.append(time.perf_counter() - t)
    figures["apply latlong"] = 1000.0 * float(np.median(ours))
    figures["apply cube"] = median_ms(lambda: apply_table(tables["cube"], plate), repeat)
    if peer:
        figures["peer c2e"] = 1000.0 * float(np.median(peer))
        figures["ratio"] = figures["apply latlong"] / figures["peer c2e"]

    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, NumPy {np.__version__}"
    )
    print(f"plate {PLATE_W}x{PLATE_H}, bbox {BBOX}, medians of {repeat} runs")
    print(f"  build table, 1024x512 lat-long : {figures['build latlong']:8.1f} ms")
    print(f"  build table, 6x512^2 cube      : {figures['build cube']:8.1f} ms")
    print(f"  apply table, 1024x512 lat-long : {figures['apply latlong']:8.1f} ms")
    print(f"  apply table, 6x512^2 cube      : {figures['apply cube']:8.1f} ms")
    if peer:
        print(f"  peer: {peer_name} c2e cube->1024x512 (warm): {figures['peer c2e']:8.1f} ms")
        print(f"  ratio ours/peer (apply lat-long / c2e): {figures['ratio']:.2f}  (target <= 1.00)")
    else:
        print(f"  peer: {peer_name}")
    return figures
