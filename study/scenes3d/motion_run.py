"""Render the motion sequences (bpy, Cycles on the CPU) and measure their change per frame pair.

One sequence (motion.Motion): the scene built once, the subject and camera keyed per frame.
Per frame: the plate (the subject hidden; float EXR and an 8-bit sRGB PNG numbered as an image
sequence), the truth (the subject as a mirror and as rough 0.35 in the full scene). Then per
method and look, as Update Every Frame does it: the PNG sequence as the plate, Generate at the
first frame, `sequence.update` at every frame (smoothing at its default), the subject rendered
alone over a transparent film and composited over that frame's float plate. A deliberately
discontinuous variant (the map updated only every HOLD frames) checks the popping rule.
"""

from __future__ import annotations

import importlib
import math
import pathlib
import time

import bpy
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from ..evaluate.metrics import psnr, to_display
from . import build, motion
from .run import Addon, new_file, render, subject_border, write_png
from .scenes import centre_height

HOLD = 3  # the held variant updates the map on every HOLD-th frame only
HELD = "held"


def _key(obj, frame, paths):
    for path in paths:
        obj.keyframe_insert(path, frame=frame)


def animate(motion_, scene, camera, subject) -> int:
    """Key the subject's and the camera's pose at every frame (1 ..); returns the frame count."""
    spec = motion_.spec
    for k, pose in enumerate(motion_.poses, 1):
        subject.location = (*pose.subject_xy, spec.lift)
        camera.location = (*pose.camera_xy, spec.camera_height)
        camera.rotation_euler = (
            math.radians(90.0 - spec.pitch_deg),
            0.0,
            math.radians(pose.pan_deg),
        )
        _key(subject, k, ("location",))
        _key(camera, k, ("location", "rotation_euler"))
    scene.frame_start, scene.frame_end = 1, len(motion_.poses)
    return len(motion_.poses)


def subject_on_screen(scene, camera, subject, spec) -> tuple:
    """((x, y) pixels, y down, radius in pixels) of the subject's bounding-sphere centre."""
    centre = subject.matrix_world.translation + Vector(
        (0.0, 0.0, centre_height(spec.shape, spec.size))
    )
    u, v, depth = world_to_camera_view(scene, camera, centre)
    w, h = scene.render.resolution_x, scene.render.resolution_y
    focal = camera.data.lens / camera.data.sensor_width * w
    return (u * w, (1.0 - v) * h), spec.size / 2 / depth * focal


def _labels(addon) -> dict:
    return dict(addon.methods)


def run_motion(
    motion_,
    addon: Addon,
    work: pathlib.Path,
    width,
    samples,
    log,
    held=True,
    methods=None,
    looks=None,
):
    """One sequence: renders, Update Every Frame per method and look, the change measures.
    Returns its record (motion.Motion.to_json() with per-column PSNR per frame, changes per
    pair and their summaries against the truth). ``methods``: the add-on's method identifiers
    (default motion.METHODS); ``looks``: names of motion.LOOKS (default all); ``held``: also
    the held variant (with the World look)."""
    looks = [entry for entry in motion.LOOKS if looks is None or entry[0] in looks]
    started = time.perf_counter()
    new_file()
    spec = motion_.spec
    scene, camera, subject, others, _dome, material = build.build(spec, width, samples)
    frames = animate(motion_, scene, camera, subject)
    # Not Persistent Data: with it, Cycles keeps the map pixels of the first render (bpy 4.5
    # and 5.2: a map rewritten in place by sequence.update is not synced again), so every
    # frame would show the first frame's map.
    scene.render.use_persistent_data = False
    work.mkdir(parents=True, exist_ok=True)
    sequence = importlib.import_module(f"{addon.module.__name__}.operators.sequence")
    renders = 0

    def shot(name, border=None):
        nonlocal renders
        renders += 1
        return render(scene, work / f"{name}.exr", border)

    plates, borders, where, truth = _plates_and_truths(
        scene, camera, subject, material, spec, frames, looks, shot, work
    )
    # (b) each method and look as Update Every Frame runs it, on the plate sequence
    settings = _on_the_plate_sequence(scene, others, subject, work)
    labels = _labels(addon)
    runs = [(m, look, r, c, False) for m in (methods or motion.METHODS) for look, r, c in looks]
    if held and any(c == "WORLD" for _, _, c in looks):
        runs.append(("GROUND", "rough 0.35", 0.35, "WORLD", True))
    alone, updates, masks = {}, {}, [None] * frames
    for method, look, roughness, combine, hold in runs:
        name = motion.column(labels[method], look) + (f" ({HELD})" if hold else "")
        settings.method, settings.combine = method, combine
        scene.frame_set(1)
        report = addon.generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [subject])
        if not report.done:
            raise RuntimeError(f"{motion_.name}: Generate ({name}) made nothing: {report.warnings}")
        build.set_roughness(material, roughness)
        alone[name], updates[name] = _every_frame(
            scene, sequence, shot, name, hold, frames, plates, borders, masks
        )
        addon.generate.remove_all()
        build.set_roughness(material, 0.0)

    columns = _columns(looks, truth, alone, updates, masks, where)
    record = motion_.to_json()
    record.update(
        {
            "subject_pixels": [int(m.sum()) for m in masks],
            "screen": [[round(c[0], 2), round(c[1], 2), round(r, 2)] for c, r in where],
            "columns": columns,
            "renders": renders,
            "seconds": time.perf_counter() - started,
        }
    )
    log(
        f"{motion_.name}: {frames} frames, {renders} renders, {record['seconds']:.0f} s; "
        + ", ".join(
            f"{n}: max ratio {c['summary']['aligned']['max_ratio']:.2f}, "
            f"pops {c['summary']['aligned']['pops']}"
            for n, c in columns.items()
            if "summary" in c
        )
    )
    return record


