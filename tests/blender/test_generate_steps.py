"""Generate in steps (generate.steps / generate.Job), as the button runs it: the same maps
as the blocking run, and a run stopped before its last step leaves the scene as it was."""

import bpy
import numpy as np
import pytest
from shots import addon_part
from test_generate import add_sphere, make_scene, red_blue_plate


def snapshot():
    return (
        sorted(i.name for i in bpy.data.images),
        sorted(m.name for m in bpy.data.materials),
        sorted(g.name for g in bpy.data.node_groups),
        [len(o.material_slots) for o in bpy.data.objects],
        [tuple(o.virtual_reflections.bounds) for o in bpy.data.objects],
    )


def pixels(image):
    out = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(out)
    return out


@pytest.fixture
def shot(addon):
    scene = make_scene()
    scene.virtual_reflections.plate_image = red_blue_plate()
    scene.virtual_reflections.resolution = "256"
    return scene, [add_sphere("Ball"), add_sphere("Other", location=(2, 3, 0))]


def test_the_job_makes_the_maps_the_blocking_run_makes(shot):
    generate = addon_part("operators.generate")
    scene, objects = shot
    depsgraph = bpy.context.evaluated_depsgraph_get()
    blocking = generate.generate(scene, depsgraph, objects)
    expected = {o.name: pixels(bpy.data.images[f"VR Map {o.name}"]) for o in objects}
    generate.remove_all()
    stages, shares = [], []
    job = generate.Job(generate.steps(scene, depsgraph, objects))
    assert generate.running() is job
    while True:
        stages.append(job.stage)
        shares.append(job.done)
        report = job.advance(wait=1.0)
        if report is not None:
            break
    assert generate.running() is None
    assert report.done == blocking.done == ["Ball", "Other"]
    for obj in objects:
        assert np.array_equal(pixels(bpy.data.images[f"VR Map {obj.name}"]), expected[obj.name])
    seen = list(dict.fromkeys(stages))
    assert seen[0] == "Reading the plate" and seen[-1] == "Writing the maps", seen
    assert seen.index("Building the table (Ball)") < seen.index("Gathering (Ball)")
    assert shares == sorted(shares) and 0 <= shares[0] and shares[-1] < 1  # the bar only grows


@pytest.mark.parametrize("stop_before", ["Measuring the objects", "Gathering (Other)",
                                         "Writing the maps"])  # fmt: skip
def test_a_stopped_run_leaves_the_scene_as_it_was(shot, stop_before):
    generate = addon_part("operators.generate")
    scene, objects = shot
    before = snapshot()
    job = generate.Job(generate.steps(scene, bpy.context.evaluated_depsgraph_get(), objects))
    while job.stage != stop_before:
        assert job.advance(wait=1.0) is None
    job.stop()
    assert generate.running() is None
    assert snapshot() == before


def test_one_run_at_a_time(shot):
    generate = addon_part("operators.generate")
    scene, objects = shot
    depsgraph = bpy.context.evaluated_depsgraph_get()
    job = generate.Job(generate.steps(scene, depsgraph, objects), "Generate")
    try:
        second = generate.steps(scene, depsgraph, objects)
        with pytest.raises(ValueError, match="Generate is under way"):
            generate.Job(second, "Inter-Reflections")
        assert generate.running() is job
        assert "under way" in generate.why_not_generate(bpy.context)  # the buttons say why
    finally:
        job.stop()
    assert generate.running() is None and generate.why_not_generate(bpy.context) is None
