"""The ray-traced pass seen from inside (`python -m study traced`, study/scenes3d/traced.py):
the quick case (two mirror spheres side by side, 320 x 180, 32 samples) through the bpy module,
and the claims of docs/scenes3d.md's "The ray-traced pass: seeing against blind": traced, the
mirrors show each other where the truth does (the inter pixels much nearer the truth than one
pass and than the same mirrors blind to each other), and their pixels as a whole are no further
from the truth. About 10 s (bpy 4.5); skipped only when bpy cannot be imported."""

import json

import pytest

NOISE_DB = 0.1  # one run at 32 samples: differences under this on all the pixels are noise


@pytest.fixture(scope="module")
def traced_quick(tmp_path_factory):
    pytest.importorskip("bpy", reason="it renders with the bpy module")
    from study.scenes3d import traced

    out = tmp_path_factory.mktemp("traced")
    return traced.run_command(quick=True, out=out, log=lambda line: None), out, traced


def test_the_traced_mirrors_show_each_other_where_the_truth_does(traced_quick):
    data, _, traced = traced_quick
    (record,) = data["scenes"]
    assert record["mirrors"] == 2 and record["inter_pixels"] > 0.02 * record["subject_pixels"]
    one, seeing, blind = (record["results"][run] for run in traced.RUNS)
    assert seeing["inter psnr"] > one["inter psnr"] + 0.5
    assert seeing["inter psnr"] > blind["inter psnr"] + 0.3
    assert seeing["psnr"] > one["psnr"] - NOISE_DB
    assert seeing["ssim"] > one["ssim"]


def test_the_run_leaves_its_table_and_record(traced_quick):
    data, out, _ = traced_quick
    saved = json.loads((out / "scenes3d_traced_quick.json").read_text())
    assert saved["scenes"][0]["scene"]["name"] == data["scenes"][0]["scene"]["name"]
    text = (out / "scenes3d.md").read_text()
    assert "<!-- scenes3d:traced -->" in text and "ray traced − one pass" in text
