"""A fast loop for the mirror subject (`python -m study scenes --mirror-only`): per scene only
the plate, the mirror truth, the plate mean's mirror and the add-on's default method's mirror,
scored as `run.run_scene` scores them. The plate, truth and plate-mean renders are kept on
disk (`--cache DIR`), keyed by the scene's description, the render settings, the bpy version
and the source of the scene builder, so a re-run after a change to the add-on (the sky prior,
the fill) renders only the default method: ~1.5 min for the 16 scenes instead of ~35 for the
full study. Its figures match the full run's mirror columns (docs/scenes3d.json) within the
renderer's noise (docs/scenes3d.md, "The fast mirror loop").

Research only (bpy); run through `study.scenes3d.run_command(mirror_only=True)`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib
import json
import math
import pathlib
import time

import bpy
import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from . import build, oracles, prior_colour, prior_level, run
from .scenes import Scene3D

MIRROR = "mirror"
CACHED = ("plate.exr", "plate.png", "truth mirror.exr", "Plate mean mirror.exr")
ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILDERS = (ROOT / "study" / "scenes3d" / "build.py", ROOT / "sample_scenes" / "build_scenes.py")


def cache_key(spec: Scene3D, width: int, samples: int) -> str:
    """What the cached renders depend on: the scene, the render settings, the renderer and the
    code that builds the scene (not the add-on: its render is never cached)."""
    h = hashlib.sha1()
    h.update(json.dumps(spec.to_json(), sort_keys=True).encode())
    h.update(f"{width} {samples} {bpy.app.version_string}".encode())
    for path in BUILDERS:
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def run_scene(
    spec: Scene3D,
    addon: run.Addon,
    cache: pathlib.Path,
    work,
    width,
    samples,
    log,
    split=False,
    surroundings=None,
    oracle=None,
    contact_shadow=None,
    probe=False,
):
    """One scene's mirror: (record, crops) shaped as `run.run_scene`'s, with only the default
    method and the plate mean (``probe``: and the on-set probe, `run.PROBE`, cached as the
    plate mean is). ``split``: also the default with a black sky prior (one more
    Generate and render), and the record's "split" (`error_split`; with the PSNR over the plate
    mean at every scale of the prior, `prior_level.scale_curve`, the band's levels,
    `prior_level.band_levels`, and at every tint of the prior, `prior_colour.tint_scores`).
    ``surroundings``: the
    panel's Surroundings for it (`run.surroundings_of`). ``oracle``: also the rows of that
    oracle (the package's ORACLES, `oracles`), scored as the default's. ``contact_shadow``:
    the panel's Contact Shadow for it (None: the add-on's)."""
    started = time.perf_counter()
    run.new_file()
    scene, camera, subject, others, dome, material = build.build(spec, width, samples)
    height = scene.render.resolution_y
    folder = cache / f"{spec.name}-{cache_key(spec, width, samples)}"
    hit = all((folder / name).is_file() for name in CACHED)
    folder.mkdir(parents=True, exist_ok=True)
    border = run.subject_border(scene, camera, subject)
    crop = run.border_pixels(border, width, height)
    plate, truth, plate8, mean, seen, renders = _plate_truth_and_mean(
        scene, subject, others, dome, material, folder, hit, border, probe
    )
    label, method, dark, report, seconds, count = _default_mirror(
        spec, addon, scene, subject, folder, work, border, surroundings, contact_shadow, split
    )
    renders += count
    rows = {}
    if oracle is not None:
        rendered, count = oracles.render_rows(
            oracle, scene, subject, others, addon, folder, work, spec.name, border
        )
        rows = dict(zip(oracles.labels(label, oracle), rendered))
        renders += count

    mask = mean[..., 3] > 0.5
    named = ((label, method), *rows.items(), *seen.items(), (run.MEAN, mean))
    results, crops, composites = _scored(named, plate, truth, mask, crop)
    record = {
        "scene": spec.to_json(),
        "subject_pixels": int(mask.sum()),
        "results": {MIRROR: results},
        "generate_s": {label: {"REPLACE": seconds}},
        "finite": {label: bool(np.isfinite(method).all())},
        "warnings": {label: list(report.warnings)} if report.warnings else {},
        "renders": renders,
        "cached": hit,
        "seconds": time.perf_counter() - started,
        "plate_mean": [float(c) for c in plate8.reshape(-1, 3).mean(0)],
        "surroundings": scene.virtual_reflections.surroundings,
    }
    if dark is not None:
        record["split"] = _split(
            composites, dark, plate, truth, mask, crop, results, label, plate8, spec
        )
    log(
        f"{spec.name}: {mask.sum()} px, mirror PSNR {label} {results[label]['psnr']:.2f}, "
        f"plate mean {results[run.MEAN]['psnr']:.2f} ({record['seconds']:.0f} s, {renders} "
        f"renders{', cached' if hit else ''})"
    )
    return record, crops


def _scored(renders, plate, truth, mask, crop):
    """Each (label, RGBA render) of ``renders`` composited over ``plate`` and scored against
    ``truth`` on ``mask``, and the plate itself: (scores, display crops with the truth's,
    composites), each by label."""
    results, crops, composites = {}, {}, {}
    y0, y1, x0, x1 = crop
    for name, rgba in renders:
        composite = composites[name] = rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plate
        results[name] = run.score(composite, truth, mask, crop)
        crops[name] = run.to_display(composite[y0:y1, x0:x1])
    results["(plate itself)"] = run.score(plate, truth, mask, crop)
    crops["Truth"] = run.to_display(truth[y0:y1, x0:x1])
    return results, crops, composites


def _plate_truth_and_mean(scene, subject, others, dome, material, folder, hit, border, probe):
    """The plate, the mirror truth, the 8-bit plate (linear), the plate mean's mirror and, with
    ``probe``, the on-set probe's (in a dict by its label), rendered into ``folder`` or read
    from it (``hit``), and how many were rendered. Leaves the neighbours hidden from render,
    the film transparent and the dome the world."""
    renders = 0
    if not hit:
        subject.hide_render = True
        scene.render.film_transparent = False
        plate = run.render(scene, folder / "plate.exr")[..., :3]
        run.write_png(folder / "plate.png", plate)
        subject.hide_render = False
        build.set_roughness(material, 0.0)
        truth = run.render(scene, folder / "truth mirror.exr", border)[..., :3]
        renders += 2
    else:
        plate = read_rgba(str(folder / "plate.exr"))[..., :3]
        truth = read_rgba(str(folder / "truth mirror.exr"))[..., :3]
    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    plate8 = srgb_to_linear(read_rgba(str(folder / "plate.png"))[..., :3])
    if not hit:
        scene.world = build.mean_world(plate8.reshape(-1, 3).mean(0))
        mean = run.render(scene, folder / "Plate mean mirror.exr", border)
        renders += 1
    else:
        mean = read_rgba(str(folder / "Plate mean mirror.exr"))
    scene.world = dome
    seen = {}
    if probe:  # the scene's own HDRI at infinity around the subject alone
        path = folder / f"{run.PROBE} mirror.exr"
        if path.is_file():
            seen[run.PROBE] = read_rgba(str(path))
        else:
            seen[run.PROBE] = run.render(scene, path, border)
            renders += 1
    return plate, truth, plate8, mean, seen, renders


def _default_mirror(
    spec, addon, scene, subject, folder, work, border, surroundings, contact_shadow, split
):
    """The default method's mirror (Replace look, the 8-bit plate, Auto resolution, the
    panel's ``surroundings`` and ``contact_shadow`` if given): Generate timed, then its render;
    with ``split`` the same maps with the sky prior black rendered too. Returns (the method's
    label, its render, the black-sky render or None, Generate's report, its seconds, the
    number of renders)."""
    label = run.default_method_label(addon)
    settings = scene.virtual_reflections
    settings.plate_image = bpy.data.images.load(str(folder / "plate.png"))
    settings.resolution = "AUTO"
    settings.method = scene.virtual_reflections.bl_rna.properties["method"].default
    settings.combine = "REPLACE"
    kind = run.surroundings_of(spec, surroundings)
    if kind is not None:
        settings.surroundings = kind
    if contact_shadow is not None:
        settings.contact_shadow = contact_shadow
    subject.virtual_reflections.enabled = True
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    report = addon.generate.generate(scene, depsgraph, [subject])
    seconds = time.perf_counter() - t0
    if not report.done:
        raise RuntimeError(f"{spec.name}: Generate ({label}) made nothing: {report.warnings}")
    work.mkdir(parents=True, exist_ok=True)
    method = run.render(scene, work / f"{spec.name} {label}.exr", border)
    renders = 1
    addon.generate.remove_all()
    dark = None
    if split:  # the same maps with the sky prior black: the pixels it sets are those that change
        with sky_gain(addon, 0.0):
            depsgraph = bpy.context.evaluated_depsgraph_get()
            dark_report = addon.generate.generate(scene, depsgraph, [subject])
        if not dark_report.done:
            raise RuntimeError(f"{spec.name}: Generate ({label}, sky gain 0) made nothing")
        dark = run.render(scene, work / f"{spec.name} {label} sky 0.exr", border)
        renders += 1
        addon.generate.remove_all()
    return label, method, dark, report, seconds, renders


def _split(composites, dark, plate, truth, mask, crop, results, label, plate8, spec) -> dict:
    """The record's "split": `error_split` of the default against its black-sky render
    ``dark``, with the PSNR over the plate mean at every scale of the prior
    (`prior_level.scale_curve`), the ground band's levels and every tint of the prior."""
    black = dark[..., :3] + (1.0 - dark[..., 3:4]) * plate
    split = error_split(composites, black, truth, mask, label)
    split["prior_scales"] = prior_level.scale_curve(
        composites[label], black, truth, mask, crop, results[run.MEAN]["psnr"]
    )
    split["band"] = prior_level.band_levels(plate8, spec.hfov_deg(), spec.pitch_deg)
    split["tints"] = prior_colour.tint_scores(
        composites[label], black, truth, mask, crop, results[run.MEAN]["psnr"],
        [float(c) for c in plate8.reshape(-1, 3).mean(0)],
    )  # fmt: skip
    return split


