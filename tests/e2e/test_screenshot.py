"""The README's panel screenshot is made by a script, in Blender's own window under Xvfb:
tools/screenshot-panel builds the sample scene, generates, clicks the Reflections tab, shoots
the panel, opens the segmentation in an Image Editor with the panel's button, and drags the
sphere with live update on (Blender's real timers). Needs a real Blender, xvfb-run and xwd;
skipped with the reason otherwise."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from gl_libraries import skip_without_gl

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.e2e


def read_png(path):
    import OpenImageIO as oiio

    image = oiio.ImageInput.open(str(path))
    assert image is not None, oiio.geterror()
    pixels = image.read_image(format=oiio.UINT8)
    image.close()
    return np.asarray(pixels)


def test_screenshot_of_the_panel(blender, tmp_path):
    # `blender` skips without one; the tool finds the same ($VR_BLENDER, PATH, the chroot).
    for tool in ("xvfb-run", "xwd"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not installed (apt-get install xvfb x11-apps)")
    r = subprocess.run(
        [str(ROOT / "tools" / "screenshot-panel"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    skip_without_gl(r, failed_only=False)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    result = json.loads(r.stdout.strip().splitlines()[-1])
    assert result["tab"] == "Reflections"
    assert len(result["previews"]) == 2 and all(result["previews"])  # icons made in the UI
    assert result["show_image"] == ["FINISHED"]
    assert "VR Segmentation Chrome Sphere" in result["image_editors"]
    x, y, w, h = result["panel"]
    panel = read_png(tmp_path / "panel.png")
    assert panel.shape[:2] == (h, w)
    assert panel.std() > 10  # a drawn panel, not a black front buffer
    # Live update with Blender's own event loop and timers: moved, a small map then the full
    # one (two writes), the same size as before; a shaping setting: one more full map.
    live = result["live"]
    assert live["passes"] == 2 and live["size"] == result["map"], live
    assert live["status"].startswith("full") and live["after_enlarge"] >= 1, live
    for name in ("viewport", "segmentation_editor"):
        assert read_png(tmp_path / f"{name}.png").std() > 10, name
