"""The 3D ground truth (`python -m study scenes`), its quick subset run through the bpy module:
the truth is not the plate, the harness ranks a known-better world above a known-worse one,
the default ranks where the docs put it (docs/scenes3d.md, "Means per method and material"),
every add-on method renders something finite, and the outputs hold every method and metric;
one failure case (`--cases failures --quick`) scores every method finitely. About 80 s on two
cores (bpy 4.5); skipped only when bpy cannot be imported."""

import importlib.util
import json
import math
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from study.scenes3d import QUICK, scenes

ROOT = pathlib.Path(__file__).resolve().parents[2]


def method_labels():
    """The add-on's methods, by the panel's names, from their one definition."""
    from virtual_reflections.methods import METHODS

    return [m.label for m in METHODS]


def test_scene_descriptions_are_deterministic_and_in_range():
    full = scenes.scene_set()
    assert len(full) == 16 and [s.to_json() for s in full] == [
        s.to_json() for s in scenes.scene_set()
    ]
    assert {s.hdri for s in full} == set(scenes.HDRIS)
    assert not {s.hdri for s in full} & set(scenes.HELD_OUT)
    assert {s.shape for s in full} == set(scenes.SHAPES)
    for s in full:
        assert 1.4 <= s.camera_height <= 1.8 and 2 <= s.pitch_deg <= 15
        assert 24 <= s.lens_mm <= 85 and 3 <= s.distance <= 10 and 0.3 <= s.size <= 1.5
        assert {n.role for n in s.neighbours} == {"beside", "behind", "behind camera"}
        behind_camera = next(n for n in s.neighbours if n.role == "behind camera")
        assert behind_camera.y < 0  # the camera looks along +Y from y = 0
    assert 2 <= len(QUICK.specs()) <= 3


def test_the_held_out_scenes_use_only_the_held_out_hdris_with_every_shape():
    held = scenes.held_out_set()
    assert [s.to_json() for s in held] == [s.to_json() for s in scenes.held_out_set()]
    assert {s.hdri for s in held} == set(scenes.HELD_OUT)
    assert not {s.name for s in held} & {s.name for s in scenes.scene_set()}
    for hdri in scenes.HELD_OUT:  # every shape under each held-out HDRI
        assert {s.shape for s in held if s.hdri == hdri} == set(scenes.SHAPES)
    for s in held:  # drawn from the same ranges as the training scenes
        assert 1.4 <= s.camera_height <= 1.8 and 2 <= s.pitch_deg <= 15
        assert 24 <= s.lens_mm <= 85 and 3 <= s.distance <= 10 and 0.3 <= s.size <= 1.5
    assert [s.name for s in scenes.held_out_set(quick=True)] == [s.name for s in held[:2]]


def test_the_more_scenes_continue_the_default_sets_draw():
    """`--cases more`: the 16 scenes' own rule run on (seeds 117-148, set indices 16-47), so
    the six HDRIs and four shapes keep their turns and no scene repeats one of the 16."""
    more, first = scenes.more_set(), scenes.scene_set()
    assert len(more) == 32 and [s.to_json() for s in more] == [
        s.to_json() for s in scenes.more_set()
    ]
    assert not {s.name for s in more} & {s.name for s in first}
    both = first + more
    assert [s.hdri for s in both] == [scenes.HDRIS[i % 6] for i in range(48)]
    assert [s.shape for s in both] == [scenes.SHAPES[i % 4] for i in range(48)]
    assert [s.name for s in scenes.more_set(quick=True)] == [s.name for s in more[:2]]


