"""The installed extension in a real Blender without NumPy, or without OpenImageIO (as
distributions' Blender packages come): it enables without a traceback and says in one
sentence what to install; without OpenImageIO, Generate and the inter-reflections still work.

The module is hidden by a startup script in the private user folder, which Blender runs
before it enables extensions (a meta-path entry makes importing it fail)."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e

BLOCKER = """
import sys
HIDDEN = {hidden!r}

class _Hide:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in HIDDEN:
            raise ImportError(f"No module named {{name!r}} (hidden by the test)")
        return None

for name in list(sys.modules):
    if name.split(".")[0] in HIDDEN:
        del sys.modules[name]
sys.meta_path.insert(0, _Hide())


def register():
    pass


def unregister():
    pass
"""

CHECK = r"""
import bpy, importlib, json, sys
out = {"addons": sorted(a.module for a in bpy.context.preferences.addons)}
name = next((a for a in out["addons"] if a.endswith(".virtual_reflections")), None)
out["enabled"] = name is not None
out["panel"] = hasattr(bpy.types, "VR_PT_main")
out["menu"] = hasattr(bpy.types, "VR_MT_object")
deps = importlib.import_module(name + ".dependencies")
out["sentence"] = deps.missing_required()
try:
    import OpenImageIO  # noqa: F401
    out["openimageio_hidden"] = False
except ImportError:
    out["openimageio_hidden"] = True
out["detected"] = {m: deps.available(m) for m in ("numpy", "OpenImageIO")}
out["oiio_sentence"] = deps.needs("OpenImageIO", "The batch")
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.location = (0, -6, 0)
cam.rotation_euler = (1.5707963, 0, 0)
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=24, ring_count=12)
scene.render.resolution_x, scene.render.resolution_y = 64, 36
scene.render.engine = "CYCLES"
scene.cycles.samples = 1
if hasattr(scene, "virtual_reflections"):
    scene.virtual_reflections.plate_image = bpy.data.images.load(sys.argv[-1])
    scene.virtual_reflections.resolution = "256"
for op in ("generate", "render_passes"):
    try:
        out[op] = sorted(getattr(bpy.ops.vr, op)())
    except RuntimeError as exc:
        out[op] = str(exc).strip()
print("RESULT=" + json.dumps(out), flush=True)
"""


@pytest.fixture(scope="module")
def package(blender, tmp_path_factory):
    out = tmp_path_factory.mktemp("build")
    r = blender("--command", "extension", "build", "--source-dir", ROOT, "--output-dir", out)
    assert r.returncode == 0, r.stdout + r.stderr
    (zip_path,) = out.glob("virtual_reflections-*.zip")
    return zip_path


def run_without(blender, package, tmp_path, hidden):
    env = {"BLENDER_USER_RESOURCES": str(tmp_path / "user")}
    r = blender(
        "--command", "extension", "install-file", "-r", "user_default", "--enable", package, env=env
    )
    assert r.returncode == 0, r.stdout + r.stderr
    startup = tmp_path / "user" / "scripts" / "startup"
    startup.mkdir(parents=True, exist_ok=True)
    (startup / "hide_modules.py").write_text(BLOCKER.format(hidden=tuple(hidden)))
    script = tmp_path / "check.py"
    script.write_text(CHECK)
    plate = ROOT / "sample_scenes/plates/courtyard.jpg"
    r = blender("-b", "--python-exit-code", 1, "--python", script,
                "--", plate, env=env)  # fmt: skip
    line = next((x for x in r.stdout.splitlines() if x.startswith("RESULT=")), None)
    assert line, r.stdout[-3000:] + r.stderr[-3000:]
    return r, json.loads(line[len("RESULT=") :])


def test_without_numpy_it_enables_and_says_what_to_install(blender, package, tmp_path):
    r, out = run_without(blender, package, tmp_path, ["numpy"])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Traceback" not in r.stdout + r.stderr, r.stdout[-3000:] + r.stderr[-3000:]
    assert out["enabled"] and out["panel"] and out["menu"], out
    sentence = out["sentence"]
    assert sentence.startswith("Virtual Reflections needs NumPy: install it"), sentence
    assert "numpy" in sentence.split("(")[1], sentence  # the command names the package
    # The operators are there (F3, the menus) and report the sentence, nothing else.
    assert out["generate"] == f"Error: {sentence}", out["generate"]
    assert out["render_passes"] == f"Error: {sentence}", out["render_passes"]


def test_without_openimageio_generate_and_inter_reflections_work(blender, package, tmp_path):
    r, out = run_without(blender, package, tmp_path, ["OpenImageIO"])
    assert r.returncode == 0, r.stderr[-3000:]
    assert "Traceback" not in r.stdout + r.stderr, r.stdout[-3000:] + r.stderr[-3000:]
    assert out["enabled"] and out["panel"] and out["sentence"] is None, out
    assert out["generate"] == ["FINISHED"], out["generate"]
    assert out["render_passes"] == ["FINISHED"], out["render_passes"]  # two passes, no OIIO
    assert out["openimageio_hidden"], out
    # Detected: the preferences say the batch command line needs it, and how to install it.
    assert out["detected"] == {"numpy": True, "OpenImageIO": False}, out
    assert out["oiio_sentence"].startswith("The batch needs OpenImageIO: install it"), out
