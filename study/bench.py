"""`python -m study bench`: the engine's speed and memory, with a peer measured in the same run.

Per frame (the table cached): applying the table to a 1920x1080 plate for both methods
(Paper, Camera View) at 1024 and 2048 wide lat-longs, against py360convert's `c2e` making the
same lat-long from cube faces with the fastest back end it finds (OpenCV's `remap` when
installed, else SciPy's `map_coordinates`; the line says which), and beside them the bandwidth
floor: one copy of the plate. Repetitions are interleaved, so all see the same machine load;
the ratio ours / peer is what we hold ourselves to. Ours is measured with both back ends
(virtual_reflections/backends.py), each that imports: Numba's compiled kernels (the default
then), OpenCV's remap/resize, and NumPy (VR_GATHER=numpy, what Blender runs: it bundles
neither); the line says which one the engine uses by default here.

Cold tables (new bounds or camera): building the table from a 3840x2160 plate for 2048 and
4096 wide lat-longs, its time, its bytes per texel and the peak memory while building
(tracemalloc, which NumPy reports to; measured in a separate run from the time).

`run_sweep` charts time and memory (the cached table's bytes and the plate's mip pyramid,
kept with the plate) against map width (256 .. 4096) and plate size (1080p, 4K, 8K), ours
against the peer.
"""

from __future__ import annotations

import gc
import os
import platform
import time
import tracemalloc

import numpy as np

from virtual_reflections.backends import available_backends, backend
from virtual_reflections.cache import nbytes
from virtual_reflections.envmap import apply_table
from virtual_reflections.mipmap import pyramid_size
from virtual_reflections.params import Params
from virtual_reflections.segmentation import segment
from virtual_reflections.table import build_table

PLATE_W, PLATE_H = 1920, 1080
BBOX = (760.0, 400.0, 1160.0, 760.0)  # on the 1080p plate; scaled with the plate
HFOV = 50.0
METHODS = {"paper": Params(), "camera": Params(method="camera", hfov=HFOV)}
PLATES = {"1080p": (1920, 1080), "4K": (3840, 2160), "8K": (7680, 4320)}


def _plate(width: int = PLATE_W, height: int = PLATE_H) -> np.ndarray:
    """A deterministic scene-linear test plate (H, W, 3) float32 with detail at every scale."""
    rng = np.random.default_rng(2004)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    base = np.stack(
        [x / width, y / height, 0.5 + 0.5 * np.sin(x / 37.0) * np.cos(y / 23.0)], -1
    ).astype(np.float32)
    base += 0.1 * rng.random((height, width, 3), dtype=np.float32)
    return base


def _bbox(width: int) -> tuple:
    s = width / PLATE_W
    return tuple(v * s for v in BBOX)


def _table(method: str, width: int, height: int, size: int):
    params = METHODS[method]
    return build_table(segment(width, height, _bbox(width), params), "latlong", size, params)


