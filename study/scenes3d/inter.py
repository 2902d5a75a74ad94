"""Inter-reflections against the 3D truth (issue 11, item 4): two or three mirror objects side
by side, path-traced with enough glossy bounces that each shows the others (and their
reflections) in the truth; per add-on method, one pass (Generate, one render) against the
paper's passes until converged (`operators/interreflect.py` `render_passes(..., "auto")`),
with each map as Generate builds it from the composite (``neighbours=False``) and with the
neighbours placed where they stand (the product's default), all composited over the plate.

Per scene: the plate (no mirrors), the truth (every mirror in the full scene), the truth with
the mirrors blind to each other (``visible_glossy`` off: where the two differ are the "inter"
pixels), the plate mean (the mirrors alone under a world of the 8-bit plate's mean colour: a
baseline; they see each other there too, in that grey), then per method the three renders of
the mirrors alone (ground and neighbours hidden, combine Replace: the chrome look;
`render_passes` refuses World). Metrics as run.py (PSNR and SSIM of display values, si-RMSE of
linear ones) on all the mirrors' pixels (alpha > 0.5), SSIM over the box around all of them;
PSNR on the inter pixels; and the most the passes could gain: one pass with its inter pixels
replaced by the truth's.
"""

from __future__ import annotations

import importlib
import pathlib
import time

import bpy
import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from ..evaluate.metrics import to_display
from . import build
from .run import (
    MEAN,
    Addon,
    border_pixels,
    default_method_label,
    new_file,
    render,
    score,
    subject_border,
    write_png,
)
from .scenes import Scene3D

GLOSSY_BOUNCES = 8  # the truth: mirrors in mirrors in mirrors ... (the passes stop near 3)
ONE, PLAIN, AUTO = "one pass", "auto, maps as built", "auto"
# (name, passes, render_passes' ``neighbours``): one pass; the passes with each map as Generate
# builds it from the composite (Listing 1); the passes with the neighbours placed in 3D
RUNS = ((ONE, 1, True), (PLAIN, "auto", False), (AUTO, "auto", True))
INTER_THRESHOLD = 0.05  # display units: a pixel whose truth changes this much is "inter"
PLATE_ITSELF = "(plate itself)"
CEILING = "one pass, inter pixels exact"
BLIND = "truth without inter-reflections"  # the mirrors blind to each other: a ceiling for 1 pass
# the default's ray-traced pass with the mirrors blind to each other: its lookup alone, which
# should score as one pass (what the tracing adds is auto minus this)
TRACED_BLIND = "ray traced, mirrors blind"


class InterAddon(Addon):
    """The add-on with the modules the passes need."""

    def __init__(self):
        super().__init__()
        self.interreflect = importlib.import_module(
            f"{self.module.__name__}.operators.interreflect"
        )
        self.plate = importlib.import_module(f"{self.module.__name__}.operators.scene.plate")
        self.traced_pass = importlib.import_module(f"{self.module.__name__}.operators.traced_pass")


def union_border(scene, camera, objects):
    """The screen box (fractions, y up) around every object's (subject_border)."""
    boxes = np.array([subject_border(scene, camera, obj) for obj in objects])
    return (
        float(boxes[:, 0].min()),
        float(boxes[:, 1].max()),
        float(boxes[:, 2].min()),
        float(boxes[:, 3].max()),
    )


def run_scene(spec: Scene3D, addon: InterAddon, work: pathlib.Path, width, samples, log):
    """One scene: plate, truth, plate mean, one pass and auto passes per method; scores.
    Returns (record, crops) with crops {column: display crop around the mirrors}."""
    started = time.perf_counter()
    new_file()
    scene, camera, subject, others, dome, material = build.build(spec, width, samples)
    objects = [subject, *build.add_companions(scene, spec, material)]
    scene.cycles.glossy_bounces = GLOSSY_BOUNCES
    scene.cycles.max_bounces = GLOSSY_BOUNCES + 2
    height = scene.render.resolution_y
    work.mkdir(parents=True, exist_ok=True)
    renders = 0

    def shot(name, border=None):
        nonlocal renders
        renders += 1
        return render(scene, work / f"{name}.exr", border)

    for obj in objects:
        obj.hide_render = True
    scene.render.film_transparent = False
    plate = shot("plate")[..., :3]
    write_png(work / "plate.png", plate)
    for obj in objects:
        obj.hide_render = False
    border = union_border(scene, camera, objects)
    crop = border_pixels(border, width, height)
    truth = shot("truth", border)[..., :3]
    for obj in objects:  # the same mirrors, blind to each other: where inter-reflections show
        obj.visible_glossy = False
    blind = shot("truth without inter-reflections", border)[..., :3]
    for obj in objects:
        obj.visible_glossy = True

    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    plate_image = bpy.data.images.load(str(work / "plate.png"))
    plate8 = srgb_to_linear(read_rgba(str(work / "plate.png"))[..., :3])
    scene.world = build.mean_world(plate8.reshape(-1, 3).mean(0))
    alone = {MEAN: shot("plate mean", border)}
    scene.world = dome
    mask = alone[MEAN][..., 3] > 0.5
    changed = np.abs(to_display(truth) - to_display(blind)).max(-1) > INTER_THRESHOLD
    region = mask & changed

    passes, warnings, count = _run_passes(scene, addon, objects, plate_image, alone)
    renders += count
    traced_label = _traced_blind(scene, addon, objects, border, alone, shot)

    results, inter, crops = _scored(
        alone, plate, blind, truth, mask, region, crop, passes, traced_label
    )
    record = {
        "scene": spec.to_json(),
        "mirrors": len(objects),
        "subject_pixels": int(mask.sum()),
        "inter_pixels": int(region.sum()),
        "results": {
            "mirror": {m: results[m] for m in (MEAN, PLATE_ITSELF, BLIND)},
            "inter": {m: inter[m] for m in (MEAN, PLATE_ITSELF, BLIND)},
        },
        "passes": passes,
        "warnings": warnings,
        "renders": renders,
        "seconds": time.perf_counter() - started,
    }
    log(
        f"{spec.name}: {mask.sum()} px ({region.sum()} inter), PSNR one pass / auto as built / "
        "auto: "
        + ", ".join(
            f"{m} {p[ONE]['psnr']:.2f} / {p[PLAIN]['psnr']:.2f} / {p[AUTO]['psnr']:.2f} "
            f"(r = {p[AUTO]['passes']})"
            for m, p in passes.items()
        )
        + f"; plate mean {results[MEAN]['psnr']:.2f} ({record['seconds']:.0f} s, "
        f"{renders} renders)"
    )
    return record, crops


