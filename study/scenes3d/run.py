"""Render and score the 3D scenes (bpy, Cycles on the CPU), one process, bpy imported once.

Per scene: the plate (the scene without the subject: float EXR and 8-bit sRGB PNG), the truth
(the subject in the full scene as a mirror and as a rough glossy at two roughnesses), and each
method's render of the subject alone (ground and neighbours hidden from render) over the plate:
the add-on's methods (read from operators/scene/choices.py METHOD_ITEMS at run time; Generate on the
8-bit plate, Auto resolution, combine Replace for the mirror and World for the rough subjects)
and three worlds around the subject's own material (the true HDRI at infinity: an on-set
probe; the plate stretched over the sphere; the plate's mean colour). Metrics on the subject's
pixels (study/evaluate/metrics.py): PSNR and SSIM of display values, si-RMSE of linear values
clipped at white.
"""

from __future__ import annotations

import importlib
import math
import pathlib
import time

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from .. import polyhaven
from ..evaluate.metrics import psnr, si_rmse, ssim, to_display
from ..evaluate.perceptual import detail_ratio, flip_ldr, upper_half
from ..sky_prior import KINDS
from . import build
from .scenes import Scene3D

# (name, roughness, the add-on's combine mode for it): the rough subjects in the World look
# (their own glossy BSDF lit by the map) and in the Mix look (the map pre-filtered for their
# roughness, issue 11 item 3), with IOR 4 and strength `MIX_STRENGTH`: the Mix weight
# min(1, strength x Fresnel) is 1 at every angle (Fresnel >= 0.36 at IOR 4), so the map is
# the whole reflection, as for a metal, and the material's own BSDF (lit by the true dome in
# these renders) has no part in it; the truth and baselines are rendered once per roughness.
MATERIALS = (
    ("mirror", 0.0, "REPLACE"),
    ("rough 0.15", 0.15, "WORLD"),
    ("rough 0.35", 0.35, "WORLD"),
    ("rough 0.15, Mix", 0.15, "MIX"),
    ("rough 0.35, Mix", 0.35, "MIX"),
)
MIX_IOR, MIX_STRENGTH = 4.0, 3.0
PROBE, STRETCHED, MEAN = "On-set probe", "Plate stretched", "Plate mean"
BASELINES = (PROBE, STRETCHED, MEAN)
# the issue-41 metrics: LDR-FLIP (lower is better) and the detail ratio, the subject's and its
# upper half's (study/evaluate/perceptual.py)
METRICS = ("psnr", "ssim", "si_rmse", "flip", "detail", "detail_upper")
GROUND_CHOSEN = "Camera View + Ground (ground chosen)"
NAMED = "Camera View + Ground (surroundings named)"  # the artist's: surroundings_of
WORLD_HDRI = "Camera View + Ground (world HDRI)"  # Surroundings: World HDRI, the dome as world


class Addon:
    """The add-on registered for the run (build_scenes.addon: this checkout as a package, or
    the copy already imported); `close` unregisters it if this run registered it (bpy 4.5
    hangs at exit otherwise)."""

    def __init__(self):
        self.module, self.registered = build.build_scenes().addon()
        self.generate = importlib.import_module(f"{self.module.__name__}.operators.generate")
        choices = importlib.import_module(f"{self.module.__name__}.operators.scene.choices")
        self.methods = [(item[0], item[1]) for item in choices.METHOD_ITEMS]

    def close(self):
        if self.registered:
            self.module.unregister()
            self.registered = False


def new_file():
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    return bpy.context.scene


def render(scene, path, border=None) -> np.ndarray:
    """Render the scene to a float RGBA EXR at ``path``; (H, W, 4) premultiplied linear."""
    r = scene.render
    r.filepath = str(path)
    r.use_file_extension = False
    settings = r.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    r.use_border = border is not None
    if border is not None:
        r.use_crop_to_border = False
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = border
    bpy.ops.render.render(write_still=True)
    return read_rgba(str(path))


