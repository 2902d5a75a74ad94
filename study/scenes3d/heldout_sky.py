"""The unseen sky's colour and level estimated from the plate, every constant fitted
leave-one-HDRI-out (issue 41, items 2-4; docs/scenes3d.md, "The unseen sky's colour and level
from the plate, held out by HDRI").

50 mirror scenes under all 23 HDRIs (`specs`: the 16 under Blender's six, forest and night from
the held-out set's first four, the Poly Haven fifteen's 30). Per scene the fast mirror loop's
renders with ``split`` (`mirror.run_scene`): the default's mirror with its sky prior ("full") and
with the prior black ("dark"), the plate-mean world's mirror, the truth. The prior's part is
linear in its colour, so a prior of colour c renders as dark + (c / today's) (full - dark), and a
fall-back w toward the plate mean as a blend with its mirror: every estimate of `FAMILIES` is
scored without another render. `loho` fits each family's constants on 22 HDRIs' scenes and
scores the 23rd's: only held-out figures are reported.

    python -m study.scenes3d.heldout_sky render OUT     # ~8 min on 2 cores (bpy 4.5)
    python -m study.scenes3d.heldout_sky fit OUT [--safe] [--groups] [--flip]   # seconds
    python -m study.scenes3d.heldout_sky fit OUT --auto   # Auto's sky: methods.AUTO_SKY_*

Renders made before Auto took the plate's mean colour (records without ``auto_sky``) are what
the fits above were run on; `fit_auto` scores the plate-mean family on either kind.
"""

from __future__ import annotations

import json
import math
import pathlib
import sys

import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba
from virtual_reflections.methods import AUTO_SKY_GAIN, AUTO_SKY_TINT, SKY_GAINS
from virtual_reflections.params import Params

from ..evaluate.metrics import psnr, ssim, to_display
from ..evaluate.perceptual import detail_ratio, flip_ldr, upper_half
from . import scenes

LABEL = "Camera View + Ground"
WIDTH, SAMPLES = 256, 16
LUMA = np.array([0.2126, 0.7152, 0.0722])
GAINS = np.exp(np.linspace(math.log(1 / 8), math.log(8), 31))  # GAINS[15] == 1
TAUS = (0.0, 0.25, 0.5, 1.0)  # the share of a colour's chromaticity the sky takes
FALLBACKS = (0.0, 0.25, 0.5)  # a constant blend toward the plate-mean world
BETAS = ("b0.25", "b0.5", "b1", "b2")  # a blend growing with the two levels' disagreement
STRUCTURES = (0.25, 0.5, 0.75, 1.0)  # the share of the camera view's structure in the sky
CAMERA_VIEW = "Camera View"  # its render (`render`, ``structure``) lends the sky structure
BLENDERS = ("city", "courtyard", "interior", "studio", "sunrise", "sunset")
SAFE_FLOOR = -1.0  # dB: the safe fit's floor (issue 41, item 4)
AUTO_GAINS = np.exp(np.linspace(math.log(0.7), math.log(2.5), 23))  # Auto's sky: times the
AUTO_TINTS = (0.0, 0.25, 0.5, 0.75, 1.0)  # plate mean's level; the share of its hue


def specs() -> list:
    return scenes.scene_set() + scenes.held_out_set()[:4] + scenes.polyhaven_set()


def render(out, log=print) -> None:
    """Render every scene of `specs` (bpy) into OUT (cache/, work/) and append its record to
    OUT/records.jsonl (the default's mirror with ``split``), then the camera view's mirror
    ("<scene> Camera View.exr" in OUT's work folder, its record in OUT/camera.jsonl); a scene
    already recorded is skipped."""
    from . import mirror, run

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    addon = run.Addon()
    generate, label = addon.generate.generate, run.default_method_label

    def camera_view(scene, *args, **kwargs):
        scene.virtual_reflections.method = "CAMERA"
        return generate(scene, *args, **kwargs)

    try:
        for name, split in (("records.jsonl", True), ("camera.jsonl", False)):
            done = {r["scene"]["name"] for r in read_records(out, name)}
            if not split:  # the same scene, Generate with Camera View, its render so named
                addon.generate.generate = camera_view
                run.default_method_label = lambda _addon: CAMERA_VIEW
            with open(out / name, "a") as records:
                for spec in specs():
                    if spec.name in done:
                        continue
                    record, _ = mirror.run_scene(
                        spec, addon, out / "cache", out / "work", WIDTH, SAMPLES, log, split
                    )
                    record["auto_sky"] = [AUTO_SKY_GAIN, AUTO_SKY_TINT]  # the prior's recipe
                    records.write(json.dumps(record) + "\n")
                    records.flush()
    finally:
        addon.generate.generate, run.default_method_label = generate, label
        run.new_file()
        addon.close()


