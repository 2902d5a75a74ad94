"""The JSON report of a frame range (`<name>.report.json`): written whole after every frame
(a temporary file, then renamed), read back to carry over a resumed run's skipped frames.
"""

import json
import os
import time

from ..virtual_reflections.atomic_files import temp_path


def write_json(path, data):
    temp = temp_path(path)
    with open(temp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=_plain)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(temp, path)


def one_line(exc):
    lines = [line for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__


def _plain(value):
    """JSON for what json does not know: NumPy scalars and arrays, anything else as text."""
    return value.tolist() if hasattr(value, "tolist") else str(value)


def read_report(path):
    """The per-frame entries of an earlier report at ``path`` by frame, or {}."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
        return {e["frame"]: e for e in data.get("frames", []) if isinstance(e, dict)}
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        return {}


def pass_report(report):
    if hasattr(report, "__dataclass_fields__"):
        return {k: getattr(report, k) for k in report.__dataclass_fields__}
    return report if isinstance(report, dict) else str(report)


def _totals(entries, wall):
    rendered = [e for e in entries if e.get("status") == "rendered"]
    seconds = {}
    for entry in rendered:
        for stage, value in entry.get("times", {}).items():
            seconds[stage] = round(seconds.get(stage, 0.0) + value, 4)
    return {
        "frames": len(entries),
        "rendered": len(rendered),
        "skipped": sum(e.get("status") == "skipped" for e in entries),
        "warnings": sum(len(e.get("warnings", [])) for e in entries),
        "seconds": seconds,
        "wall_seconds": round(wall, 3),
    }


def run_report(header, entries, frames, warnings, started, complete=False):
    ordered = [entries[f] for f in frames if f in entries]
    return {
        **header,
        "warnings": list(warnings),
        "frames": ordered,
        "totals": _totals(ordered, time.perf_counter() - started),
        "complete": complete and len(ordered) == len(frames),
    }
