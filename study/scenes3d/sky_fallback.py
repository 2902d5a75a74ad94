"""A safe fall-back for the unseen sky (issue 41, item 4: never worse than a flat colour): a cue
from the plate alone flags the scenes where the sky estimate is unsure, and there the mirror
leans toward the plate-mean world by a share W; the cue, its side, its threshold, W and the
estimate's own constants are fitted leave-one-HDRI-out (`heldout_sky.loho`'s rule), on the
renders of `heldout_sky render` (no new render). Held-out figures only.

    python -m study.scenes3d.sky_fallback OUT [--safe] [--nested]   # OUT as heldout_sky's; ~2 min
    python -m study.scenes3d.sky_fallback render-fresh FRESH          # 12 new scenes, ~5 min
    python -m study.scenes3d.sky_fallback confirm OUT FRESH           # the choice on them
"""

from __future__ import annotations

import json
import math
import pathlib
import sys

import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from ..evaluate.metrics import psnr, to_display
from . import heldout_sky as hs
from . import scenes, sky_retrieval

SHARES = (0.0, 0.25, 0.5, 0.75, 1.0)  # W, the share of the plate-mean world where unsure


def ground_share(hfov_deg, pitch_deg, width=256, height=144) -> float:
    """The share of the plate's rows below the world's horizon (a level camera ``pitch_deg``
    down, `prior_level.band_levels`' frame)."""
    f = (width / 2) / math.tan(math.radians(hfov_deg) / 2)
    y = (height / 2 - np.arange(height) - 0.5) / f  # +y up, row 0 at the top
    return float(np.mean(y < math.tan(math.radians(pitch_deg))))


def cues(d, record) -> dict:
    """The plate's cues of an unsure sky: each from the plate (8-bit, as Generate reads it),
    its camera and the ground band's levels (`prior_level.band_levels`) alone."""
    band = record["split"]["band"]
    plate = d["plate8"]
    luma = plate.reshape(-1, 3) @ hs.LUMA
    p10, p99 = np.percentile(luma, [10, 99])
    levels = np.log(np.maximum([band["mean"], hs.lum(d["plate_mean"]), hs.lum(d["top"])], 1e-6))
    scene = record["scene"]
    return {
        "plate range ln(p99/p10)": math.log(max(p99, 1e-6) / max(p10, 1e-6)),
        "top rows / ground band ln": levels[2] - levels[0],
        "ground share": ground_share(scene["hfov_deg"], scene["pitch_deg"]),
        "band contrast ln(mean/log-average)": math.log(
            band["mean"] / max(band["log_average"], 1e-9)
        ),
        "band / plate mean |ln|": abs(levels[0] - levels[1]),
        "level cues' spread (sd ln)": float(np.std(levels)),
    }


def base_columns(data, retrieved=False):
    """The sky estimates a fall-back may lean from: the default as rendered (its gain fitted on
    Blender's HDRIs), heldout_sky's tinted level and structure families and (``retrieved``)
    sky_retrieval's (their constants fitted with the fall-back)."""
    grids = {
        "the default (its gain NOT held out on Blender's six)": [None],
        "today's level × g, tinted": hs.grid_of(["today's level"], ["plate mean"], hs.TAUS, [0.0]),
        "the plate mean's level × g, tinted": hs.grid_of(
            ["plate mean's level"], ["plate mean"], hs.TAUS, [0.0]
        ),
        "the camera view's structure, levelled × g, tinted": hs.grid_of(
            ["today's level", "plate mean's level"], ["plate mean"], hs.TAUS, [0.0], [0.25, 0.5]
        ),
    }
    if retrieved:
        grids["the retrieved HDRI's structure (sky_retrieval), levelled × g, tinted"] = [
            ("retrieved", *p) for p in sky_retrieval.grid() if p[3] < 1.0
        ]
    return grids


def scores_for(data, params):
    """(scenes, len(params), len(SHARES)) dB over the plate mean: each estimate leaning W."""
    out = np.empty((len(data), len(params), len(SHARES)))
    for i, d in enumerate(data):
        truth = to_display(d["truth"])
        for j, p in enumerate(params):
            if p is None:
                sky = d["full"]
            elif p[0] == "retrieved":
                sky = sky_retrieval.composite(d, *p[1:])
            else:
                sky = hs.composite(d, *p)
            for k, w in enumerate(SHARES):
                image = (1 - w) * sky + w * d["mean"]
                out[i, j, k] = psnr(to_display(image), truth, d["mask"]) - d["base"]
    return out


