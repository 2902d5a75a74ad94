"""The JSON report of a run (`<name>.report.json`, or --report): written whole after every
frame (a temporary file, then renamed), read back to carry over a resumed run's skipped
frames. `check_report_path` refuses, before anything is written, a --report that would
replace an input, an output of the run, or a file that is not one of these reports.
"""

import contextlib
import json
import os
import re
import time

from ...virtual_reflections.atomic_files import WriteError, same_file, temp_path
from ...virtual_reflections.frames import pattern_frame

REPORT_KEYS = ("frames", "totals", "complete")  # every report has them (run_report)
MAPS_FOLDER = "vr_maps"  # OUT/vr_maps/<name>/: the run's saved maps (render.configure)


def write_json(path, data):
    """Write ``data`` to ``path`` whole or not at all; WriteError (exit code 1, one line
    naming ``path``) when it cannot be written (a full disk): no temporary file is left."""
    temp = temp_path(path)
    try:
        with open(temp, "w", encoding="utf-8") as f:
            json.dump(data, f, indent=1, default=_plain)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(temp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.remove(temp)
        raise WriteError(f"cannot write the report {path}: {exc.strerror or exc}") from exc


def report_file(report, out, name):
    """The report's absolute path: --report, else OUT/<name>.report.json."""
    return os.path.abspath(report or os.path.join(out, f"{name}.report.json"))


def is_report(path):
    """True when the file ``path`` is one of these reports (a JSON object with REPORT_KEYS)."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and all(key in data for key in REPORT_KEYS)


def _outputs(name):
    """Every file name the batch writes for ``name`` in OUT, any frame, either mode: frames
    <name>.<frame>.exr|png, elements <name>_render.<frame>.exr, one frame's <name>_render.exr
    and <name>_composite.png|exr, and its hidden files (lock, records, temporary files)."""
    stem = re.escape(name)
    return re.compile(
        rf"{stem}\.-?\d+\.(exr|png)|{stem}_render(\.-?\d+)?\.exr|{stem}_composite\.(exr|png)"
        rf"|\.{stem}(\.|_render|_composite).*",
        re.IGNORECASE,
    )


def check_report_path(report, out, name, inputs, sequence=None):
    """ValueError (one line) unless the absolute path ``report`` may be written: not a
    folder, not an input (the files ``inputs``: the shot, a still or movie plate; any frame
    of the plate pattern ``sequence``, requested or not), not a file the run of ``name``
    writes in ``out`` (any frame number), and, if it exists, one of these reports."""
    if os.path.isdir(report):
        raise ValueError(f"--report is a folder, not a file: {report}")
    for path in inputs:
        if path and same_file(report, path):
            raise ValueError(f"--report {report} is an input of the run: choose another path")
    frame = pattern_frame(sequence, report) if sequence else None
    if frame is not None:
        raise ValueError(
            f"--report {report} is frame {frame} of the plate {sequence}: choose another path"
        )
    folder, base = os.path.split(report)
    maps = os.path.join(out, MAPS_FOLDER, name)
    if (same_file(folder, out) and _outputs(name).fullmatch(base)) or _inside(report, maps):
        raise ValueError(
            f"--report {report} is a file this run writes: choose another path (the default "
            f"is {os.path.join(out, name + '.report.json')})"
        )
    if os.path.lexists(report) and not is_report(report):
        raise ValueError(
            f"--report {report} exists and is not a report of render_shot: move it or choose "
            "another path"
        )


def _inside(path, folder):
    real, folder = os.path.realpath(path), os.path.realpath(folder)
    return real.startswith(folder + os.sep)


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
