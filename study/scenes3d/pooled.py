"""The mirror target over every set of the 3D truth (`--cases all --mirror-only`): the fast
mirror loop's records of the default 16 scenes, the 32 more, the 8 under Blender's held-out
HDRIs and the 30 under the Poly Haven HDRIs, each set's mean mirror PSNR and SSIM over the
plate mean, and the same over the scenes under forest, night and the Poly Haven HDRIs and over
all of them (issue 11's target: >= 1 dB and >= 0.05 SSIM on average, ahead in >= 75 % of scenes);
with each set's worst scene, the mean FLIP of the default and of the plate mean and the
default's median upper-half detail ratio (issue 41, item 1). No bpy.
"""

from __future__ import annotations

import math

import numpy as np

SETS = ("default", "more", "heldout", "polyhaven")
TITLES = {
    "default": "the 16 scenes (Blender's six HDRIs; in Auto's sky fit)",
    "more": "32 scenes more (the same six; scenes no fit saw)",
    "heldout": "8 scenes, Blender's forest and night (4 in Auto's sky fit)",
    "polyhaven": "30 scenes, 15 Poly Haven HDRIs (in Auto's sky fit)",
}
# HDRIs the ground band's gains (SKY_GAINS) were not fitted on. Auto's sky from the plate
# (methods.AUTO_SKY_*) was fitted leave-one-HDRI-out on 50 scenes under all 23: the first 16,
# forest and night's first 4 and the 30 Poly Haven scenes.
UNSEEN = ("heldout", "polyhaven")
UNSEEN_TITLE = "forest, night and Poly Haven (no ground gain fitted on them)"
MIRROR = "mirror"


def differences(data) -> tuple:
    """(PSNR, SSIM) of the default method less the plate mean's, per scene of one run."""
    label, mean = data["addon_methods"][0], data["baselines"][0]
    dp, ds = [], []
    for record in data["scenes"]:
        r = record["results"][MIRROR]
        dp.append(r[label]["psnr"] - r[mean]["psnr"])
        ds.append(r[label]["ssim"] - r[mean]["ssim"])
    return np.array(dp), np.array(ds)


def perceptual(data) -> tuple:
    """(FLIP of the default, FLIP of the plate mean, the default's upper-half detail ratio)
    per scene of one run (issue 41, item 1); NaN where a record was scored before them."""
    label, mean = data["addon_methods"][0], data["baselines"][0]
    rows = [record["results"][MIRROR] for record in data["scenes"]]
    return tuple(
        np.array([r[name].get(key, math.nan) for r in rows], dtype=float)
        for name, key in ((label, "flip"), (mean, "flip"), (label, "detail_upper"))
    )


def _stat(values, how, digits) -> str:
    values = values[np.isfinite(values)]
    return "–" if values.size == 0 else f"{how(values):.{digits}f}"


def row(title: str, dp, ds, hdris: int, extra=None) -> str:
    """One line of the pooled table; ``extra``: `perceptual`'s arrays for the last columns."""
    n = len(dp)
    error = float(np.std(dp, ddof=1) / math.sqrt(n)) if n > 1 else float("nan")
    ours, flat, upper = extra if extra is not None else (np.full(n, math.nan),) * 3
    return (
        f"| {title} | {n} | {hdris} | {dp.mean():+.2f} ({error:.2f}) | {ds.mean():+.3f} | "
        f"{int((dp > 0).sum())}/{n} ({100 * (dp > 0).mean():.0f} %) | {int((ds > 0).sum())}/{n} | "
        f"{dp.min():+.2f} | {_stat(ours, np.mean, 3)} / {_stat(flat, np.mean, 3)} | "
        f"{_stat(upper, np.median, 2)} |"
    )


def pooled_table(runs: dict) -> str:
    """``runs``: {set name of SETS: the fast mirror loop's record of that set}. A row per set,
    then the sets under unseen HDRIs together and every set together."""
    lines = [
        "| scenes | n | HDRIs | mirror PSNR over the plate mean, dB (standard error) | SSIM | "
        "ahead: PSNR | SSIM | worst scene, dB | FLIP: default / plate mean (lower is better) | "
        "upper-half detail, default (median) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    parts = {name: differences(data) for name, data in runs.items()}
    seen = {name: perceptual(data) for name, data in runs.items()}
    hdris = {name: {r["scene"]["hdri"] for r in data["scenes"]} for name, data in runs.items()}
    for name in runs:
        lines.append(row(TITLES.get(name, name), *parts[name], len(hdris[name]), seen[name]))
    groups = [(UNSEEN_TITLE, [n for n in runs if n in UNSEEN])]
    groups.append(("all", list(runs)))
    for title, names in groups:
        if len(names) > 1:
            dp = np.concatenate([parts[n][0] for n in names])
            ds = np.concatenate([parts[n][1] for n in names])
            extra = tuple(np.concatenate([seen[n][k] for n in names]) for k in range(3))
            count = len(set().union(*(hdris[n] for n in names)))
            lines.append(row(title, dp, ds, count, extra))
    return "\n".join(lines)
