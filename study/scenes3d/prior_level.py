"""How the sky prior's level is taken, measured on the fast mirror loop's ``--split`` renders
(docs/scenes3d.md, "The level's statistic").

The prior's part of a mirror render is linear in the prior's level: with the prior black
(``dark``) and at the run's gain (``full``), the prior scaled by s renders as
dark + s (full - dark). So one pair of renders scores every level: `scale_curve` keeps each
scene's mirror PSNR over `SCALES`, less the plate mean's. The level is the ground band's
log-average luminance brightened toward its mean by an exponent (`fill.prior_level`'s
``energy``, the add-on's `Params.fill_energy`); `band_levels` takes both as the engine does,
on the plate's mip level the fill uses; `statistic_table` scores each exponent of `EXPONENTS`
with the gain derived again on the HDRIs for it (`sky_prior.gain_for_exponent`), and the
constant gain the scenes themselves would pick (`best_constant_gain`).
"""

from __future__ import annotations

import math

import numpy as np

from virtual_reflections.camera_view import intrinsics_from_hfov
from virtual_reflections.fill import fill_geometry, fill_level, prior_level
from virtual_reflections.mipmap import build_pyramid, level_shapes, level_view
from virtual_reflections.params import SKY_GAINS, Params

from .. import sky_prior
from ..evaluate.metrics import psnr, to_display

SCALES = np.exp(np.linspace(math.log(1 / 32), math.log(32), 101))  # SCALES[50] == 1
EXPONENTS = (0.0, 0.25, 0.5, 0.75, 1.0)


def scale_curve(full, dark, truth, mask, crop, baseline: float) -> list:
    """(len(SCALES),) mirror PSNR of the linear composites ``full`` (the prior at the run's
    gain) and ``dark`` (the prior black) with the prior's part scaled by each of SCALES,
    scored on ``mask`` within ``crop`` as `run.score` does, less ``baseline`` (the plate
    mean's PSNR)."""
    return scaled_scores(full, dark, truth, mask, crop, baseline, SCALES)


def scaled_scores(full, dark, truth, mask, crop, baseline: float, factors) -> list:
    """Mirror PSNR less ``baseline`` of dark + k (full - dark) for each k of ``factors`` (a
    number, or (3,) per channel: the prior's part is linear in each), scored on ``mask``
    within ``crop`` as `run.score` does."""
    y0, y1, x0, x1 = crop
    f, d = full[y0:y1, x0:x1], dark[y0:y1, x0:x1]
    t, m = to_display(truth[y0:y1, x0:x1]), mask[y0:y1, x0:x1]
    part = f - d
    return [
        float(psnr(to_display(d + np.asarray(k, part.dtype) * part), t, m)) - baseline
        for k in factors
    ]


def band_levels(plate, hfov_deg: float, pitch_deg: float) -> dict:
    """The level `fill.prior_level` takes of the (H, W, 3) linear ``plate`` seen by a level
    camera (no roll) ``pitch_deg`` down with horizontal field ``hfov_deg``, at energy 0 (the
    ground band's log-average luminance) and 1 (its mean), on the mip level the fill uses."""
    h, w = plate.shape[:2]
    shapes = level_shapes(h, w)
    level = fill_level(shapes)
    pixels = level_view(build_pyramid(plate), shapes, level)
    p = math.radians(pitch_deg)
    up = (0.0, math.cos(p), -math.sin(p))  # the engine's camera frame: +X left, +Y up, +Z ahead
    intrinsics = intrinsics_from_hfov(w, h, hfov_deg)
    bins, _, _ = fill_geometry(shapes[level], level, intrinsics, Params().fill_width, up=up)
    return {"log_average": prior_level(pixels, bins, 0.0), "mean": prior_level(pixels, bins, 1.0)}


def statistic_table(data) -> str:
    """Per exponent of EXPONENTS: the gain derived on the HDRIs for it and the mean mirror
    PSNR over the plate mean (scenes ahead) it gives, from each scene's `scale_curve` and
    `band_levels` (the record's "split"). Only for a run at the add-on's own Auto gain."""
    if data.get("sky_gain") is not None or data.get("surroundings") not in (None, "auto"):
        return "(the level's statistic: at the Auto gain only, not --sky-gain or --surroundings)"
    energy, base = Params().fill_energy, SKY_GAINS["auto"]
    images = sky_prior.load_images()
    rows = [
        "| exponent | gain from the HDRIs | mirror PSNR over the plate mean | ahead |",
        "|---|---|---|---|",
    ]
    for exponent in EXPONENTS:
        gain = sky_prior.gain_for_exponent(images, exponent)
        over = []
        for record in data["scenes"]:
            split = record["split"]
            band = split["band"]
            scale = gain / base * (band["mean"] / band["log_average"]) ** (exponent - energy)
            over.append(np.interp(math.log(scale), np.log(SCALES), split["prior_scales"]))
        d = np.array(over)
        mark = " (the add-on's)" if exponent == energy else ""
        rows.append(
            f"| {exponent:g}{mark} | {gain:.1f} | {d.mean():+.2f} dB | {(d > 0).sum()}/{len(d)} |"
        )
    gain, over = best_constant_gain(data)
    rows.append("")
    rows.append(
        f"The constant gain that serves these scenes best (the add-on's statistic): {gain:.1f}, "
        f"{over:+.2f} dB over the plate mean (the add-on's {base:g}: chosen on the HDRIs)"
    )
    best = np.array([max(record["split"]["prior_scales"]) for record in data["scenes"]])
    rows.append(
        f"Each scene at its own best gain (an oracle: Surroundings Custom set to each shot's "
        f"sky exactly): {best.mean():+.2f} dB, ahead in {(best > 0).sum()}/{len(best)}"
    )
    return "\n".join(rows)


def scene_gains_line(data) -> str:
    """Each scene's own best gain (`scene_gains`) on one line; only for a run at the add-on's
    own Auto gain, as `statistic_table`."""
    if data.get("sky_gain") is not None or data.get("surroundings") not in (None, "auto"):
        return "(each scene's own best gain: at the Auto gain only)"
    own = ", ".join(f"{name} {gain:.2f}" for name, gain in scene_gains(data).items())
    return f"Each scene's own best gain: {own}"


def scene_gains(data) -> dict:
    """{scene name: the gain, at the add-on's level statistic, at which its `scale_curve`
    peaks} (on the SCALES grid)."""
    return {
        record["scene"]["name"]: float(
            SKY_GAINS["auto"] * SCALES[int(np.argmax(record["split"]["prior_scales"]))]
        )
        for record in data["scenes"]
    }


def best_constant_gain(data) -> tuple:
    """(gain, mean mirror PSNR over the plate mean): the constant gain, at the add-on's level
    statistic, whose mean over the records' `scale_curve` is highest (a figure of the scenes,
    not a choice: the add-on's gain is derived on the HDRIs, `study sky-prior`)."""
    curves = np.array([record["split"]["prior_scales"] for record in data["scenes"]])
    mean = curves.mean(0)
    best = int(np.argmax(mean))
    return float(SKY_GAINS["auto"] * SCALES[best]), float(mean[best])
