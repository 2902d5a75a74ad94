"""Oracles for the fast mirror loop (`python -m study scenes --mirror-only --oracle NAME`):
the default method given knowledge no plate holds, to bound what a model of that knowledge
could gain (docs/scenes3d.md, "Where the default's error lies").

- ``shadow``: the subject's own shadow. The plate is rendered once more with the subject in
  the scene but hidden from the camera, so it holds the subject's shadow and the light the
  subject throws on the ground, as the truth does. Generate runs on that plate with the
  contact shadow off, which would darken that ground a second time.
- ``proxies``: a perfect proxy of what stands around. The ray-traced pass
  (`traced_pass.traced`: the subject a mirror that also sees itself) renders twice: without
  and with the scene's own boxes put back for the mirror's rays alone. The boxes keep their
  true shape and their true shading under the true dome, more than any proxy built from the
  plate could know.

Each adds rows to a scene's mirror results, scored as the default's (`labels`). Research only
(bpy).
"""

from __future__ import annotations

import contextlib
import importlib
import pathlib

import bpy
import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from . import run

SHADOW_PLATE = ("plate shadow.exr", "plate shadow.png")  # cached beside the plate
# a box put back for the mirror's rays alone: hidden from every other ray
GLOSSY_ONLY = (
    "visible_camera",
    "visible_diffuse",
    "visible_shadow",
    "visible_transmission",
    "visible_volume_scatter",
)


def labels(label: str, oracle: str) -> tuple:
    """The result rows ``oracle`` ("shadow" or "proxies") adds for the default method
    ``label``."""
    if oracle == "shadow":
        return (f"{label} (shadow in the plate)",)
    return (f"{label} (traced)", f"{label} (traced, true proxies)")


@contextlib.contextmanager
def no_contact_shadow(scene):
    """While inside: the panel's Contact Shadow off (0) in ``scene``."""
    settings = scene.virtual_reflections
    before = settings.contact_shadow
    settings.contact_shadow = 0.0
    try:
        yield
    finally:
        settings.contact_shadow = before


def render_rows(oracle, scene, subject, others, addon, folder: pathlib.Path, work, name, border):
    """The oracle's renders of one scene, in `labels` order ((H, W, 4) linear RGBA each), and
    how many renders it took (the shadowed plate is rendered once, then cached). The scene is
    as `mirror.run_scene` leaves it after the default's render: the other objects hidden, the
    film transparent, the plate in the panel, no maps."""
    if oracle == "shadow":
        return _shadow_rows(
            scene, subject, others, addon, folder, work / f"{name} shadow.exr", border
        )
    return _proxy_rows(scene, subject, others[1:], addon, work, name, border)  # others[0]: ground


def _shadow_rows(scene, subject, others, addon, folder, path, border):
    settings = scene.virtual_reflections
    plate_image = settings.plate_image
    exr, png = (folder / f for f in SHADOW_PLATE)
    renders = 1
    if not (exr.is_file() and png.is_file()):
        renders += 1
        for obj in others:
            obj.hide_render = False
        scene.render.film_transparent = False
        subject.visible_camera = False
        try:
            shadowed = run.render(scene, exr)[..., :3]
        finally:
            subject.visible_camera = True
            scene.render.film_transparent = True
            for obj in others:
                obj.hide_render = True
        run.write_png(png, shadowed)
    settings.plate_image = bpy.data.images.load(str(png))
    try:
        with no_contact_shadow(scene):
            report = addon.generate.generate(
                scene, bpy.context.evaluated_depsgraph_get(), [subject]
            )
        if not report.done:
            raise RuntimeError(f"{path.stem}: Generate on the shadowed plate made nothing")
        rgba = run.render(scene, path, border)
    finally:
        addon.generate.remove_all()
        settings.plate_image = plate_image
    return [rgba], renders


def _proxy_rows(scene, subject, boxes, addon, work, name, border):
    traced_pass = importlib.import_module(f"{addon.module.__name__}.operators.traced_pass")
    report = addon.generate.generate(scene, bpy.context.evaluated_depsgraph_get(), [subject])
    if not report.done:
        raise RuntimeError(f"{name}: Generate made nothing")
    try:
        with traced_pass.traced(scene, [subject]):
            rows = [run.render(scene, work / f"{name} traced.exr", border)]
            _show_to_mirrors(boxes, True)
            try:
                rows.append(run.render(scene, work / f"{name} traced proxies.exr", border))
            finally:
                _show_to_mirrors(boxes, False)
    finally:
        addon.generate.remove_all()
    return rows, len(rows)


def _show_to_mirrors(boxes, shown: bool) -> None:
    """Put ``boxes`` back for the mirror's rays alone (``shown``), or hide them again."""
    for obj in boxes:
        obj.hide_render = not shown
        for flag in GLOSSY_ONLY:
            setattr(obj, flag, not shown)


def shadow_plate(folder: pathlib.Path) -> np.ndarray:
    """The cached shadowed plate of a scene, (H, W, 3) linear, as Generate read it (8-bit)."""
    return srgb_to_linear(read_rgba(str(folder / SHADOW_PLATE[1]))[..., :3])
