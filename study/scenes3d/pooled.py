"""The mirror target over every set of the 3D truth (`--cases all --mirror-only`): the fast
mirror loop's records of the default 16 scenes, the 32 more, the 8 under Blender's held-out
HDRIs and the 30 under the Poly Haven HDRIs, each set's mean mirror PSNR and SSIM over the
plate mean, and the same over the scenes under HDRIs nothing was chosen on and over all of
them (issue 11's target: >= 1 dB and >= 0.05 SSIM on average, ahead in >= 75 % of scenes).
No bpy.
"""

from __future__ import annotations

import math

import numpy as np

SETS = ("default", "more", "heldout", "polyhaven")
TITLES = {
    "default": "the 16 scenes (Blender's six training HDRIs)",
    "more": "32 scenes more (the same six)",
    "heldout": "8 scenes, Blender's held-out forest and night",
    "polyhaven": "30 scenes, 15 Poly Haven HDRIs",
}
UNSEEN = ("heldout", "polyhaven")  # HDRIs nothing in the add-on was chosen on
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


def row(title: str, dp, ds, hdris: int) -> str:
    n = len(dp)
    error = float(np.std(dp, ddof=1) / math.sqrt(n)) if n > 1 else float("nan")
    return (
        f"| {title} | {n} | {hdris} | {dp.mean():+.2f} ({error:.2f}) | {ds.mean():+.3f} | "
        f"{int((dp > 0).sum())}/{n} ({100 * (dp > 0).mean():.0f} %) | {int((ds > 0).sum())}/{n} |"
    )


def pooled_table(runs: dict) -> str:
    """``runs``: {set name of SETS: the fast mirror loop's record of that set}. A row per set,
    then the sets under unseen HDRIs together and every set together."""
    lines = [
        "| scenes | n | HDRIs | mirror PSNR over the plate mean, dB (standard error) | SSIM | "
        "ahead: PSNR | SSIM |",
        "|---|---|---|---|---|---|---|",
    ]
    parts = {name: differences(data) for name, data in runs.items()}
    hdris = {name: {r["scene"]["hdri"] for r in data["scenes"]} for name, data in runs.items()}
    for name in runs:
        lines.append(row(TITLES.get(name, name), *parts[name], len(hdris[name])))
    groups = [("under HDRIs nothing was chosen on", [n for n in runs if n in UNSEEN])]
    groups.append(("all", list(runs)))
    for title, names in groups:
        if len(names) > 1:
            dp = np.concatenate([parts[n][0] for n in names])
            ds = np.concatenate([parts[n][1] for n in names])
            lines.append(row(title, dp, ds, len(set().union(*(hdris[n] for n in names)))))
    return "\n".join(lines)
