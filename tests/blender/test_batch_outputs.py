"""Batch output for a pipeline (issue 12): the CG element beside every composite, the shot's
own compositor respected, PNG through the scene's view transform, named in the report."""

import json
import pathlib
import subprocess
import sys

import bpy
import numpy as np
import pytest
from sequence_shots import build_scene, read, write_plates

ROOT = pathlib.Path(__file__).resolve().parents[2]


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "render_shot", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def add_exposure_compositor(scene, stops=1.0):
    """The artist's compositor: the render one stop brighter (4.5: the scene's tree; 5.x: a
    compositor node group)."""
    if hasattr(scene, "compositing_node_group"):
        tree = bpy.data.node_groups.new("Artist Grade", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        output = tree.nodes.new("NodeGroupOutput")
        layers = tree.nodes.new("CompositorNodeRLayers")
        scene.compositing_node_group = tree
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        output = next(n for n in tree.nodes if n.type == "COMPOSITE")
        layers = next(n for n in tree.nodes if n.type == "R_LAYERS")
    grade = tree.nodes.new("CompositorNodeExposure")
    grade.name = "Grade"
    grade.inputs[1].default_value = stops
    tree.links.new(layers.outputs["Image"], grade.inputs[0])
    tree.links.new(grade.outputs[0], output.inputs[0])


@pytest.fixture
def plates(clean_file, tmp_path):
    return str(write_plates(tmp_path / "plates")[0]).replace("0001", "####")


def shot(tmp_path, compositor=False, compositing=True):
    scene = bpy.context.scene
    build_scene()
    if compositor:
        add_exposure_compositor(scene)
    scene.render.use_compositing = compositing
    path = tmp_path / ("graded.blend" if compositor else "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_the_shots_own_compositor_makes_the_composite(plates, tmp_path):
    blend = shot(tmp_path, compositor=True)
    out = tmp_path / "out"
    r = run(blend, "--plate", plates, "--out", out, "--frames", "1", "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "graded.report.json").read_text())
    assert "the shot's own compositor" in report["colour"]["over"]
    assert "Grade" in report["colour"]["over"]
    comp = read(out / "graded.0001.exr")[..., :3]
    element = read(out / "graded_render.0001.exr")
    plate = read(plates.replace("####", "0001"))
    h, w = element.shape[:2]
    inside = element[..., 3] > 0.999  # the sphere, fully covering
    outside = element[..., 3] == 0.0
    assert inside.sum() > 20 and outside.sum() > 20
    # Over the sphere: the artist's grade (one stop: twice the render), not the plain render.
    np.testing.assert_allclose(comp[inside], 2.0 * element[inside][:, :3], rtol=0.02, atol=2e-3)
    # Around it: the plate (decoded to scene-linear), untouched by the grade.
    from_plate = plate[..., :3] if plate.shape[:2] == (h, w) else None
    assert from_plate is not None
    srgb = np.where(
        from_plate <= 0.04045, from_plate / 12.92, ((from_plate + 0.055) / 1.055) ** 2.4
    )
    np.testing.assert_allclose(comp[outside], srgb[outside], atol=0.01)
    # One frame (a still plate, no --frames): the same compositor makes the composite.
    still = tmp_path / "still"
    r = run(blend, "--plate", plates.replace("####", "0001"), "--out", still, "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "composite: the shot's own compositor" in r.stdout and "Grade" in r.stdout
    one = read(still / "graded_composite.exr")[..., :3]
    np.testing.assert_allclose(one, comp, atol=2e-3)


def test_a_compositor_switched_off_is_not_used(plates, tmp_path):
    blend = shot(tmp_path, compositor=True, compositing=False)
    out = tmp_path / "out"
    r = run(blend, "--plate", plates, "--out", out, "--frames", "1", "--resolution", 256)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "graded.report.json").read_text())
    assert "premultiplied alpha over" in report["colour"]["over"]


def test_png_goes_through_the_view_transform_and_says_so(plates, tmp_path):
    blend = shot(tmp_path)
    bpy.context.scene.view_settings.view_transform = "AgX"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "out"
    common = [blend, "--plate", plates, "--frames", "1", "--resolution", 256]
    r = run(*common, "--out", out, "--format", "png")
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    report = json.loads((out / "shot.report.json").read_text())
    assert "view transform: AgX" in report["colour"]["composite"]
    assert "view transform: AgX" in r.stdout
    assert "premultiplied alpha over" in report["colour"]["over"]
    exr = tmp_path / "exr"
    r = run(*common, "--out", exr)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (
        "half-float EXR"
        in json.loads((exr / "shot.report.json").read_text())["colour"]["composite"]
    )
    # The PNG is the linear composite through AgX, not through the plain sRGB curve.
    linear = read(exr / "shot.0001.exr")[..., :3]
    png = read(out / "shot.0001.png")[..., :3]
    plain_srgb = np.where(linear <= 0.0031308, linear * 12.92, 1.055 * linear ** (1 / 2.4) - 0.055)
    assert np.abs(png - np.clip(plain_srgb, 0, 1)).mean() > 0.02
    # The CG element is the same linear render whatever the composite's format.
    np.testing.assert_array_equal(
        read(out / "shot_render.0001.exr"), read(exr / "shot_render.0001.exr")
    )