def median_ms(fn, repeat: int = 3) -> float:
    """The median wall time of `repeat` calls of `fn`, in milliseconds."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return 1000.0 * float(np.median(times))


def peak_mb(fn) -> float:
    """The peak memory (MB, tracemalloc: NumPy's arrays included) that `fn` allocates."""
    gc.collect()
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def _peer():
    """(py360convert or None, a line naming it and its back end)."""
    try:
        import py360convert
        from py360convert import utils
    except ImportError:
        return None, "py360convert not installed (pip install py360convert)"
    backend = (
        "OpenCV remap"
        if getattr(utils, "cv2", None) is not None
        else "SciPy map_coordinates (install opencv-python-headless for its fast back end)"
    )
    return py360convert, f"py360convert {getattr(py360convert, '__version__', '')} c2e, {backend}"


def _peer_call(p360, plate: np.ndarray, size: int):
    """A warm call of the peer making a size x size/2 lat-long from 6 faces of size/4
    (cut from the plate: their content does not change the cost)."""
    face = size // 4
    faces = [np.ascontiguousarray(plate[:face, :face])] * 6
    p360.c2e(faces, size // 2, size, cube_format="list")  # fills its cached sampler
    return lambda: p360.c2e(faces, size // 2, size, cube_format="list")


def _set_gather(value) -> None:
    """VR_GATHER for the next call ("numpy": the NumPy back end; "" or None: the default)."""
    if value:
        os.environ["VR_GATHER"] = value
    else:
        os.environ.pop("VR_GATHER", None)


def _machine() -> str:
    return (
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, NumPy {np.__version__}"
    )


def run_bench(repeat: int = 15) -> dict:
    """Print and return the figures (ms, MB; medians over `repeat` interleaved runs)."""
    print(_machine())
    p360, peer_name = _peer()
    print(f"peer: {peer_name}")
    figures = {}
    plate = _plate()
    default = backend()
    forced = os.environ.get("VR_GATHER")
    engines = [default] if forced else available_backends()
    print(
        f"engine back end: {default} by default, of {', '.join(available_backends())} "
        "(VR_GATHER=numba|opencv|numpy picks one)"
    )
    print(f"\nper frame (table cached): {PLATE_W}x{PLATE_H} plate, medians of {repeat}")
    for size in (1024, 2048):
        tables = {m: _table(m, PLATE_W, PLATE_H, size) for m in METHODS}
        calls = {  # (VR_GATHER for the call, the call)
            f"ours {m} {e}": (e, lambda t=t: apply_table(t, plate))
            for m, t in tables.items()
            for e in engines
        }
        for t in tables.values():  # a first call: the compiled kernels loaded
            for e in engines:
                _set_gather(e)
                apply_table(t, plate)
        _set_gather(forced)
        if p360 is not None:
            calls["peer"] = (forced, _peer_call(p360, plate, size))
        calls["plate copy"] = (forced, plate.copy)
        times = _rounds(calls, repeat, forced)
        ms = {k: 1000.0 * float(np.median(v)) for k, v in times.items()}
        line = ", ".join(f"{k} {v:.1f} ms" for k, v in ms.items())
        print(f"  {size}x{size // 2}: {line}")
        for m in METHODS:
            for e in engines:
                key = "" if e == default else f" {e}"
                figures[f"apply {m} {size}{key}"] = ms[f"ours {m} {e}"]
                if "peer" in ms:
                    ratio = figures[f"ratio {m} {size}{key}"] = ms[f"ours {m} {e}"] / ms["peer"]
                    # each round's own ratio: a burst of load from outside hits both calls
                    paired = np.median(np.divide(times[f"ours {m} {e}"], times["peer"]))
                    figures[f"paired {m} {size}{key}"] = float(paired)
                    print(
                        f"    ratio {m} ({e}) / peer: {ratio:.2f} (target <= 1.0); "
                        f"median of the rounds' ratios {paired:.2f}"
                    )
        figures[f"peer {size}"] = ms.get("peer")
        figures[f"copy {size}"] = ms["plate copy"]
    _cold_figures(figures, repeat)
    return figures


def _rounds(calls, repeat, forced) -> dict:
    """Time each of ``calls`` ({key: (VR_GATHER for it, the call)}) in interleaved rounds, the
    first ones not recorded; VR_GATHER back to ``forced`` after. Returns {key: [seconds]}."""
    times = {k: [] for k in calls}
    keys = list(calls)
    warm = max(3, repeat // 3)  # rounds not recorded: the first ones run slower (~20 %)
    try:
        for i in range(-warm, repeat):
            # Interleaved, every call sees the same load; the order turned by one each
            # time, so no call always follows the same one (the plate copy leaves 25 MB
            # of written cache lines that whatever runs next writes back: ~2 ms).
            for k in keys[i % len(keys) :] + keys[: i % len(keys)]:
                gather, fn = calls[k]
                _set_gather(gather)
                t = time.perf_counter()
                fn()
                if i >= 0:
                    times[k].append(time.perf_counter() - t)
    finally:
        _set_gather(forced)
    return times


def _cold_figures(figures, repeat) -> None:
    """`run_bench`'s cold tables on the 4K plate, printed and added to ``figures``: time, peak
    memory and bytes per texel per method and map width."""
    width, height = PLATES["4K"]
    print(f"\ncold table (new bounds or camera): {width}x{height} plate")
    for size in (2048, 4096):
        for m in METHODS:
            runs = max(1, repeat // (5 if size <= 2048 else 15))
            table = _table(m, width, height, size)
            per_texel = nbytes(table) / (size * size // 2)
            del table
            gc.collect()
            cold = median_ms(lambda m=m, s=size: _table(m, width, height, s), runs)
            peak = peak_mb(lambda m=m, s=size: _table(m, width, height, s))
            figures[f"cold {m} {size}"] = cold
            figures[f"peak {m} {size}"] = peak
            figures[f"bytes {m} {size}"] = per_texel
            target = 300 if size <= 2048 else 1000
            print(
                f"  {m:6s} {size}x{size // 2}: {cold:7.0f} ms (target <= {target}), "
                f"peak {peak:6.0f} MB, table {per_texel:5.1f} bytes/texel (target <= 16)"
            )


def run_sweep(path: str, repeat: int = 5, widths=(256, 512, 1024, 2048, 4096), plates=None):
    """Time and memory against map width and plate size, ours and the peer's, charted into
    `path` (PNG): per frame (apply) and cold table time, and the table's bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plates = plates or list(PLATES)
    p360, peer_name = _peer()
    rows = _sweep_rows(plates, widths, repeat, p360, peer_name)
    _chart_sweep(plt, rows, plates, widths, path, peer_name)
    print(f"wrote {path}")
    return rows


def _sweep_rows(plates, widths, repeat, p360, peer_name) -> list:
    """`run_sweep`'s measures, printed as they come: per plate and map width, each method's
    cold table and per-frame times and its table's bytes, the plate's pyramid, and the peer's
    time on the first plate (``p360``: its module, or None)."""
    rows = []
    print(_machine())
    print(f"peer: {peer_name}; ours: the {backend()} back end (VR_GATHER picks another)")
    for name in plates:
        width, height = PLATES[name]
        plate = _plate(width, height)
        for size in widths:
            row = {"plate": name, "width": size}
            if p360 is not None and name == plates[0]:
                row["peer"] = median_ms(_peer_call(p360, plate, size), repeat)
            for m in METHODS:
                runs = repeat if size <= 1024 else min(repeat, 3) if size <= 2048 else 1
                cold = lambda m=m, s=size, w=width, h=height: _table(m, w, h, s)  # noqa: E731
                row[f"cold {m}"] = median_ms(cold, runs)
                table = _table(m, width, height, size)
                row[f"mb {m}"] = nbytes(table) / 2**20
                pyramid = pyramid_size(height, width, table.levels, table.first_level) * 12
                row["pyramid mb"] = max(row.get("pyramid mb", 0.0), pyramid / 2**20)
                row[f"apply {m}"] = median_ms(lambda t=table, p=plate: apply_table(t, p), repeat)
                del table
            rows.append(row)
            print(
                f"  {name:5s} {size:4d}: "
                + ", ".join(f"{k} {v:.1f}" for k, v in row.items() if k not in ("plate", "width"))
            )
        del plate
        gc.collect()
    return rows


def _chart_sweep(plt, rows, plates, widths, path, peer_name) -> None:
    """`run_sweep`'s chart of ``rows`` into ``path``: per frame, cold table and memory against
    the map width, one line per method and plate (the peer's dotted)."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4), dpi=100)
    styles = {"1080p": "o", "4K": "s", "8K": "^"}
    for name in plates:
        mine = [r for r in rows if r["plate"] == name]
        x = [r["width"] for r in mine]
        for m, ls in (("paper", "-"), ("camera", "--")):
            axes[0].plot(
                x,
                [r[f"apply {m}"] for r in mine],
                ls,
                marker=styles[name],
                label=f"ours {m}, {name} plate",
            )
            axes[1].plot(
                x,
                [r[f"cold {m}"] for r in mine],
                ls,
                marker=styles[name],
                label=f"ours {m}, {name} plate",
            )
            axes[2].plot(
                x,
                [r[f"mb {m}"] for r in mine],
                ls,
                marker=styles[name],
                label=f"ours {m}, {name} plate",
            )
        axes[2].plot(
            x,
            [r["pyramid mb"] for r in mine],
            ":",
            marker=styles[name],
            color="grey",
            label=f"the plate's pyramid, {name} plate",
        )
        if "peer" in mine[0]:
            axes[0].plot(
                x,
                [r["peer"] for r in mine],
                "k:",
                marker="x",
                lw=2,
                label="peer: py360convert c2e (cube faces)",
            )
    titles = ("per frame (table cached)", "cold table (new bounds or camera)", "memory")
    for ax, title, unit in zip(axes, titles, ("ms", "ms", "MB")):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xticks(list(widths), [str(w) for w in widths])
        ax.set_xlabel("lat-long map width (texels)")
        ax.set_ylabel(f"median {unit}" if unit == "ms" else unit)
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[2].legend(fontsize=7)
    fig.suptitle(
        f"{os.cpu_count()} cores, NumPy {np.__version__}, ours on its {backend()} back end; "
        f"peer: {peer_name}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path)