@pytest.mark.parametrize("cases", ["more", "all"])
def test_the_more_scenes_run_only_in_the_fast_mirror_loop(cases):
    r = subprocess.run(
        [sys.executable, "-m", "study", "scenes", "--cases", cases],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and r.stderr.strip() == (
        f"study: error: --cases {cases} runs with --mirror-only only"
    ), r.stderr


def test_the_command_rejects_more_jobs_in_one_line():
    r = subprocess.run(
        [sys.executable, "-m", "study", "scenes", "--quick", "--jobs", "2"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    pytest.importorskip("bpy", reason="the 3D study renders with the bpy module")
    from study.scenes3d import run_command

    out = tmp_path_factory.mktemp("scenes3d")
    data, crops = run_command(quick=True, out=out, log=lambda line: None)
    return data, crops, out


def test_the_truth_differs_from_the_plate_on_the_subject(quick_run):
    data, _, _ = quick_run
    for record in data["scenes"]:
        assert record["subject_pixels"] > 200, record["scene"]["name"]
        for material, scores in record["results"].items():
            plate = scores["(plate itself)"]
            assert plate["psnr"] < 25.0 and plate["si_rmse"] > 0.1, (material, plate)


def test_an_on_set_probe_beats_the_plate_mean_on_the_mirror(quick_run):
    """A sanity check of the harness: the true HDRI at infinity (what a chrome ball captures)
    must look more like the path-traced mirror than a flat world of the plate's mean."""
    data, _, _ = quick_run
    for record in data["scenes"]:
        mirror = record["results"]["mirror"]
        assert mirror["On-set probe"]["psnr"] > mirror["Plate mean"]["psnr"], record["scene"]
        assert mirror["On-set probe"]["ssim"] > mirror["Plate mean"]["ssim"] + 0.1


def test_the_default_ranks_as_the_docs_claim(quick_run):
    """docs/scenes3d.md: the default (Camera View + Ground) is the best of the add-on's methods
    and ahead of the plate mean and the plate stretched as a world, on mean PSNR and mean SSIM,
    for the mirror and both rough subjects in both looks; Camera View is ahead of the paper's
    method on the mirror. Here on the quick subset's means (a city and an interior scene)."""
    data, _, _ = quick_run
    default = "Camera View + Ground"  # the Method setting's default (ui/properties.py)
    others = [m for m in data["addon_methods"] if m != default] + ["Plate mean", "Plate stretched"]
    assert len(others) == 4
    materials = [m["name"] for m in data["materials"]]
    assert len(materials) == 5  # the mirror, and two roughnesses in the World and Mix looks
    for material in materials:
        for metric in ("psnr", "ssim"):
            mean = {
                method: float(
                    np.mean([r["results"][material][method][metric] for r in data["scenes"]])
                )
                for method in [default, *others]
            }
            behind = [m for m in others if mean[m] >= mean[default]]
            assert not behind, (material, metric, mean)
    mirror = {
        m: np.mean([r["results"]["mirror"][m]["psnr"] for r in data["scenes"]])
        for m in ("Camera View", "Paper (2004)")
    }
    assert mirror["Camera View"] > mirror["Paper (2004)"], mirror


def test_every_addon_method_renders_something_finite(quick_run):
    data, crops, _ = quick_run
    labels = method_labels()
    assert data["addon_methods"] == labels
    for record in data["scenes"]:
        for label in labels:
            assert record["finite"][label], (record["scene"]["name"], label)
            assert record["generate_s"][label]["REPLACE"] > 0
            for material, scores in record["results"].items():
                got, plate = scores[label], scores["(plate itself)"]
                assert all(math.isfinite(got[m]) for m in ("psnr", "ssim", "si_rmse"))
                # an empty render would leave the plate itself on the subject's pixels
                assert got != plate, (material, label)
        crop = crops[record["scene"]["name"]]
        assert set(crop) >= {"Truth", *labels, "Plate mean"}


def test_the_outputs_hold_every_method_and_metric(quick_run):
    data, _, out = quick_run
    saved = json.loads((out / "scenes3d_quick.json").read_text())
    methods = [*method_labels(), "On-set probe", "Plate stretched", "Plate mean"]
    assert len(saved["scenes"]) == len(QUICK.specs())
    assert {"psnr", "ssim", "si_rmse", "flip", "detail", "detail_upper"} <= set(saved["metrics"])
    for record in saved["scenes"]:
        assert set(record["results"]) == {
            "mirror",
            "rough 0.15",
            "rough 0.35",
            "rough 0.15, Mix",
            "rough 0.35, Mix",
        }
        for scores in record["results"].values():
            for method in methods:
                assert set(scores[method]) == set(saved["metrics"])
        assert set(record["generate_s"]) == set(method_labels())
        assert {"hdri", "shape", "lens_mm", "distance", "size"} <= set(record["scene"])
    text = (out / "scenes3d_quick.md").read_text()
    assert all(f"| {m} | mirror |" in text for m in methods)
    if importlib.util.find_spec("matplotlib") is not None:  # not in every venv
        for chart in ("scenes3d_quick_pareto.png", "scenes3d_quick_examples.png"):
            assert (out / "images" / chart).stat().st_size > 5000


def test_failure_cases_are_variations_that_leave_the_scenes_alone():
    """`--cases failures` (issue 11, item 5): six cases from one ordinary scene; the 16
    scenes' descriptions carry none of the new fields."""
    assert all("lift" not in s.to_json() and "case" not in s.to_json() for s in scenes.scene_set())
    cases = scenes.failure_set()
    assert [c.case[:2] for c in cases] == ["f1", "f2", "f3", "f4", "f5", "f6"]
    assert [c.to_json() for c in cases] == [c.to_json() for c in scenes.failure_set()]
    extent = {c.case[:2]: scenes.frame_extent(c) for c in cases}
    for key in ("f1", "f2", "f3", "f4", "f6"):
        assert extent[key][3] < 1.0, key  # the subject inside the frame
    assert extent["f4"][3] > 0.95 and extent["f5"][2] > 1.0 and extent["f6"][2] < 0.06
    up = cases[1]
    half_v = math.degrees(math.atan(scenes.SENSOR_MM / 2 / up.lens_mm / scenes.ASPECT))
    assert -up.pitch_deg > half_v  # the frame's bottom row looks above the horizon: no ground
    assert cases[0].lift >= 0.5 and not any(n.role == "pedestal" for n in cases[0].neighbours)


def test_a_failure_case_scores_every_method_finitely(tmp_path):
    """The floating case, small: every method, the ground-chosen row included, renders and
    scores finitely; the outputs hold it (about 30 s)."""
    pytest.importorskip("bpy", reason="the 3D study renders with the bpy module")
    from study.scenes3d import run_command

    data, _ = run_command(quick=True, out=tmp_path, cases="failures", log=lambda line: None)
    labels = method_labels()
    assert (
        len(data["scenes"]) == 1 and "Camera View + Ground (ground chosen)" in data["addon_methods"]
    )
    assert set(labels) < set(data["addon_methods"])
    for record in data["scenes"]:
        for label in data["addon_methods"]:
            assert record["finite"][label], label
            for scores in record["results"].values():
                assert all(math.isfinite(scores[label][m]) for m in ("psnr", "ssim", "si_rmse"))
    assert json.loads((tmp_path / "scenes3d_failures_quick.json").read_text())["cases"] == (
        "failures"
    )
    assert "<!-- scenes3d:failures -->\n| case |" in (tmp_path / "scenes3d_quick.md").read_text()