def subject_border(scene, camera, subject, margin=0.04):
    """The subject's screen box (fractions, y up) from its bounding box's corners, widened."""
    corners = [subject.matrix_world @ Vector(c) for c in subject.bound_box]
    uv = np.array([tuple(world_to_camera_view(scene, camera, c))[:2] for c in corners])
    lo = np.clip(uv.min(0) - margin, 0.0, 1.0)
    hi = np.clip(uv.max(0) + margin, 0.0, 1.0)
    return (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def border_pixels(border, width, height):
    """(y0, y1, x0, x1) rows top first, one pixel inside the border on each side."""
    x0, x1, y0, y1 = border
    return (
        math.floor((1 - y1) * height) + 1,
        math.ceil((1 - y0) * height) - 1,
        math.floor(x0 * width) + 1,
        math.ceil(x1 * width) - 1,
    )


def write_png(path, linear):
    """8-bit sRGB PNG of scene-linear RGB (clipped), as a photograph would be delivered."""
    import OpenImageIO as oiio

    codes = np.round(to_display(linear) * 255.0).astype(np.uint8)
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(codes.shape[1], codes.shape[0], 3, "uint8")
    if not (out.open(str(path), spec) and out.write_image(codes) and out.close()):
        raise OSError(f"cannot write {path}")


def score(pred_linear, truth_linear, mask, crop) -> dict:
    y0, y1, x0, x1 = crop
    p, t, m = pred_linear[y0:y1, x0:x1], truth_linear[y0:y1, x0:x1], mask[y0:y1, x0:x1]
    pd, td = to_display(p), to_display(t)
    return {
        "psnr": psnr(pd, td, m),
        "ssim": ssim(pd, td, m),
        "si_rmse": si_rmse(np.clip(p, 0, 1), np.clip(t, 0, 1), m),
        "flip": flip_ldr(pd, td, m),
        "detail": detail_ratio(pd, td, m),
        "detail_upper": detail_ratio(pd, td, m, upper_half(m)),
    }


def run_scene(
    spec: Scene3D,
    addon: Addon,
    work: pathlib.Path,
    width: int,
    samples: int,
    log,
    ground_chosen: bool = False,
    named: bool = False,
):
    """One scene: renders, Generate per method, scores. Returns (record, mirror crops).
    ``ground_chosen``: also Camera View + Ground with the ground plane chosen as the scene's
    Ground object (the method row GROUND_CHOSEN); ``named``: also Camera View + Ground with
    the scene's Surroundings named as an artist would, by the kind of its HDRI (the row
    NAMED, `surroundings_of`), and with Surroundings: World HDRI, the scene's dome (the on-set
    probe) read from its world (the row WORLD_HDRI)."""
    started = time.perf_counter()
    new_file()
    scene, camera, subject, others, dome, material = build.build(spec, width, samples)
    height = scene.render.resolution_y
    work.mkdir(parents=True, exist_ok=True)
    renders = 0

    def shot(name, border=None):
        nonlocal renders
        renders += 1
        return render(scene, work / f"{name}.exr", border)

    # (a) the plate
    subject.hide_render = True
    scene.render.film_transparent = False
    plate = shot("plate")[..., :3]
    write_png(work / "plate.png", plate)
    subject.hide_render = False
    border = subject_border(scene, camera, subject)
    crop = border_pixels(border, width, height)

    # (b) the truth, the subject in the full scene
    truth = _truths(material, shot, border)

    # (c) the subject alone over the plate
    plate_image, plate8, alone = _baselines(scene, others, dome, material, spec, work, shot, border)

    times, warnings, methods = _addon_methods(
        scene, subject, others, material, spec, addon, plate_image, alone, shot, border,
        ground_chosen, named,
    )  # fmt: skip

    # scores on the subject's pixels
    mask = alone["mirror"][PROBE][..., 3] > 0.5
    results, crops = _scores(alone, truth, plate, mask, crop)
    finite = {label: bool(np.isfinite(alone["mirror"][label]).all()) for _, label in methods}
    record = {
        "scene": spec.to_json(),
        "subject_pixels": int(mask.sum()),
        "results": results,
        "generate_s": times,
        "finite": finite,
        "warnings": warnings,
        "renders": renders,
        "seconds": time.perf_counter() - started,
        "plate_mean": [float(c) for c in plate8.reshape(-1, 3).mean(0)],
    }
    mirror = results["mirror"]
    log(
        f"{spec.name}: {mask.sum()} px, mirror PSNR "
        + ", ".join(f"{m} {v['psnr']:.1f}" for m, v in mirror.items())
        + f" ({record['seconds']:.0f} s, {renders} renders)"
    )
    return record, crops


def _truths(material, shot, border) -> dict:
    """The truth per material of MATERIALS: the subject in the full scene, one render per
    roughness (``shot(name, border)`` renders)."""
    truth, by_roughness = {}, {}
    for name, roughness, _ in MATERIALS:
        if roughness not in by_roughness:
            build.set_roughness(material, roughness)
            by_roughness[roughness] = shot(f"truth {name}", border)[..., :3]
        truth[name] = by_roughness[roughness]
    return truth


def _baselines(scene, others, dome, material, spec, work, shot, border):
    """The neighbours hidden, the film transparent: the baselines' renders of the subject
    alone (the on-set probe, the plate stretched, the plate mean) per roughness. Returns (the
    8-bit plate as a Blender image, it linear, {material: {baseline: RGBA}})."""
    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    plate_image = bpy.data.images.load(str(work / "plate.png"))
    plate8 = srgb_to_linear(read_rgba(str(work / "plate.png"))[..., :3])
    worlds = {
        PROBE: dome,
        STRETCHED: build.stretched_world(plate_image, spec),
        MEAN: build.mean_world(plate8.reshape(-1, 3).mean(0)),
    }
    alone = {name: {} for name, _, _ in MATERIALS}
    baselines = {}
    for name, roughness, _ in MATERIALS:
        if roughness not in baselines:
            build.set_roughness(material, roughness)
            baselines[roughness] = {}
            for baseline, world in worlds.items():
                scene.world = world
                baselines[roughness][baseline] = shot(f"{baseline} {name}", border)
        alone[name].update(baselines[roughness])
    scene.world = dome
    build.set_roughness(material, 0.0)
    return plate_image, plate8, alone


def _addon_methods(
    scene, subject, others, material, spec, addon, plate_image, alone, shot, border,
    ground_chosen, named,
):  # fmt: skip
    """Each add-on method (and the GROUND_CHOSEN, NAMED and WORLD_HDRI rows if asked): one
    Generate per look and, in the Mix and World looks, per roughness, the subject rendered
    alone into ``alone``. Returns (Generate's seconds per method and look, its warnings, the
    (identifier, label) of every method run)."""
    settings = scene.virtual_reflections
    settings.plate_image = plate_image
    settings.resolution = "AUTO"
    subject.virtual_reflections.enabled = True
    times, warnings = {}, {}
    methods = list(addon.methods)
    if ground_chosen:  # the ground plane picked as the Ground object (the failure cases)
        methods.append(("GROUND", GROUND_CHOSEN))
    if named:
        methods += [("GROUND", NAMED), ("GROUND", WORLD_HDRI)]
    for ident, label in methods:
        settings.method = ident
        settings.ground_object = others[0] if label == GROUND_CHOSEN else None
        settings.surroundings = {NAMED: surroundings_of(spec, "artist"), WORLD_HDRI: "WORLD"}.get(
            label, "AUTO"
        )
        times[label] = {}
        # One Generate per look, and in the Mix and World looks one per roughness, read at
        # Generate: the Mix look's map is pre-filtered for it, and in both the unseen sky is
        # the one a surface of that roughness sees (params.sky_gain_for).
        runs = [("REPLACE", 0.0)]
        for look in ("MIX", "WORLD"):
            runs += [(look, r) for r in dict.fromkeys(r for _, r, c in MATERIALS if c == look)]
        for combine, generate_roughness in runs:
            settings.combine = combine
            settings.ior = MIX_IOR if combine == "MIX" else 1.45
            settings.strength = MIX_STRENGTH if combine == "MIX" else 1.0
            build.set_roughness(material, generate_roughness)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            t0 = time.perf_counter()
            report = addon.generate.generate(scene, depsgraph, [subject])
            times[label].setdefault(combine, time.perf_counter() - t0)  # the first (mirror)
            if report.warnings:
                warnings.setdefault(label, []).extend(report.warnings)
            if not report.done:
                raise RuntimeError(
                    f"{spec.name}: Generate ({label}) made nothing: {report.warnings}"
                )
            for name, roughness, mode in MATERIALS:
                if mode != combine or generate_roughness != roughness:
                    continue
                build.set_roughness(material, roughness)
                alone[name][label] = shot(f"{ident} {name}", border)
            addon.generate.remove_all()
            build.set_roughness(material, 0.0)
    settings.ground_object = None
    settings.surroundings = "AUTO"
    return times, warnings, methods


def _scores(alone, truth, plate, mask, crop):
    """Each material's and method's composite over the plate scored against the truth on
    ``mask``, and the plate itself; the mirror's display crops with the truth's."""
    results, crops = {}, {}
    for name, _, _ in MATERIALS:
        results[name] = {}
        for method, rgba in alone[name].items():
            composite = rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plate
            results[name][method] = score(composite, truth[name], mask, crop)
            if name == "mirror":
                y0, y1, x0, x1 = crop
                crops[method] = to_display(composite[y0:y1, x0:x1])
        results[name]["(plate itself)"] = score(plate, truth[name], mask, crop)
    y0, y1, x0, x1 = crop
    crops["Truth"] = to_display(truth["mirror"][y0:y1, x0:x1])
    return results, crops


def surroundings_of(spec: Scene3D, surroundings) -> str | None:
    """The panel's Surroundings for ``spec`` under the study's ``--surroundings``: None (the
    add-on's default), "AUTO", "OPEN" or "ENCLOSED"; "artist": the kind of the scene's HDRI
    (`sky_prior.KINDS`, `polyhaven.KINDS`), what an artist would answer looking at the shot."""
    if surroundings is None:
        return None
    if surroundings == "artist":
        name = spec.hdri.removeprefix(polyhaven.PREFIX)
        kinds = polyhaven.KINDS if spec.hdri.startswith(polyhaven.PREFIX) else KINDS
        return next(kind for kind, names in kinds.items() if name in names).upper()
    return surroundings.upper()


def default_method_label(addon: Addon) -> str:
    """The label of the add-on's default method (the Scene setting's default)."""
    ident = bpy.context.scene.virtual_reflections.bl_rna.properties["method"].default
    return dict(addon.methods)[ident]


def run_scenes(specs, work, width, samples, log, ground_chosen=False, named=False):
    """Every scene in turn; the add-on is registered once and unregistered at the end.
    ``ground_chosen``: add the GROUND_CHOSEN method row (after the add-on's default);
    ``named``: the NAMED and WORLD_HDRI rows (after the add-on's default)."""
    addon = Addon()
    records, crops = [], {}
    try:
        for spec in specs:
            record, scene_crops = run_scene(
                spec,
                addon,
                pathlib.Path(work) / spec.name,
                width,
                samples,
                log,
                ground_chosen,
                named,
            )
            records.append(record)
            crops[spec.name] = scene_crops
        methods = [label for _, label in addon.methods]
        if ground_chosen:
            methods.insert(1 + methods.index(default_method_label(addon)), GROUND_CHOSEN)
        if named:
            at = 1 + methods.index(default_method_label(addon))
            methods[at:at] = [NAMED, WORLD_HDRI]
    finally:
        new_file()
        addon.close()
    return records, crops, methods