def fit_fallback(scores, cue_values, groups, safe=False, fixed=None):
    """Leave-one-group-out over (estimate j, cue c, side, threshold t, share W): a scene leans W
    toward the plate mean when its cue is past t. ``scores`` (n, J, K) as `scores_for`,
    ``cue_values`` (n, C); ``fixed`` (n,): the estimate j per scene fitted beforehand without a
    fall-back (`heldout_sky.loho`; the same within a group), only the fall-back fitted then.
    Returns (held-out dB per scene, the chosen (j, c, side, t, k) per scene, whether each
    scene leaned)."""
    scores, cue_values, groups = np.asarray(scores), np.asarray(cue_values), np.asarray(groups)
    n, _, shares = scores.shape
    held, leaned, chosen = np.empty(n), np.zeros(n, bool), [None] * n

    def objective(s):
        return s + 2.0 * np.minimum(s - hs.SAFE_FLOOR, 0.0) if safe else s

    for group in np.unique(groups):
        train = groups != group
        s = scores[train]
        if fixed is not None:  # one column: the estimate fitted without a fall-back
            s = np.full_like(s, -1e9)
            j = int(np.asarray(fixed)[~train][0])
            s[:, j] = scores[train][:, j]
        best, pick = -np.inf, None
        for c in range(cue_values.shape[1]):
            values = cue_values[train, c]
            edges = np.unique(values)
            thresholds = np.concatenate(([edges[0] - 1], (edges[:-1] + edges[1:]) / 2))
            for side in (1, -1):
                # m (n_train, T): past the threshold on this side
                m = (side * values[:, None] > side * thresholds[None, :]).astype(float)
                stay = objective(s[:, :, 0])  # (n, J)
                for k in range(1, shares):
                    lean = objective(s[:, :, k])
                    total = (1 - m).T @ stay + m.T @ lean  # (T, J)
                    t, j = np.unravel_index(int(np.argmax(total)), total.shape)
                    if total[t, j] > best + 1e-12:
                        best, pick = total[t, j], (j, c, side, thresholds[t], k)
                total = stay.sum(0)
                j = int(np.argmax(total))
                if total[j] > best + 1e-12:
                    best, pick = total[j], (j, c, side, np.inf * side, 0)
        j, c, side, t, k = pick
        for i in np.nonzero(~train)[0]:
            lean = side * cue_values[i, c] > side * t
            held[i] = scores[i, j, k if lean else 0]
            leaned[i] = lean and k > 0
            chosen[i] = pick
    return held, chosen, leaned


def fit(out, safe=False, nested=False, log=print) -> dict:
    records = hs.read_records(out)
    data = [hs.load(out, r) for r in records]
    for d in data:
        folder = next(p for p in (pathlib.Path(out) / "cache").glob(f"{d['name']}-*"))
        d["plate8"] = srgb_to_linear(read_rgba(str(folder / "plate.png"))[..., :3]).astype(float)
    retrieved = (pathlib.Path(out) / "dirs").is_dir()
    if retrieved:  # sky_directions' renders: the retrieval's structure too
        hdris = sky_retrieval.blender_hdris()
        for d in data:
            sky_retrieval.attach(out, d, hdris)
    table = [cues(d, r) for d, r in zip(data, records)]
    names = list(table[0])
    cue_values = np.array([[t[k] for k in names] for t in table])
    groups = np.array([d["hdri"] for d in data])
    log(f"{len(data)} scenes; cues: " + ", ".join(names))
    default = np.array(
        [psnr(to_display(d["full"]), to_display(d["truth"]), d["mask"]) - d["base"] for d in data]
    )
    log("the default per scene, worst 6: " + ", ".join(
        f"{data[i]['name']} {default[i]:+.2f} [" + ", ".join(f"{v:.2f}" for v in cue_values[i])
        + "]"
        for i in np.argsort(default)[:6]
    ))  # fmt: skip
    log("cue medians: " + ", ".join(f"{v:.2f}" for v in np.median(cue_values, 0)))
    log("| estimate + fall-back where a cue says unsure | mean, ahead, worst | leaned |")
    log("|---|---|---|")
    results = {}
    for name, params in base_columns(data, retrieved).items():
        scores = scores_for(data, params)
        plain, fixed = hs.loho(scores[:, :, 0], groups, list(range(len(params))), safe)
        how = "fitted with the estimate"
        if nested:
            how = "fitted after the estimate"
        else:
            fixed = None
        held, chosen, leaned = fit_fallback(scores, cue_values, groups, safe, fixed)
        results[name] = held
        log(hs.table_line(f"{name}, no fall-back", plain) + " |")
        log(hs.table_line(f"{name}, + fall-back ({how})", held) + f" {leaned.sum()} |")
        picks = sorted({(names[c], s, round(float(t), 2), SHARES[k]) for _, c, s, t, k in chosen})
        log(f"|   fitted per held-out HDRI (cue, side, threshold, W): {picks} | | |")
        log("|   worst held out: " + ", ".join(
            f"{data[i]['name']} {held[i]:+.2f}" for i in np.argsort(held)[:4]) + " | | |"
        )  # fmt: skip
        for c, cue in enumerate(names):  # one cue alone
            one, _, leaned = fit_fallback(scores, cue_values[:, [c]], groups, safe, fixed)
            log(hs.table_line(f"  {cue} alone", one) + f" {leaned.sum()} |")
    return results