SPLIT_CHANGE = 0.02  # display units: a pixel the sky prior sets changes more than this with it off


def error_split(composites: dict, dark, truth, mask, label: str) -> dict:
    """Where the default method's error lies: the subject's pixels the sky prior sets (they
    change by more than SPLIT_CHANGE in any channel when the prior is black: `dark`, the
    default's composite with Params.sky_gain = 0) and the others (the ground, the plate's
    extension at the horizon, the seen region). Per method in ``composites`` (linear
    composites over the plate), the mean squared display error over the subject's pixels
    and channels, split in those two parts (they add up to the MSE its PSNR is taken from),
    and of the first part its level: the squared difference of the method's mean and the
    truth's on those pixels (per channel, averaged), weighted as the part is. Returns
    {"sky_share": share of the subject's pixels, "truth_spread": the truth's own variance on
    those pixels (per channel, averaged; weighted alike), name: {"sky": .., "rest": ..,
    "sky_level": ..}}."""
    shown = {name: run.to_display(image)[mask] for name, image in composites.items()}
    target = run.to_display(truth)[mask]
    sky = np.abs(shown[label] - run.to_display(dark)[mask]).max(axis=1) > SPLIT_CHANGE
    share = float(sky.mean())
    out = {"sky_share": share, "truth_spread": float(target[sky].var(0).mean()) * share}
    for name, values in shown.items():
        error = ((values - target) ** 2).mean(axis=1) / max(int(mask.sum()), 1)
        level = ((values[sky].mean(0) - target[sky].mean(0)) ** 2).mean() * share
        out[name] = {
            "sky": float(error[sky].sum()),
            "rest": float(error[~sky].sum()),
            "sky_level": float(level),
        }
    return out


