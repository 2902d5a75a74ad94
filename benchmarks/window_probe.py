"""What the window benchmarks (generate_window.py, passes_window.py) share, run inside
Blender's window: the extension loaded from the checkout, a 10 ms timer whose longest gap
between two ticks is the longest time the window could not draw (with the stage of the run
under way at each tick), and a context for calling operators as the 3D view's button does."""

import importlib
import importlib.util
import sys
import time

import bpy
import numpy as np


def load_addon(root: str):
    """Register the extension at ``root`` as the package "vr_bench_addon"; returns its
    operators.generate module (``running()``: the run under way)."""
    spec = importlib.util.spec_from_file_location(
        "vr_bench_addon", root + "/__init__.py", submodule_search_locations=[root]
    )
    addon = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = addon
    spec.loader.exec_module(addon)
    addon.register()
    return importlib.import_module("vr_bench_addon.operators.generate")


class Ticker:
    """A timer ticking every 10 ms once `start`ed; `longest_gap(since)` in seconds, `spent(since)`
    {stage: seconds} from the stages of ``generate.running()`` seen at the ticks."""

    def __init__(self, generate):
        self.generate = generate
        self.ticks = []
        self.stages = []  # (time, the stage under way) at each tick

    def start(self):
        bpy.app.timers.register(self._tick, first_interval=0.01)

    def _tick(self):
        self.ticks.append(time.perf_counter())
        job = self.generate.running()
        self.stages.append((self.ticks[-1], job.stage if job else None))
        return 0.01

    def longest_gap(self, since: float) -> float:
        t = [x for x in self.ticks if x >= since]
        return float(max(np.diff(t))) if len(t) > 1 else float("nan")

    def spent(self, since: float) -> dict:
        seen = [(t, st) for t, st in self.stages if t >= since]
        out = {}
        for a, b in zip(seen, seen[1:], strict=False):
            out[a[1]] = out.get(a[1], 0.0) + b[0] - a[0]
        return out


def window_figures(results: dict, ticker: Ticker, started: float) -> None:
    """Put the window run's total and longest gap (since ``started``) into ``results``, beside
    the blocking run's ("blocking_longest_gap_s"), and their ratio."""
    results["window_total_s"] = time.perf_counter() - started
    results["window_longest_gap_s"] = ticker.longest_gap(started)
    results["ratio_gap"] = results["blocking_longest_gap_s"] / results["window_longest_gap_s"]


def view3d_context():
    """A context override as the 3D view's sidebar button gives its operator."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    return bpy.context.temp_override(window=win, area=area)