def read_records(out, name="records.jsonl") -> list:
    path = pathlib.Path(out) / name
    if not path.is_file():
        return []
    latest = {}
    for line in path.read_text().splitlines():
        record = json.loads(line)
        latest[record["scene"]["name"]] = record
    return list(latest.values())


def lum(colour) -> float:
    return float(np.asarray(colour, np.float64) @ LUMA)


def load(out, record) -> dict:
    """One scene's crops (linear composites over the plate) and the plate's cues."""
    out, name = pathlib.Path(out), record["scene"]["name"]
    folder = next(p for p in (out / "cache").glob(f"{name}-*") if (p / "truth mirror.exr").exists())
    plate = read_rgba(str(folder / "plate.exr"))[..., :3].astype(np.float64)
    plate8 = srgb_to_linear(read_rgba(str(folder / "plate.png"))[..., :3]).astype(np.float64)
    truth = read_rgba(str(folder / "truth mirror.exr"))[..., :3].astype(np.float64)
    mean = read_rgba(str(folder / "Plate mean mirror.exr")).astype(np.float64)
    full = read_rgba(str(out / "work" / f"{name} {LABEL}.exr")).astype(np.float64)
    camera_path = out / "work" / f"{name} {CAMERA_VIEW}.exr"
    camera = read_rgba(str(camera_path)).astype(np.float64) if camera_path.is_file() else full
    dark = read_rgba(str(out / "work" / f"{name} {LABEL} sky 0.exr")).astype(np.float64)
    mask = mean[..., 3] > 0.5
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = max(ys.min() - 4, 0), ys.max() + 5, max(xs.min() - 4, 0), xs.max() + 5

    def crop(rgba):
        over = rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plate if rgba.shape[-1] == 4 else rgba
        return over[y0:y1, x0:x1]

    f, d, m, t, cv = crop(full), crop(dark), crop(mean), crop(truth), crop(camera)
    part = f - d
    strong = part.sum(-1) > 0.02
    today = np.median(part[strong], axis=0) if strong.sum() > 5 else np.full(3, 1e-3)
    band = record.get("split", {}).get("band")
    plate_mean = plate8.reshape(-1, 3).mean(0)
    if "auto_sky" in record and record.get("surroundings", "AUTO") == "AUTO":
        gain, tint = record["auto_sky"]  # Auto's sky from the plate's mean colour
        hue = plate_mean / max(lum(plate_mean), 1e-6)
        today = gain * lum(plate_mean) * ((1 - tint) + tint * hue)
    elif band and record.get("surroundings", "AUTO") == "AUTO":
        today = np.full(3, prior_as_set(band))  # the prior the engine set, not its median
    k = mask[y0:y1, x0:x1]
    return {
        "name": name,
        "hdri": record["scene"]["hdri"],
        "full": f,
        "dark": d,
        "mean": m,
        "truth": t,
        "part": part,
        "sky": strong,  # the pixels the prior sets
        "camera": cv,  # the camera view's mirror (the default's where it was not rendered)
        "mask": k,
        "today": np.maximum(today, 1e-4),  # the prior's colour as rendered
        "top": plate8[: max(1, plate8.shape[0] // 10)].reshape(-1, 3).mean(0),
        "plate_mean": plate_mean,
        "base": psnr(to_display(m), to_display(t), k),
        "crop": (int(y0), int(y1), int(x0), int(x1)),  # of the full frame
        "auto_sky": record.get("auto_sky"),  # (gain, tint) when rendered with Auto's sky
    }


def prior_as_set(band) -> float:
    """The Auto prior's level as the engine set it (neutral): SKY_GAINS["auto"] times the
    ground band's level at Params.fill_energy (`fill.prior_level`: the log-average brightened
    toward the mean), from the record's `prior_level.band_levels`. The median of the prior's
    rendered part (used before) is lower where few mirror pixels see the prior fully (Suzanne,
    the cars: down to 0.4 of it), which scaled every absolute level's colour up there."""
    e = Params().fill_energy
    return SKY_GAINS["auto"] * band["log_average"] ** (1 - e) * band["mean"] ** e


LEVELS = {
    "today's level": lambda d: lum(d["today"]),
    "plate mean's level": lambda d: lum(d["plate_mean"]),
    "top rows' level": lambda d: lum(d["top"]),
}
COLOURS = {"plate mean": lambda d: d["plate_mean"], "top rows": lambda d: d["top"]}


def chroma(d, colour, tau):
    """Today's prior's chromaticity moved toward ``colour``'s by ``tau``."""
    c = np.maximum(np.asarray(colour, np.float64), 1e-6)
    return (1 - tau) * d["today"] / lum(d["today"]) + tau * c / max(lum(c), 1e-6)


def composite(d, gain, level, colour, tau, fallback, structure=0.0):
    """The scene's mirror (linear crop) with the sky of this estimate; ``fallback`` a share of
    the plate-mean world, or "b<beta>": beta times |ln(today's level / the plate mean's)|;
    ``structure``: the share of the sky's pixels taken from the camera view's mirror (the
    plate's own structure, as the paper's front face), levelled to the estimate's luminance."""
    if isinstance(fallback, str):
        disagree = abs(math.log(max(lum(d["today"]), 1e-6) / max(lum(d["plate_mean"]), 1e-6)))
        fallback = min(1.0, float(fallback[1:]) * disagree)
    target = gain * LEVELS[level](d) * chroma(d, COLOURS[colour](d), tau)
    sky = d["dark"] + (target / d["today"]) * d["part"]
    if structure:
        where = d["sky"]
        seen = d["camera"][where]
        level = lum(target) / max(float(np.mean(seen @ LUMA)), 1e-6) if where.any() else 0.0
        sky[where] = (1 - structure) * sky[where] + structure * level * seen
    return (1 - fallback) * sky + fallback * d["mean"]


def grid_of(levels, colours, taus, fallbacks, structures=(0.0,)):
    return [
        (g, lv, c, t, w, s) for g in GAINS for lv in levels for c in colours for t in taus
        for w in fallbacks for s in structures
    ]  # fmt: skip


FAMILIES = {
    "today's level × g, neutral (the default's form)": grid_of(
        ["today's level"], ["plate mean"], [0.0], [0.0]
    ),
    "today's level × g, tinted toward the plate mean": grid_of(
        ["today's level"], ["plate mean"], TAUS, [0.0]
    ),
    "today's level × g, tinted toward the top rows": grid_of(
        ["today's level"], ["top rows"], TAUS, [0.0]
    ),
    "the plate mean's level × g, tinted": grid_of(
        ["plate mean's level"], list(COLOURS), TAUS, [0.0]
    ),
    "the top rows' level × g, tinted": grid_of(["top rows' level"], list(COLOURS), TAUS, [0.0]),
    "any of these, constant fall-back w": grid_of(list(LEVELS), list(COLOURS), TAUS, FALLBACKS),
    "today's level × g, tinted, fall-back by disagreement": grid_of(
        ["today's level"], ["plate mean"], TAUS, BETAS
    ),
    "the camera view's structure, levelled to today's or the plate mean's level × g": grid_of(
        ["today's level", "plate mean's level"], ["plate mean"], TAUS, [0.0], STRUCTURES
    ),
}


def loho(scores, groups, columns, safe=False):
    """Leave-one-group-out: for each group (an HDRI), the column of ``columns`` with the best
    mean of ``scores`` (scenes x params) over the other groups' scenes (``safe``: less twice
    the mean shortfall below SAFE_FLOOR), scored on the group's own. Returns (held-out score
    per scene, the column chosen for it)."""
    scores, groups, columns = np.asarray(scores), np.asarray(groups), np.asarray(columns)
    held = np.empty(len(scores))
    chosen = np.empty(len(scores), int)
    for group in np.unique(groups):
        train = groups != group
        part = scores[train][:, columns]
        objective = part.mean(0)
        if safe:
            objective = objective + 2.0 * np.minimum(part - SAFE_FLOOR, 0.0).mean(0)
        best = columns[int(np.argmax(objective))]
        held[~train] = scores[~train, best]
        chosen[~train] = best
    return held, chosen


def plate_sky(d, gain, tint):
    """The scene's mirror (linear crop) with Auto's sky from the plate: ``gain`` times the
    plate mean's luminance, its hue ``tint`` of the way from grey to the plate mean's."""
    hue = d["plate_mean"] / max(lum(d["plate_mean"]), 1e-6)
    target = gain * lum(d["plate_mean"]) * ((1 - tint) + tint * hue)  # from grey, as the engine
    return d["dark"] + (target / d["today"]) * d["part"]


def loho_floor(scores, groups, floor=SAFE_FLOOR):
    """Leave-one-group-out under a floor: for each group, of the columns whose worst scene
    over the other groups is at least ``floor`` dB, the one with the best mean there (none:
    the one with the best worst scene), scored on the group's own. Returns (held-out score
    per scene, the column chosen for it)."""
    scores, groups = np.asarray(scores), np.asarray(groups)
    held = np.empty(len(scores))
    chosen = np.empty(len(scores), int)
    for group in np.unique(groups):
        train = groups != group
        best = pick_under_floor(scores[train], floor)
        held[~train], chosen[~train] = scores[~train, best], best
    return held, chosen


def pick_under_floor(scores, floor=SAFE_FLOOR, objective=None) -> int:
    """The column of ``scores`` (scenes x columns) with the best mean (of ``objective``, the
    same shape, when given) among those whose worst scene is at least ``floor``; none: the
    one with the best worst scene."""
    worst = scores.min(0)
    mean = (scores if objective is None else objective).mean(0)
    return int(np.argmax(np.where(worst >= floor, mean, mean.min() - 1e3 + worst)))


def fit_auto(out, log=print) -> tuple:
    """Auto's sky (methods.AUTO_SKY_GAIN, AUTO_SKY_TINT) fitted on OUT's renders: the
    plate-mean family (`plate_sky`) held out by HDRI under SAFE_FLOOR, then fitted on every
    scene; prints PSNR over the plate-mean world (mean, ahead, worst), SSIM over it, FLIP and
    the upper half's detail ratio, for the default as rendered and held out; for renders made
    with Auto's sky from the plate, how far their recorded recipe (`plate_sky`) lies from them;
    and the
    engine's constants beside the fit. Returns (gain, tint)."""
    data = [load(out, r) for r in read_records(out)]
    truths = [to_display(d["truth"]) for d in data]
    grid = [(g, t) for g in AUTO_GAINS for t in AUTO_TINTS]
    scores = np.array(
        [[psnr(to_display(plate_sky(d, *p)), t, d["mask"]) - d["base"] for p in grid]
         for d, t in zip(data, truths)]
    )  # fmt: skip
    hdris = np.array([d["hdri"] for d in data])
    held, chosen = loho_floor(scores, hdris)
    log(f"{len(data)} scenes, {len(set(hdris))} HDRIs; mirror PSNR over the plate mean")
    rendered = [to_display(d["full"]) for d in data]
    held_out = [to_display(plate_sky(d, *grid[c])) for d, c in zip(data, chosen)]
    for name, images in (("the default as rendered", rendered), ("held out", held_out)):
        log(summary_line(name, images, truths, data))
    predicted = [
        psnr(to_display(plate_sky(d, *d["auto_sky"])), t, d["mask"]) - psnr(x, t, d["mask"])
        for d, t, x in zip(data, truths, rendered)
        if d["auto_sky"]
    ]
    if predicted:
        log(f"the recorded recipe of Auto's sky against its renders: within "
            f"{np.max(np.abs(predicted)):.2f} dB a scene ({len(predicted)} scenes)")  # fmt: skip
    picked = sorted({(round(grid[c][0], 2), grid[c][1]) for c in chosen})
    gain, tint = grid[pick_under_floor(scores)]
    log(f"fitted per held-out HDRI: {picked}")
    log(f"fitted on every scene: gain {gain:.2f}, tint {tint:g} (the engine's: "
        f"{AUTO_SKY_GAIN:g}, {AUTO_SKY_TINT:g})")  # fmt: skip
    return float(gain), float(tint)


def summary_line(name, images, truths, data) -> str:
    """One row of `fit_auto`: display-space ``images`` against ``truths`` per scene of
    ``data``: PSNR over the plate mean (`table_line`), SSIM over it, FLIP and the upper half's
    median detail ratio."""
    v = np.array([psnr(x, t, d["mask"]) - d["base"] for x, t, d in zip(images, truths, data)])
    gain = [
        ssim(x, t, d["mask"]) - ssim(to_display(d["mean"]), t, d["mask"])
        for x, t, d in zip(images, truths, data)
    ]
    f = [flip_ldr(x, t, d["mask"]) for x, t, d in zip(images, truths, data)]
    u = [
        detail_ratio(x, t, d["mask"], upper_half(d["mask"]))
        for x, t, d in zip(images, truths, data)
    ]
    return (
        f"{table_line(name, v)} SSIM {np.mean(gain):+.3f}, FLIP {np.mean(f):.3f}, "
        f"upper-half detail {np.nanmedian(u):.2f}"
    )


def table_line(name, v):
    return f"| {name} | {v.mean():+.2f} dB, {(v > 0).sum()}/{len(v)}, worst {v.min():+.2f} |"


def fit(out, safe=False, groups=False, flip=False, log=print) -> dict:
    """Score every family held out by HDRI on OUT's renders; prints the tables."""
    data = [load(out, r) for r in read_records(out)]
    params = sorted({p for family in FAMILIES.values() for p in family}, key=str)
    index = {p: i for i, p in enumerate(params)}
    scores = np.array(
        [
            [psnr(to_display(composite(d, *p)), to_display(d["truth"]), d["mask"]) - d["base"]
             for p in params]
            for d in data
        ]
    )  # fmt: skip
    default = np.array(
        [psnr(to_display(d["full"]), to_display(d["truth"]), d["mask"]) - d["base"] for d in data]
    )
    hdris = np.array([d["hdri"] for d in data])
    log(f"{len(data)} scenes, {len(set(hdris))} HDRIs; mirror PSNR over the plate mean")
    log("| the unseen sky | mean, ahead, worst scene |")
    log("|---|---|")
    log(table_line("the default (Auto; fitted on Blender's HDRIs: not held out there)", default))
    results = {}
    for name, family in FAMILIES.items():
        held, chosen = loho(scores, hdris, [index[p] for p in family], safe)
        results[name] = (held, [params[c] for c in chosen])
        log(table_line(name, held))
        picked = sorted({(round(params[c][0], 2), *params[c][1:]) for c in chosen}, key=str)
        log(f"|   fitted per held-out HDRI: {picked} | |")
    if groups:
        sets = {
            "Blender's six": np.isin(hdris, BLENDERS),
            "forest, night": np.isin(hdris, scenes.HELD_OUT),
            "Poly Haven": ~np.isin(hdris, (*BLENDERS, *scenes.HELD_OUT)),
        }
        for name, v in {"the default": default, **{k: r[0] for k, r in results.items()}}.items():
            cells = ", ".join(f"{s} {table_line('', v[m])[5:-2]}" for s, m in sets.items())
            log(f"{name}: {cells}")
    if flip:
        for name, (_, chosen) in [("the default", (None, None)), *results.items()]:
            images = [
                to_display(d["full"] if chosen is None else composite(d, *p))
                for d, p in zip(data, chosen or [None] * len(data))
            ]
            f = [flip_ldr(x, to_display(d["truth"]), d["mask"]) for x, d in zip(images, data)]
            u = [
                detail_ratio(x, to_display(d["truth"]), d["mask"], upper_half(d["mask"]))
                for x, d in zip(images, data)
            ]
            log(f"{name}: FLIP {np.mean(f):.3f}, upper-half detail (median) {np.nanmedian(u):.2f}")
        f = [flip_ldr(to_display(d["mean"]), to_display(d["truth"]), d["mask"]) for d in data]
        log(f"the plate-mean world: FLIP {np.mean(f):.3f}")
    return {"default": default, **{k: r[0] for k, r in results.items()}}


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) < 2 or args[0] not in ("render", "fit"):
        print("usage: python -m study.scenes3d.heldout_sky render|fit OUT [--safe] [--groups] "
              "[--flip] [--auto]", file=sys.stderr)  # fmt: skip
        return 2
    if args[0] == "render":
        render(args[1])
    elif "--auto" in args:
        fit_auto(args[1])
    else:
        fit(args[1], "--safe" in args, "--groups" in args, "--flip" in args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
