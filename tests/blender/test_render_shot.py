"""The headless batch entry through the bpy module: `python -m render_shot ...`."""

import pathlib
import subprocess
import sys

import bpy
import pytest
from shots import add_camera, addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]
PLATE = ROOT / "sample_scenes/plates/courtyard.jpg"


@pytest.fixture
def shot(clean_file, tmp_path):
    scene = bpy.context.scene
    add_camera(scene)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 2
    scene.view_settings.view_transform = "Standard"
    path = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "render_shot", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )


def read(path):
    return addon_part("virtual_reflections.imagefiles").read_rgba(str(path))


def test_render_shot_writes_render_and_composite(shot, tmp_path):
    out = tmp_path / "out"
    r = run(shot, "--plate", PLATE, "--out", out, "--resolution", 256, "--scale", 10)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    assert "reflections: 1 reflection(s)" in r.stdout
    render, comp = read(out / "shot_render.exr"), read(out / "shot_composite.exr")
    assert render.shape == comp.shape == (72, 128, 4)
    alpha = render[..., 3]
    assert alpha.max() > 0.99 and alpha.min() == 0.0  # the sphere over a transparent film
    # Where the film is empty the composite is the plate (not black).
    assert comp[alpha == 0][:, :3].mean() > 0.05
    assert (out / "shot_composite.png").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        (("--plate", "{tmp}/missing.jpg", "--out", "{tmp}/o"), "plate not found"),
        (("{tmp}/nope.blend", "--plate", PLATE, "--out", "{tmp}/o"), "shot not found"),
        (("--plate", PLATE, "--out", "{tmp}/o", "--objects", "Nobody"), "no object named"),
        (("--plate", PLATE, "--out", "{tmp}/o", "--frame", 1, "--frames", "1-2"), "not both"),
        (("--plate", PLATE, "--out", "{tmp}/o", "--resolution", 300), "--resolution must be"),
        (("--plate", PLATE, "--out", "{tmp}/o", "--ground-object", "Nobody"), "--ground-object"),
    ],
)
def test_render_shot_bad_input(shot, tmp_path, args, message):
    args = [str(a).format(tmp=tmp_path) for a in args]
    if not args[0].endswith(".blend"):
        args = [str(shot), *args]
    r = run(*args)
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    errors = [x for x in r.stderr.splitlines() if x.startswith("render_shot: error")]
    assert len(errors) == 1 and message in errors[0], r.stderr[-2000:]


def test_method_option_sets_the_scene_method(addon, tmp_path):
    """--method picks the camera-view or the paper's method; without it the shot's own stays."""
    import importlib

    batch_render = importlib.import_module(f"{addon.__name__}.operators.batch.render")
    render_shot = importlib.import_module("render_shot")
    settings = bpy.context.scene.virtual_reflections
    base = ["--plate", str(PLATE), "--out", str(tmp_path)]

    def options(*argv):
        return render_shot.batch_options(addon, render_shot.parse([*base, *argv]))

    for given, expected in (("ground", "GROUND"), ("camera", "CAMERA"), ("paper", "PAPER")):
        batch_render.configure(bpy.context.scene, options("--method", given))
        assert settings.method == expected
    floor = bpy.data.objects.new("Floor", None)
    bpy.context.scene.collection.objects.link(floor)
    paper_on_floor = options("--method", "paper", "--ground-object", "Floor")
    batch_render.configure(bpy.context.scene, paper_on_floor)
    assert settings.ground_object == floor
    batch_render.configure(bpy.context.scene, options())
    assert settings.method == "PAPER"  # kept, not reset to the default (Camera View)
    with pytest.raises(SystemExit) as bad:
        render_shot.parse([*base, "--method", "nope"])
    assert bad.value.code == 2


def test_batch_takes_batch_options(addon, tmp_path):
    """The batch reads a BatchOptions, not a namespace of whatever attributes it has."""
    import importlib
    from types import SimpleNamespace

    batch = importlib.import_module(f"{addon.__name__}.operators.batch.shot")
    with pytest.raises(TypeError, match="BatchOptions"):
        batch.render_shot(SimpleNamespace(plate=str(PLATE), out=str(tmp_path)), 0.0)


def test_a_shot_set_up_in_the_panel_renders_as_the_artist_saw_it(addon, tmp_path):
    """Issue 42: the batch used to call Set Up again, which first undid the artist's: the view
    transform went back to AgX (the PNG's plate 8.6 levels off) and the ground was deleted. A
    shot already Set Up keeps its set-up; only the plate is the batch's."""
    import numpy as np

    compositor = addon_part("operators.compositor")
    images = addon_part("operators.scene.images")
    scene = bpy.context.scene
    add_camera(scene)
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 2
    scene.view_settings.view_transform = "AgX"  # Blender's default: Set Up makes it Standard
    image = bpy.data.images.load(str(PLATE))
    record = compositor.setup_from_plate(scene, image, ground=True)
    assert record["ground"] and scene.view_settings.view_transform == "Standard"
    ground = record["ground"]["object"] if isinstance(record["ground"], dict) else None
    shot = tmp_path / "shot.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))

    # In this process: the batch's set-up keeps the view, the ground and the record.
    other = bpy.data.images.load(str(PLATE), check_existing=False)
    again = compositor.plate_for_batch(scene, other)
    assert scene.view_settings.view_transform == "Standard"
    assert again["ground"] == record["ground"] and again["view"] == record["view"]
    if ground:
        assert ground in bpy.data.objects
    assert compositor.undo_setup_from_plate(scene)
    assert scene.view_settings.view_transform == "AgX"  # Undo still goes back to before
    assert not any(images.CREATED in o and o.get(images.CREATED) for o in scene.objects)

    # Through the command line: the PNG's plate is the plate (Standard), not AgX's.
    out = tmp_path / "out"
    r = run(shot, "--plate", PLATE, "--out", out, "--resolution", 256, "--scale", 10)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    png = read(out / "shot_composite.png")[..., :3]
    photo = read(PLATE)[..., :3]  # 1280 x 720: at 10 % each output pixel is a 10 x 10 block
    h, w = png.shape[:2]
    small = photo.reshape(h, 10, w, 10, 3).mean((1, 3))
    srgb = lambda lin: np.where(  # noqa: E731
        lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(np.maximum(lin, 0), 1 / 2.4) - 0.055
    )
    sky = slice(0, h // 5)  # above the sphere
    off = np.median(np.abs(srgb(png[sky]) - srgb(small[sky]))) * 255
    assert off < 2.0, f"the composite's plate is {off:.1f} levels off (AgX?)"
