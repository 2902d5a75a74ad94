"""The extension as users get it: validated, built, installed and run headless in a real
Blender binary."""

import json
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.e2e


def test_manifest_passes_blenders_validator(blender):
    r = blender("--command", "extension", "validate", ROOT)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.fixture(scope="module")
def package(blender, tmp_path_factory):
    out = tmp_path_factory.mktemp("build")
    r = blender("--command", "extension", "build", "--source-dir", ROOT, "--output-dir", out)
    assert r.returncode == 0, r.stdout + r.stderr
    (zip_path,) = out.glob("virtual_reflections-*.zip")
    return zip_path


def test_build_leaves_out_tests_docs_and_benchmarks(package):
    names = zipfile.ZipFile(package).namelist()
    assert "blender_manifest.toml" in names and "render_shot.py" in names
    assert "virtual_reflections/projection.py" in names and "operators/generate.py" in names
    for name in names:
        assert not name.startswith(
            ("tests/", "docs/", "tools/", "benchmarks/", "pipeline/", "study/", ".ci/", ".venv")
        ), name
        assert not name.endswith(("pyproject.toml", ".zip")), name


SCENE_SCRIPT = """
import bpy, json, sys
bpy.ops.wm.read_homefile(use_empty=True)
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.location = (0, -6, 0)
cam.rotation_euler = (1.5707963, 0, 0)
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=24, ring_count=12)
scene.render.resolution_x, scene.render.resolution_y = 64, 36
scene.render.engine = "CYCLES"
scene.cycles.samples = 2
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[-1])
print("ADDONS=" + json.dumps(sorted(a.module for a in bpy.context.preferences.addons)))
# The installed extension's preferences: what new files start with, where saved maps go.
import importlib
addons = bpy.context.preferences.addons
name = next(a.module for a in addons if a.module.endswith(".virtual_reflections"))
prefs = addons[name].preferences
prefs.combine, prefs.map_folder = "MODULATE", "USER"
maps = importlib.import_module(name + ".operators.scene.maps")
bpy.ops.wm.read_homefile(use_empty=True)
print("PREFS=" + json.dumps({
    "combine": bpy.context.scene.virtual_reflections.combine,
    "folder": maps.maps_folder(create=False),
}))
"""


def test_installed_extension_renders_headless(blender, package, tmp_path):
    env = {"BLENDER_USER_RESOURCES": str(tmp_path / "user")}  # a private user folder
    r = blender(
        "--command", "extension", "install-file", "-r", "user_default", "--enable", package, env=env
    )
    assert r.returncode == 0, r.stdout + r.stderr
    installed = next((tmp_path / "user").rglob("virtual_reflections/blender_manifest.toml")).parent
    shot = tmp_path / "shot.blend"
    script = tmp_path / "make_shot.py"
    script.write_text(SCENE_SCRIPT)
    r = blender("-b", "--python", script, "--", shot, env=env)
    assert r.returncode == 0 and shot.exists(), r.stdout[-2000:] + r.stderr[-2000:]
    line = next(x for x in r.stdout.splitlines() if x.startswith("ADDONS="))
    addons = json.loads(line[len("ADDONS=") :])
    assert any(a.endswith(".virtual_reflections") for a in addons), addons
    line = next(x for x in r.stdout.splitlines() if x.startswith("PREFS="))
    prefs = json.loads(line[len("PREFS=") :])
    assert prefs["combine"] == "MODULATE"  # a new file takes the preferred combine mode
    assert str(tmp_path / "user") in prefs["folder"]
    assert Path(prefs["folder"]).name.startswith("untitled-")  # an unsaved file's own folder
    plate = ROOT / "sample_scenes/plates/courtyard.jpg"
    out = tmp_path / "out"
    r = blender(
        "-b",
        shot,
        "--python",
        installed / "render_shot.py",
        "--",
        "--plate",
        plate,
        "--out",
        out,
        "--resolution",
        256,
        env=env,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert (out / "shot_composite.png").exists() and (out / "shot_render.exr").exists()
    assert "reflections: 1 reflection(s)" in r.stdout


def test_headless_bad_plate_is_one_line_and_exit_2(blender, package, tmp_path):
    r = blender(
        "-b",
        "--factory-startup",
        "--python",
        ROOT / "render_shot.py",
        "--",
        "--plate",
        tmp_path / "missing.jpg",
        "--out",
        tmp_path / "out",
    )
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    errors = [line for line in r.stderr.splitlines() if line.startswith("render_shot: error")]
    assert len(errors) == 1 and "plate not found" in errors[0]