@contextlib.contextmanager
def sky_gain(addon: run.Addon, gain):
    """While inside: the add-on's maps built with Params.sky_gain = ``gain`` (None: as is), by
    wrapping its `pipeline.map_params` (the one place Generate takes its Params from)."""
    if gain is None:
        yield
        return
    pipeline = importlib.import_module(f"{addon.module.__name__}.operators.pipeline")
    original = pipeline.map_params

    def map_params(*args, **kwargs):
        return dataclasses.replace(original(*args, **kwargs), sky_gain=float(gain))

    pipeline.map_params = map_params
    try:
        yield
    finally:
        pipeline.map_params = original


def run_scenes(
    specs,
    cache,
    work,
    width,
    samples,
    log,
    gain=None,
    split=False,
    surroundings=None,
    oracle=None,
    contact_shadow=None,
):
    """Every scene's mirror in turn; returns (records, crops, [the default method's label]).
    ``gain``: the sky prior's gain for this run (None: the add-on's default); ``split``: each
    record's error split (`error_split`); ``surroundings``: the panel's Surroundings set in
    each scene (`run.surroundings_of`; a ``gain`` overrides it); ``oracle``: each scene's rows
    of that oracle (`oracles`); ``contact_shadow``: the panel's Contact Shadow in each scene
    (None: the add-on's)."""
    addon = run.Addon()
    records, crops = [], {}
    try:
        label = run.default_method_label(addon)
        with sky_gain(addon, gain):
            for spec in specs:
                record, scene_crops = run_scene(
                    spec,
                    addon,
                    pathlib.Path(cache),
                    pathlib.Path(work),
                    width,
                    samples,
                    log,
                    split,
                    surroundings,
                    oracle,
                    contact_shadow,
                )
                records.append(record)
                crops[spec.name] = scene_crops
    finally:
        run.new_file()
        addon.close()
    return records, crops, [label]


