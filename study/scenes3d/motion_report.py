"""The motion sequences' outputs (no bpy; matplotlib's Agg backend): the command, the JSON, the
table of docs/scenes3d.md's "In motion" block and the chart of the change per frame pair.

`python -m study scenes --cases motion [--quick] [--out DIR]` runs `run_command`.
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

import numpy as np

from . import motion

COMMAND = "python -m study scenes --cases motion"
MARK = "scenes3d"
BLOCK = "motion"
HEADING = "In motion"

# (width, samples, frames per sequence, methods, looks); quick: the sliding sphere's World look
FULL = (320, 16, 14, None, None)
QUICK = (160, 8, 5, ("GROUND",), ("rough 0.35",))


class MotionInputError(Exception):
    """Bad input to the command (bpy missing, unwritable folder); one line."""


def _json_safe(value):
    """NaN as null, infinities as strings, so the file is strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def run_study(quick=False, log=None, keep=None) -> dict:
    """Render and measure the sequences; the JSON record."""
    try:
        from . import motion_run
    except ImportError as exc:  # bpy (or Blender's own modules) not importable
        raise MotionInputError(f"the 3D study needs the bpy module: {exc}") from exc
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    width, samples, frames, methods, looks = QUICK if quick else FULL
    work = pathlib.Path(keep) if keep else pathlib.Path(tempfile.mkdtemp(prefix="vr_motion_"))
    started = time.perf_counter()
    try:
        records, labels = motion_run.run_motions(
            motion.motion_set(quick, frames), work, width, samples, say, True, methods, looks
        )
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    import bpy

    return {
        "command": COMMAND + (" --quick" if quick else ""),
        "quick": quick,
        "resolution": [width, round(width * 9 / 16)],
        "samples": samples,
        "frames": frames,
        "methods": [labels[m] for m in (methods or motion.METHODS)],
        "default_method": labels["GROUND"],
        "pop": motion.POP,
        "floor": motion.FLOOR,
        "hold": motion_run.HOLD,
        "sequences": records,
        "machine": {
            "bpy": bpy.app.version_string,
            "python": platform.python_version(),
            "cores": os.cpu_count(),
        },
        "seconds": time.perf_counter() - started,
    }


def refresh(data) -> dict:
    """Recompute every method column's summary (ratios, popping pairs) from its stored changes
    with the current rule (motion.summarise): a saved run re-read without rendering again."""
    for seq in data["sequences"]:
        for col in seq["columns"].values():
            if "summary" in col:
                truth = seq["columns"][motion.column(motion.TRUTH, col["look"])]["changes"]
                col["summary"] = motion.summarise(col["changes"], truth)
    data["pop"], data["floor"] = motion.POP, motion.FLOOR
    return data


def _fmt(v, digits=2):
    return "–" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _pairs(pops) -> str:
    """Pops as frame pairs (frames numbered from 1): '3→4, 6→7' or 'none'."""
    return ", ".join(f"{k + 1}→{k + 2}" for k in pops) or "none"


