"""The sky prior's colour, measured on the fast mirror loop's ``--split`` renders
(docs/scenes3d.md, "The prior's colour and the plate's mean").

The add-on's prior is neutral. The prior's part of a mirror render is linear in each channel
of the prior's colour: with the prior black (``dark``) and neutral at the run's gain
(``full``), a prior of the same luminance tinted by per-channel factors f renders as
dark + f (full - dark). So one pair of renders scores any tint: `tint_scores` keeps each
scene's mirror PSNR, less the plate mean's, with the prior tinted toward the plate's mean
colour by each share of its saturation in `TINTS` (0: the add-on's neutral prior).
"""

from __future__ import annotations

import numpy as np

from virtual_reflections.fill import REC709_LUMA, tint_colour

from .prior_level import scaled_scores

TINTS = (0.0, 0.25, 0.5)  # shares of the plate's mean colour's saturation the prior takes


def tint_factors(plate_mean, tint: float) -> np.ndarray:
    """(3,) per-channel factors that tint a neutral prior toward the linear colour
    ``plate_mean`` by ``tint`` of its saturation (0: neutral, 1: its chromaticity), its
    luminance kept."""
    mean = np.maximum(np.asarray(plate_mean, np.float64), 0.0)
    if float(mean @ REC709_LUMA) <= 0.0:  # a black plate has no colour to take
        return np.ones(3)
    return (1.0 - tint) + tint * tint_colour(mean).astype(np.float64)


def tint_scores(full, dark, truth, mask, crop, baseline: float, plate_mean) -> list:
    """(len(TINTS),) mirror PSNR of the linear composites ``full`` (the neutral prior at the
    run's gain) and ``dark`` (the prior black) with the prior tinted by each of TINTS toward
    ``plate_mean``, scored on ``mask`` within ``crop`` as `run.score` does, less ``baseline``
    (the plate mean's PSNR)."""
    factors = [tint_factors(plate_mean, tint) for tint in TINTS]
    return scaled_scores(full, dark, truth, mask, crop, baseline, factors)


def colour_table(data) -> str:
    """Per tint of TINTS: the mean mirror PSNR over the plate mean (scenes ahead) of the
    records' `tint_scores` (the record's "split"). Only for a run at the add-on's own Auto
    gain, whose neutral prior the first row is."""
    if data.get("sky_gain") is not None or data.get("surroundings") not in (None, "auto"):
        return "(the prior's colour: at the Auto gain only, not --sky-gain or --surroundings)"
    scores = np.array([record["split"]["tints"] for record in data["scenes"]])
    rows = ["| the prior | mirror PSNR over the plate mean | ahead |", "|---|---|---|"]
    for k, tint in enumerate(TINTS):
        name = f"tinted, {tint:g} of the plate's saturation" if tint else "neutral (the add-on's)"
        d = scores[:, k]
        rows.append(f"| {name} | {d.mean():+.2f} dB | {(d > 0).sum()}/{len(d)} |")
    return "\n".join(rows)