def _run_passes(scene, addon, objects, plate_image, alone):
    """Each add-on method's runs of RUNS (one pass; the passes with the maps as built; auto)
    on the mirrors over the plate, Replace look, each composite's RGBA put in ``alone``.
    Returns (per method and run its passes, changes and seconds; per method its warnings;
    the number of renders)."""
    settings = scene.virtual_reflections
    settings.plate_image = plate_image
    settings.resolution = "AUTO"
    settings.combine = "REPLACE"
    for obj in objects:
        obj.virtual_reflections.enabled = True
    pixels, _ = addon.plate.pixels(scene)
    passes, warnings, count = {}, {}, 0
    for ident, label in addon.methods:
        settings.method = ident
        passes[label] = {}
        for run, asked, placed in RUNS:
            depsgraph = bpy.context.evaluated_depsgraph_get()
            t0 = time.perf_counter()
            _, rgba, reports = addon.interreflect.render_passes(
                scene, depsgraph, objects, pixels, passes=asked, neighbours=placed
            )
            seconds = time.perf_counter() - t0
            count += len(reports)
            warnings[label] = sorted({w for r in reports for w in r.warnings})
            alone[f"{label}: {run}"] = rgba
            passes[label][run] = {
                "passes": len(reports),
                "changes": [r.change for r in reports],
                "seconds": seconds,
            }
            addon.generate.remove_all()
    return passes, warnings, count


def _scored(alone, plate, blind, truth, mask, region, crop, passes, traced_label):
    """Every column composited over the plate (and the plate itself, the blind truth) scored
    on the mirrors' pixels and on the inter pixels, the scores put in ``passes`` with each
    method's ceiling (one pass with the inter pixels the truth's). Returns (scores, inter
    scores, display crops)."""
    results, inter, crops = {}, {}, {}
    y0, y1, x0, x1 = crop
    composites = {
        column: rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plate for column, rgba in alone.items()
    }
    composites[PLATE_ITSELF] = plate
    composites[BLIND] = blind
    for column, composite in composites.items():
        results[column] = score(composite, truth, mask, crop)
        inter[column] = score(composite, truth, region, crop) if region.any() else None
        crops[column] = to_display(composite[y0:y1, x0:x1])
    crops["Truth"] = to_display(truth[y0:y1, x0:x1])
    for label in passes:
        for run, _, _ in RUNS:
            passes[label][run].update(results[f"{label}: {run}"])
            passes[label][run]["inter"] = inter[f"{label}: {run}"]
        # the most passes could bring: one pass with the inter pixels exactly the truth's
        perfect = composites[f"{label}: {ONE}"].copy()
        perfect[region] = truth[region]
        passes[label][CEILING] = score(perfect, truth, mask, crop)
    if traced_label is not None:
        blind_traced = f"{traced_label}: {TRACED_BLIND}"
        passes[traced_label][TRACED_BLIND] = dict(results[blind_traced], inter=inter[blind_traced])
    return results, inter, crops


def _traced_blind(scene, addon, objects, border, alone, shot):
    """The default method's ray-traced pass rendered with the mirrors blind to each other (into
    ``alone``); returns the method's label, or None when its pass is not traced."""
    default = scene.virtual_reflections.bl_rna.properties["method"].default
    label = dict(addon.methods)[default]
    scene.virtual_reflections.method = default
    report = addon.generate.generate(scene, bpy.context.evaluated_depsgraph_get(), objects)
    try:
        if not report.done or not addon.traced_pass.applies(scene, objects):
            return None
        with addon.traced_pass.traced(scene, objects):
            for obj in objects:
                obj.visible_glossy = False
            try:
                alone[f"{label}: {TRACED_BLIND}"] = shot(f"{label} {TRACED_BLIND}", border)
            finally:
                for obj in objects:
                    obj.visible_glossy = True
        return label
    finally:
        addon.generate.remove_all()


def run_scenes(specs, work, width, samples, log):
    """Every scene in turn; the add-on registered once. Returns (records, crops, methods), the
    add-on's default method first."""
    addon = InterAddon()
    records, crops = [], {}
    try:
        for spec in specs:
            record, scene_crops = run_scene(
                spec, addon, pathlib.Path(work) / spec.name, width, samples, log
            )
            records.append(record)
            crops[spec.name] = scene_crops
        default = default_method_label(addon)
        methods = [default] + [label for _, label in addon.methods if label != default]
    finally:
        new_file()
        addon.close()
    return records, crops, methods