def _plates_and_truths(scene, camera, subject, material, spec, frames, looks, shot, work):
    """Frame by frame, the plate (also written as plate_NNNN.png, the sequence the methods
    read), the subject's render border, its place on screen and the truth of every look
    (``shot(name, border)`` renders). Returns (plates, borders, places, truths by look)."""
    plates, borders, where, truth = [], [], [], {look: [] for look, _, _ in motion.LOOKS}
    for k in range(1, frames + 1):
        scene.frame_set(k)
        subject.hide_render = True
        scene.render.film_transparent = False
        plate = shot(f"plate {k:04d}")[..., :3]
        write_png(work / f"plate_{k:04d}.png", plate)
        plates.append(plate)
        subject.hide_render = False
        borders.append(subject_border(scene, camera, subject))
        where.append(subject_on_screen(scene, camera, subject, spec))
        for look, roughness, _ in looks:
            build.set_roughness(material, roughness)
            truth[look].append(shot(f"truth {look} {k:04d}", borders[-1])[..., :3])
    build.set_roughness(material, 0.0)
    return plates, borders, where, truth


def _on_the_plate_sequence(scene, others, subject, work):
    """Set the scene up for the methods: the neighbours hidden from render, a transparent
    film, the plate_NNNN.png sequence of ``work`` as the plate, Auto resolution, the subject
    enabled. Returns the scene's settings."""
    for obj in others:
        obj.hide_render = True
    scene.render.film_transparent = True
    image = bpy.data.images.load(str(work / "plate_0001.png"))
    image.source = "SEQUENCE"
    settings = scene.virtual_reflections
    settings.plate_image = image
    settings.resolution = "AUTO"
    subject.virtual_reflections.enabled = True
    return settings


def _every_frame(scene, sequence, shot, name, hold, frames, plates, borders, masks):
    """One method and look as Update Every Frame runs it after Generate: `sequence.update` at
    every frame (``hold``: every HOLD-th only), the subject rendered alone and composited over
    that frame's plate. Fills ``masks`` (the subject's pixels per frame) where still None.
    Returns (the composites, the updates' reports)."""
    filters, alone, updates = {}, [], []
    for k in range(1, frames + 1):
        scene.frame_set(k)
        if not hold or (k - 1) % HOLD == 0:
            t0 = time.perf_counter()
            result = sequence.update(
                scene, bpy.context.evaluated_depsgraph_get(), filters=filters, frame=k
            )
            updates.append(
                {
                    "seconds": round(time.perf_counter() - t0, 4),
                    "maps": len(result.maps),
                    "tables_built": result.tables["built"],
                    "warnings": result.warnings,
                }
            )
        rgba = shot(f"{name} {k:04d}", borders[k - 1])
        if masks[k - 1] is None:
            masks[k - 1] = rgba[..., 3] > 0.5
        alone.append(rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plates[k - 1])
    return alone, updates


def _columns(looks, truth, alone, updates, masks, where) -> dict:
    """The measures on the subject's pixels: per look the truth's changes, per method and look
    its PSNR per frame, its changes, their summary against the truth's and its updates."""

    def series(images):
        return [(to_display(img), masks[i], *where[i]) for i, img in enumerate(images)]

    columns = {}
    truth_changes = {}
    for look, _, _ in looks:
        truth_changes[look] = motion.changes(series(truth[look]))
        columns[motion.column(motion.TRUTH, look)] = {
            "look": look,
            "changes": truth_changes[look],
        }
    for name, images in alone.items():
        look = next(lk for lk, _, _ in looks if f" {lk}" in name)
        got = motion.changes(series(images))
        columns[name] = {
            "look": look,
            "psnr": [
                psnr(to_display(img), to_display(truth[look][i]), masks[i])
                for i, img in enumerate(images)
            ],
            "changes": got,
            "summary": motion.summarise(got, truth_changes[look]),
            "updates": updates[name],
        }
    return columns


def run_motions(motions, work, width, samples, log, held=True, methods=None, looks=None):
    """Every sequence in turn; the add-on registered once, unregistered at the end. Returns
    (records, the add-on's method labels by identifier)."""
    addon = Addon()
    records = []
    try:
        for m in motions:
            records.append(
                run_motion(
                    m, addon, pathlib.Path(work) / m.name, width, samples, log, held, methods, looks
                )
            )
        labels = _labels(addon)
    finally:
        new_file()
        addon.close()
    return records, labels
