"""The ray-traced pass seen from inside (issue 11, item 4): seeing against blind.

The add-on's passes trace Camera View + Ground's Replace look under Cycles in one render
(`operators/traced_pass.py`: every object a mirror, the default's own lookup on a dome for
whatever else a ray meets). This command renders the inter-reflection cases (inter.py) three
ways: the product's one pass (Generate, one render), the traced pass with the mirrors seeing
each other (what the add-on's pass 2 renders), and the same with the mirrors blind to each
other (each sees only the dome). Blind should score as one pass (the dome reproduces the
material's lookup); seeing minus blind is what the tracing adds. Scores as inter.py: all the
mirrors' pixels and the inter pixels (where the truth differs from the truth with the mirrors
blind to each other). docs/scenes3d.md, "Ray-traced inter-reflections".

    python -m study traced [--quick] [--out DIR]
"""

from __future__ import annotations

import importlib
import json
import pathlib
import shutil
import sys
import tempfile
import time

import bpy
import numpy as np

from ..evaluate.metrics import to_display
from . import build, inter, scenes
from .run import border_pixels, new_file, render, score, write_png

ONE, SEEING, BLIND = "one pass", "ray traced", "ray traced, mirrors blind"
RUNS = (ONE, SEEING, BLIND)


def run_scene(spec, addon, work: pathlib.Path, width, samples, log):
    """One case: plate, truth, blind truth, the product's one pass, the traced pass seeing
    and blind. Returns the record."""
    started = time.perf_counter()
    new_file()
    scene, camera, subject, others, _, material = build.build(spec, width, samples)
    mirrors = [subject, *build.add_companions(scene, spec, material)]
    scene.cycles.glossy_bounces = inter.GLOSSY_BOUNCES
    scene.cycles.max_bounces = inter.GLOSSY_BOUNCES + 2
    work.mkdir(parents=True, exist_ok=True)
    for obj in mirrors:
        obj.hide_render = True
    scene.render.film_transparent = False
    plate = render(scene, work / "plate.exr")[..., :3]
    write_png(work / "plate.png", plate)
    for obj in mirrors:
        obj.hide_render = False
    border = inter.union_border(scene, camera, mirrors)
    crop = border_pixels(border, width, scene.render.resolution_y)
    truth = render(scene, work / "truth.exr", border)[..., :3]
    for obj in mirrors:
        obj.visible_glossy = False
    blind = render(scene, work / "blind.exr", border)[..., :3]
    for obj in mirrors:
        obj.visible_glossy = True

    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    settings = scene.virtual_reflections
    settings.plate_image = bpy.data.images.load(str(work / "plate.png"))
    settings.resolution = "AUTO"
    settings.method = settings.bl_rna.properties["method"].default
    settings.combine = "REPLACE"
    for obj in mirrors:
        obj.virtual_reflections.enabled = True
    report = addon.generate.generate(scene, bpy.context.evaluated_depsgraph_get(), mirrors)
    if not report.done:
        raise RuntimeError(f"{spec.name}: Generate made nothing: {report.warnings}")
    rgba = {ONE: render(scene, work / "one.exr", border)}
    traced_pass = importlib.import_module(f"{addon.module.__name__}.operators.traced_pass")
    if not traced_pass.applies(scene, mirrors):
        raise RuntimeError(f"{spec.name}: the ray-traced pass does not apply")
    with traced_pass.traced(scene, mirrors):
        rgba[SEEING] = render(scene, work / "seeing.exr", border)
        for obj in mirrors:
            obj.visible_glossy = False
        try:
            rgba[BLIND] = render(scene, work / "traced blind.exr", border)
        finally:
            for obj in mirrors:
                obj.visible_glossy = True
    addon.generate.remove_all()

    mask = rgba[ONE][..., 3] > 0.5
    region = mask & (np.abs(to_display(truth) - to_display(blind)).max(-1) > inter.INTER_THRESHOLD)
    results = {}
    for run, image in rgba.items():
        composite = image[..., :3] + (1.0 - image[..., 3:4]) * plate
        results[run] = score(composite, truth, mask, crop)
        results[run]["inter psnr"] = score(composite, truth, region, crop)["psnr"]
    record = {
        "scene": spec.to_json(),
        "mirrors": len(mirrors),
        "subject_pixels": int(mask.sum()),
        "inter_pixels": int(region.sum()),
        "results": results,
        "seconds": time.perf_counter() - started,
    }
    log(
        f"{spec.name}: "
        + ", ".join(
            f"{run} {r['psnr']:.2f} dB (inter {r['inter psnr']:.2f})" for run, r in results.items()
        )
    )
    return record


def table(data) -> str:
    """Per case and on average: PSNR / SSIM on all the mirrors' pixels, PSNR on the inter px."""
    head = " | ".join(RUNS)
    lines = [
        f"| case | mirrors: px (inter px) | {head} | ray traced − one pass |",
        "|---|---|" + "---|" * (len(RUNS) + 1),
    ]

    def cell(r):
        return f"{r['psnr']:.2f} / {r['ssim']:.3f} ({r['inter psnr']:.2f})"

    for rec in data["scenes"]:
        res = rec["results"]
        gain = res[SEEING]["psnr"] - res[ONE]["psnr"]
        lines.append(
            f"| {rec['scene']['name']} | {rec['mirrors']}: {rec['subject_pixels']} "
            f"({rec['inter_pixels']}) | "
            + " | ".join(cell(res[r]) for r in RUNS)
            + f" | {gain:+.2f} dB |"
        )
    mean = {
        r: {
            k: float(np.mean([rec["results"][r][k] for rec in data["scenes"]]))
            for k in ("psnr", "ssim", "inter psnr")
        }
        for r in RUNS
    }
    ahead = sum(
        rec["results"][SEEING]["psnr"] > rec["results"][ONE]["psnr"] for rec in data["scenes"]
    )
    lines.append(
        "| mean | | "
        + " | ".join(cell(mean[r]) for r in RUNS)
        + f" | {mean[SEEING]['psnr'] - mean[ONE]['psnr']:+.2f} dB, ahead in {ahead}/"
        f"{len(data['scenes'])} |"
    )
    return "\n".join(lines)


def run_command(quick=False, out=None, log=None, width=320, samples=32):
    """Run the cases (quick: the two spheres), print the table; with ``out`` write
    OUT/scenes3d_traced.json and the table into OUT/scenes3d.md."""
    from . import report

    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    addon = inter.InterAddon()
    work = pathlib.Path(tempfile.mkdtemp(prefix="vr_traced_"))
    started = time.perf_counter()
    try:
        records = [
            run_scene(spec, addon, work / spec.name, width, samples, say)
            for spec in scenes.inter_set(quick)
        ]
    finally:
        new_file()
        addon.close()
        shutil.rmtree(work, ignore_errors=True)
    data = {
        "command": "python -m study traced" + (" --quick" if quick else ""),
        "resolution": [width, round(width / scenes.ASPECT)],
        "samples": samples,
        "glossy_bounces": inter.GLOSSY_BOUNCES,
        "scenes": records,
        "bpy": bpy.app.version_string,
        "seconds": time.perf_counter() - started,
    }
    text = table(data)
    print(text)
    if out is not None:
        out = pathlib.Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"scenes3d_traced{'_quick' if quick else ''}.json").write_text(
            json.dumps(data, indent=1) + "\n"
        )
        report.add_block(
            out / "scenes3d.md", "traced", "Ray-traced inter-reflections", text, data["command"]
        )
    return data
