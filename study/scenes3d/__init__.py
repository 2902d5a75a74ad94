"""A 3D ground truth (issue 11, item 1): scenes path-traced in Cycles with the `bpy` module, the
plate rendered without the subject, the truth with it (a mirror and a rough glossy at two
roughnesses), and every method's render of the subject alone composited over the plate.

- `scenes`: the scene descriptions, drawn from seeds (no bpy);
- `build`: a description as a Blender scene, and the baselines' worlds (bpy);
- `run`: renders, Generate per add-on method, scores on the subject's pixels (bpy);
- `report`: summaries, the tables of docs/scenes3d.md, the charts (no bpy).

`python -m study scenes [--quick] [--out DIR] [--jobs 1]` runs it (`run_command`). Research
only: bpy is imported when a run starts (once per process); the product never imports this.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import pathlib
import platform
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass

from . import scenes

COMMAND = "python -m study scenes"


class ScenesInputError(Exception):
    """Bad input to the command (bpy missing, unwritable folder); one line."""


@dataclass(frozen=True)
class Config:
    quick: bool = False
    width: int = 320  # x 180
    samples: int = 32

    def specs(self):
        return scenes.scene_set(self.quick)


FULL = Config()
QUICK = Config(quick=True, width=256, samples=16)


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def run_study(config: Config, log=None, keep=None):
    """Render and score every scene of ``config``. Returns (data, crops): ``data`` the JSON
    record (``scenes``, ``addon_methods``, ``baselines``, settings, machine, seconds),
    ``crops`` {scene: {column: display crop}} for the contact sheet. ``keep``: a folder to keep
    the renders in (default: a temporary one, removed)."""
    try:
        from . import run
    except ImportError as exc:  # bpy (or Blender's own modules) not importable
        raise ScenesInputError(f"the 3D study needs the bpy module: {exc}") from exc
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    specs = config.specs()
    work = pathlib.Path(keep) if keep else pathlib.Path(tempfile.mkdtemp(prefix="vr_scenes3d_"))
    started = time.perf_counter()
    try:
        records, crops, methods = run.run_scenes(specs, work, config.width, config.samples, say)
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    import bpy

    data = {
        "command": COMMAND + (" --quick" if config.quick else ""),
        "quick": config.quick,
        "resolution": [config.width, round(config.width / scenes.ASPECT)],
        "samples": config.samples,
        "denoised": run.build.build_scenes().has_oidn(),
        "hdris": list(scenes.HDRIS),
        "held_out_hdris": list(scenes.HELD_OUT),
        "materials": [{"name": n, "roughness": r, "combine": c} for n, r, c in run.MATERIALS],
        "addon_methods": methods,
        "baselines": list(run.BASELINES),
        "metrics": list(run.METRICS),
        "scenes": records,
        "machine": {
            "bpy": bpy.app.version_string,
            "python": platform.python_version(),
            "cores": os.cpu_count(),
        },
        "seconds": time.perf_counter() - started,
    }
    return data, crops


def run_command(quick=False, out=None, jobs=1, log=None):
    """The `scenes` sub-command: run, print the means, and with ``out`` (default docs for the
    full set; nothing for --quick unless given) write OUT/scenes3d.json (scenes3d_quick.json),
    the tables of OUT/scenes3d.md and OUT/images/scenes3d_{pareto,examples}.png."""
    if jobs != 1:
        raise ScenesInputError(
            "--jobs: only 1 is supported (one bpy per process; Cycles already uses every core)"
        )
    config = QUICK if quick else FULL
    target = pathlib.Path(out) if out else (None if quick else pathlib.Path("docs"))
    if target is not None:
        try:
            (target / "images").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ScenesInputError(f"cannot write in {target}: {exc.strerror}") from exc
    data, crops = run_study(config, log=log)
    from . import report

    print(report.table_means(data))
    print(
        f"{len(data['scenes'])} scenes in {data['seconds']:.0f} s on {data['machine']['cores']} "
        f"cores (bpy {data['machine']['bpy']})"
    )
    if target is not None:
        write_outputs(data, crops, target)
    return data, crops


def write_outputs(data, crops, target) -> None:
    from . import report

    target = pathlib.Path(target)
    (target / "images").mkdir(parents=True, exist_ok=True)
    name = "scenes3d_quick" if data["quick"] else "scenes3d"
    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    if importlib.util.find_spec("matplotlib") is None:
        print("matplotlib is not installed: no charts", file=sys.stderr)
    else:
        report.chart_pareto(data, target / "images" / f"{name}_pareto.png")
        report.contact_sheet(data, crops, target / "images" / f"{name}_examples.png")
    header = (
        "# The 3D ground truth\n\n"
        f"Generated by `{data['command']}`; the tables between the markers are rewritten by "
        "it.\n"
    )
    report.update_markdown(target / f"{name}.md", report.blocks(data), header)
    print(
        f"wrote {target / (name + '.json')}, {target / (name + '.md')} and the charts in "
        f"{target / 'images'}",
        file=sys.stderr,
    )