def table(data) -> str:
    """Per scene and on average: the default method's and the plate mean's mirror PSNR / SSIM
    / FLIP, the default's detail ratio on the upper half, how many scenes the default is ahead
    in and its worst scene."""
    label = data["addon_methods"][0]
    rows = [
        f"| scene | HDRI | {label} PSNR | plate mean PSNR | difference | {label} SSIM | "
        f"plate mean SSIM | {label} FLIP | plate mean FLIP | {label} upper-half detail |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    dp, ds = [], []
    for record in data["scenes"]:
        r = record["results"][MIRROR]
        a, m = r[label], r[run.MEAN]
        dp.append(a["psnr"] - m["psnr"])
        ds.append(a["ssim"] - m["ssim"])
        rows.append(
            f"| {record['scene']['name']} | {record['scene']['hdri']} | {a['psnr']:.2f} | "
            f"{m['psnr']:.2f} | {dp[-1]:+.2f} | {a['ssim']:.3f} | {m['ssim']:.3f} | "
            f"{a.get('flip', math.nan):.3f} | {m.get('flip', math.nan):.3f} | "
            f"{a.get('detail_upper', math.nan):.2f} |"
        )

    def values(key, name):
        return [s["results"][MIRROR][name].get(key, math.nan) for s in data["scenes"]]

    def mean(key, name):
        return float(np.nanmean(values(key, name)))

    n = len(data["scenes"])
    rows.append(
        f"| mean | | {mean('psnr', label):.2f} | {mean('psnr', run.MEAN):.2f} | "
        f"{np.mean(dp):+.2f} | {mean('ssim', label):.3f} | {mean('ssim', run.MEAN):.3f} | "
        f"{mean('flip', label):.3f} | {mean('flip', run.MEAN):.3f} | "
        f"{float(np.nanmedian(values('detail_upper', label))):.2f} (median) |"
    )
    spread = f" (standard error {np.std(dp, ddof=1) / math.sqrt(n):.2f})" if n > 1 else ""
    rows.append(
        f"\nahead of the plate mean: PSNR in {sum(d > 0 for d in dp)}/{n}, SSIM in "
        f"{sum(d > 0 for d in ds)}/{n}; mean difference {np.mean(dp):+.2f} dB{spread}, "
        f"{np.mean(ds):+.3f} SSIM; worst scene {min(dp):+.2f} dB"
    )
    return "\n".join(rows)


def split_table(data) -> str:
    """Where the default method's mirror error lies (`error_split`): per scene, the share of
    the subject's pixels the sky prior sets and the mean squared display error on them and on
    the rest, the default's and the plate mean's; then what the mean PSNR difference over the
    plate mean would be if one part of the default's error were smaller (what a better model
    of that part could gain at most, the other part as it is)."""
    label = data["addon_methods"][0]
    rows = [
        f"| scene | sky share | {label}: sky / rest | plate mean: sky / rest |",
        "|---|---|---|---|",
    ]
    parts = []
    for record in data["scenes"]:
        split = record["split"]
        ours, mean = split[label], split[run.MEAN]
        parts.append((ours["sky"], ours["rest"], mean["sky"], mean["rest"]))
        rows.append(
            f"| {record['scene']['name']} | {split['sky_share']:.2f} | {ours['sky']:.4f} / "
            f"{ours['rest']:.4f} | {mean['sky']:.4f} / {mean['rest']:.4f} |"
        )
    p = np.array(parts)
    share = np.mean([r["split"]["sky_share"] for r in data["scenes"]])
    rows.append(
        f"| mean | {share:.2f} | {p[:, 0].mean():.4f} / {p[:, 1].mean():.4f} | "
        f"{p[:, 2].mean():.4f} / {p[:, 3].mean():.4f} |"
    )
    base = -10 * np.log10(p[:, 2] + p[:, 3])  # the plate mean's PSNR
    level = np.mean([r["split"][label]["sky_level"] for r in data["scenes"]])
    spread = np.mean([r["split"]["truth_spread"] for r in data["scenes"]])
    rows.append("")
    rows.append(
        f"of {label}'s error on the prior's pixels ({p[:, 0].mean():.4f}): its level "
        f"{level:.4f}, the truth's own spread about its mean {spread:.4f}"
    )
    for text, sky, rest in (
        ("as rendered", 1.0, 1.0),
        ("the rest's error halved", 1.0, 0.5),
        ("no error on the rest", 1.0, 0.0),
        ("the sky's error 10 % smaller", 0.9, 1.0),
    ):
        d = -10 * np.log10(sky * p[:, 0] + rest * p[:, 1]) - base
        ahead = int((d > 0).sum())
        rows.append(f"{text}: {d.mean():+.2f} dB over the plate mean, ahead in {ahead}/{len(d)}")
    return "\n".join(rows)


def oracle_table(data, oracle: str) -> str:
    """Per scene and on average: the mirror PSNR of the default, of each row of ``oracle``
    (`oracles.labels`) and of the plate mean; then each one's mean difference over the plate
    mean and the scenes it is ahead in."""
    label = data["addon_methods"][0]
    names = (label, *oracles.labels(label, oracle))
    rows = [
        "| scene | " + " | ".join(names) + " | plate mean |",
        "|---|" + "---|" * (len(names) + 1),
    ]
    over = {name: [] for name in names}
    for record in data["scenes"]:
        r = record["results"][MIRROR]
        for name in names:
            over[name].append(r[name]["psnr"] - r[run.MEAN]["psnr"])
        cells = " | ".join(f"{r[name]['psnr']:.2f}" for name in names)
        rows.append(f"| {record['scene']['name']} | {cells} | {r[run.MEAN]['psnr']:.2f} |")
    rows.append("")
    n = len(data["scenes"])
    for name in names:
        d = np.array(over[name])
        rows.append(f"{name}: {d.mean():+.2f} dB over the plate mean, ahead in {(d > 0).sum()}/{n}")
    return "\n".join(rows)