def table(data) -> str:
    """Per sequence, method and look: mean PSNR, the ratio of the change to the truth's (median
    and max, both measures), the popping pairs, and the median change itself."""
    lines = [
        "| sequence | method | look | PSNR (dB): mean (min) "
        "| change / truth's, aligned: median / max | mean colour: median / max "
        "| popping pairs | median change (truth) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for seq in data["sequences"]:
        for name, col in seq["columns"].items():
            if "summary" not in col:
                continue
            s = col["summary"]
            truth = seq["columns"][motion.column(motion.TRUTH, col["look"])]["changes"]
            pops = sorted(set(s["aligned"]["pops"]) | set(s["mean"]["pops"]))
            method = name[: -len(col["look"]) - 1] if name.endswith(col["look"]) else name
            if "(" in name and name.endswith(")"):  # the held variant: "<method> <look> (held)"
                method = name.replace(f" {col['look']}", "")
            lines.append(
                f"| {seq['name']} | {method} | {col['look']} | "
                f"{_fmt(float(np.mean(col['psnr'])), 1)} ({_fmt(float(np.min(col['psnr'])), 1)}) | "
                f"{_fmt(s['aligned']['median_ratio'])} / {_fmt(s['aligned']['max_ratio'])} | "
                f"{_fmt(s['mean']['median_ratio'])} / {_fmt(s['mean']['max_ratio'])} | "
                f"{_pairs(pops)} | "
                f"{_fmt(float(np.nanmedian(col['changes']['aligned'])), 4)} "
                f"({_fmt(float(np.nanmedian(truth['aligned'])), 4)}) |"
            )
    return "\n".join(lines) + "\n"


def default_verdict(data) -> dict:
    """The default method's worst case over sequences and looks (the held variant left out):
    {"max_ratio": aligned max ratio, "mean_max_ratio": the mean colour's, "pops": count}."""
    worst = {"max_ratio": 0.0, "mean_max_ratio": 0.0, "pops": 0}
    for seq in data["sequences"]:
        for name, col in seq["columns"].items():
            if "summary" not in col or not name.startswith(data["default_method"] + " "):
                continue
            if name.endswith(")"):
                continue
            s = col["summary"]
            worst["max_ratio"] = max(worst["max_ratio"], s["aligned"]["max_ratio"])
            worst["mean_max_ratio"] = max(worst["mean_max_ratio"], s["mean"]["max_ratio"])
            worst["pops"] += len(set(s["aligned"]["pops"]) | set(s["mean"]["pops"]))
    return worst


def chart(data, path) -> None:
    """The aligned change per frame pair: one panel per sequence and look, the truth and each
    method (the held variant dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    seqs = data["sequences"]
    looks = [
        lk
        for lk, _, _ in motion.LOOKS
        if any(c["look"] == lk for s in seqs for c in s["columns"].values())
    ]
    fig, axes = plt.subplots(
        len(seqs), len(looks), figsize=(4.6 * len(looks), 3.0 * len(seqs)), squeeze=False
    )
    for i, seq in enumerate(seqs):
        for j, look in enumerate(looks):
            ax = axes[i][j]
            for name, col in seq["columns"].items():
                if col["look"] != look:
                    continue
                values = col["changes"]["aligned"]
                x = np.arange(1, len(values) + 1) + 0.5
                truth = name.startswith(motion.TRUTH)
                ax.plot(
                    x,
                    values,
                    "k-" if truth else ("--" if name.endswith(")") else "-"),
                    marker="o",
                    ms=3,
                    lw=2.0 if truth else 1.2,
                    label=name.replace(f" {look}", ""),
                )
            ax.set_title(f"{seq['name']}: {look}", fontsize=9)
            ax.set_xlabel("frame pair (k → k + 1, at k + 0.5)", fontsize=8)
            ax.set_ylabel("aligned change (display)", fontsize=8)
            ax.set_ylim(bottom=0)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def add_block(path, text: str, command: str) -> None:
    """Rewrite the motion block of ``path``; a file without it gets the heading and the block
    at its end."""
    from .report import update_markdown

    path = pathlib.Path(path)
    marker = f"<!-- {MARK}:{BLOCK} -->"
    body = path.read_text() if path.is_file() else ""
    if marker not in body:
        body = (
            body.rstrip()
            + ("\n\n" if body else "")
            + f"## {HEADING}\n\nGenerated by `{command}`.\n\n{marker}\n<!-- /{MARK}:{BLOCK} -->\n"
        )
        path.write_text(body)
    update_markdown(path, {BLOCK: text}, "")


def write_outputs(data, target) -> None:
    target = pathlib.Path(target)
    (target / "images").mkdir(parents=True, exist_ok=True)
    name = "scenes3d_motion" + ("_quick" if data["quick"] else "")
    (target / f"{name}.json").write_text(json.dumps(_json_safe(data), indent=1) + "\n")
    if importlib.util.find_spec("matplotlib") is None:
        print("matplotlib is not installed: no chart", file=sys.stderr)
    else:
        chart(data, target / "images" / f"{name}.png")
    md = target / ("scenes3d_quick.md" if data["quick"] else "scenes3d.md")
    add_block(md, table(data), data["command"])
    print(
        f"wrote {target / (name + '.json')}, {md} and {target / 'images' / name}.png",
        file=sys.stderr,
    )


def run_command(quick=False, out=None, log=None) -> dict:
    """`--cases motion`: run, print the table, and with ``out`` (default docs; nothing for
    --quick unless given) write OUT/scenes3d_motion(_quick).json, the chart and the block."""
    target = pathlib.Path(out) if out else (None if quick else pathlib.Path("docs"))
    if target is not None:
        try:
            (target / "images").mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise MotionInputError(f"cannot write in {target}: {exc.strerror}") from exc
    data = refresh(run_study(quick, log=log))
    print(table(data))
    print(
        f"{len(data['sequences'])} sequence(s) in {data['seconds']:.0f} s on "
        f"{data['machine']['cores']} cores (bpy {data['machine']['bpy']})"
    )
    if target is not None:
        write_outputs(data, target)
    return data
