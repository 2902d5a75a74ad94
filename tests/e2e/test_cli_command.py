"""`blender -c virtual_reflections ...`: the installed extension's own command line (issue 12),
so a TD never has to find the extension's folder; Blender's frame syntax (1..3) is accepted."""

import json

import pytest
from conftest import ROOT
from test_extension import SCENE_SCRIPT

pytestmark = pytest.mark.e2e


@pytest.fixture
def built(blender, tmp_path):
    """The extension's zip, built by Blender."""
    out = tmp_path / "build"
    out.mkdir()
    r = blender("--command", "extension", "build", "--source-dir", ROOT, "--output-dir", out)
    assert r.returncode == 0, r.stdout + r.stderr
    (zip_path,) = out.glob("virtual_reflections-*.zip")
    return zip_path


def test_cli_command_renders_frames_and_refuses_bad_input(blender, built, tmp_path):
    env = {"BLENDER_USER_RESOURCES": str(tmp_path / "user")}  # a private user folder
    r = blender(
        "--command", "extension", "install-file", "-r", "user_default", "--enable", built, env=env
    )
    assert r.returncode == 0, r.stdout + r.stderr
    r = blender("-c", "help", env=env)
    assert "virtual_reflections" in r.stdout + r.stderr, r.stdout[-2000:] + r.stderr[-2000:]
    shot = tmp_path / "shot.blend"
    script = tmp_path / "make_shot.py"
    script.write_text(SCENE_SCRIPT)
    r = blender("-b", "--python", script, "--", shot, env=env)
    assert r.returncode == 0 and shot.exists(), r.stdout[-2000:] + r.stderr[-2000:]

    plate = ROOT / "sample_scenes/plates/courtyard.jpg"
    out = tmp_path / "out"
    args = [shot, "--plate", plate, "--out", out, "--resolution", 256, "--frames", "1..2"]
    r = blender("-c", "virtual_reflections", *args, env=env)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    for frame in (1, 2):
        assert (out / f"shot.{frame:04d}.exr").exists()
        assert (out / f"shot_render.{frame:04d}.exr").exists()
    report = json.loads((out / "shot.report.json").read_text())
    assert [e["frame"] for e in report["frames"]] == [1, 2] and report["requested"] == "1..2"

    # Bad input: one line, exit code 2, as under --python.
    r = blender("-c", "virtual_reflections", *args[:-1], "3..1", env=env)
    assert r.returncode == 2, r.stdout[-2000:] + r.stderr[-2000:]
    errors = [x for x in r.stderr.splitlines() if x.startswith("render_shot: error")]
    assert len(errors) == 1 and "bad frame range '3..1'" in errors[0]
