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

    batch_render = importlib.import_module(f"{addon.__name__}.operators.batch_render")
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

    batch = importlib.import_module(f"{addon.__name__}.operators.batch")
    with pytest.raises(TypeError, match="BatchOptions"):
        batch.render_shot(SimpleNamespace(plate=str(PLATE), out=str(tmp_path)), 0.0)