CHOSEN = "the plate mean's level × g, tinted"  # the family the confirmation applies


def fresh_specs() -> list:
    """Scenes no fit or choice here saw: the held-out set's last four (forest, night) and
    eight new seeds (401-408) under the hardest HDRIs (studio, interior) and four others."""
    hdris = ("studio", "interior", "studio", "interior", "courtyard", "city", "sunset", "forest")
    new = [
        scenes.make_scene(seed, i, hdri=h, shape=scenes.SHAPES[(i + 2) % len(scenes.SHAPES)])
        for i, (seed, h) in enumerate(zip(range(401, 409), hdris))
    ]
    return scenes.held_out_set()[4:] + new


def render_fresh(out, log=print) -> None:
    """`heldout_sky.render`'s renders (no camera view) of `fresh_specs` into OUT."""
    from . import mirror, run

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    done = {r["scene"]["name"] for r in hs.read_records(out)}
    addon = run.Addon()
    try:
        with open(out / "records.jsonl", "a") as records:
            for spec in fresh_specs():
                if spec.name in done:
                    continue
                record, _ = mirror.run_scene(
                    spec, addon, out / "cache", out / "work", hs.WIDTH, hs.SAMPLES, log, True
                )
                record["auto_sky"] = [hs.AUTO_SKY_GAIN, hs.AUTO_SKY_TINT]  # the prior's recipe
                records.write(json.dumps(record) + "\n")
                records.flush()
    finally:
        run.new_file()
        addon.close()


def _data(out):
    records = hs.read_records(out)
    data = [hs.load(out, r) for r in records]
    for d in data:
        folder = next(p for p in (pathlib.Path(out) / "cache").glob(f"{d['name']}-*"))
        d["plate8"] = srgb_to_linear(read_rgba(str(folder / "plate.png"))[..., :3]).astype(float)
    cue_values = np.array([list(cues(d, r).values()) for d, r in zip(data, records)])
    return data, cue_values


def confirm(out, fresh, log=print) -> None:
    """CHOSEN's estimate and its fall-back fitted (safe, nested) on all of OUT's scenes,
    applied unchanged to FRESH's (`render_fresh`): the variant's choice itself tested."""
    data, cue_values = _data(out)
    params = base_columns(data)[CHOSEN]
    scores = scores_for(data, params)
    # a dummy group (a copy of one scene) whose fold is fitted on all the real scenes
    fake = np.concatenate((np.zeros(len(data)), [1.0]))
    padded = np.concatenate((scores, scores[:1]), 0)
    _, fixed = hs.loho(padded[:, :, 0], fake, list(range(len(params))), safe=True)
    cues_padded = np.concatenate((cue_values, cue_values[:1]), 0)
    _, chosen, _ = fit_fallback(padded, cues_padded, fake, True, fixed)
    j, c, side, t, k = chosen[-1]
    names = list(cues(data[0], hs.read_records(out)[0]))
    log(f"fitted on all {len(data)}: {params[j]}, lean {SHARES[k]} where {names[c]} "
        f"{'>' if side > 0 else '<'} {t:.3f}")  # fmt: skip
    new, new_cues = _data(fresh)
    ours, default = [], []
    for d, cue in zip(new, new_cues):
        lean = SHARES[k] if side * cue[c] > side * t else 0.0
        image = (1 - lean) * hs.composite(d, *params[j]) + lean * d["mean"]
        truth = to_display(d["truth"])
        ours.append(psnr(to_display(image), truth, d["mask"]) - d["base"])
        default.append(psnr(to_display(d["full"]), truth, d["mask"]) - d["base"])
        log(f"{d['name']}: default {default[-1]:+.2f}, chosen {ours[-1]:+.2f}"
            f"{' (leaned)' if lean else ''}")  # fmt: skip
    log(hs.table_line("the default on the fresh scenes", np.array(default)))
    log(hs.table_line("the chosen estimate + fall-back, fitted on all 50", np.array(ours)))


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) == 2 and args[0] == "render-fresh":
        render_fresh(args[1])
        return 0
    if len(args) == 3 and args[0] == "confirm":
        confirm(args[1], args[2])
        return 0
    if not args:
        print(
            "usage: python -m study.scenes3d.sky_fallback OUT [--safe] [--nested]",
            file=sys.stderr,
        )
        return 2
    fit(args[0], "--safe" in args, "--nested" in args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
