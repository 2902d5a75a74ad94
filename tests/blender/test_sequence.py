"""Image sequences and movies as plates: live update (operators/sequence.py), in-process."""

import importlib
import threading

import bpy
import numpy as np
import pytest
from sequence_shots import COLOURS, build_scene, mean_rgb, read, write_movie, write_plates

from virtual_reflections import frames


def module(addon, name):
    return importlib.import_module(f"{addon.__name__}.operators.{name}")


@pytest.fixture
def seq(addon):
    return module(addon, "sequence")


def _generate(addon, scene, objects):
    report = module(addon, "generate").generate(
        scene, bpy.context.evaluated_depsgraph_get(), objects
    )
    assert report.done, report.warnings
    return report


@pytest.fixture
def live(addon, seq, tmp_path):
    """A sphere reflecting a three-frame sequence plate (red, green, blue), live update on."""
    plates = write_plates(tmp_path)
    scene = bpy.context.scene
    sphere = build_scene()
    image = bpy.data.images.load(str(plates[0]))
    image.source = "SEQUENCE"
    settings = scene.virtual_reflections
    settings.plate_image = image
    settings.resolution = "256"
    module(addon, "compositor").setup_from_plate(scene, image)
    scene.frame_set(1)
    _generate(addon, scene, [sphere])
    scene.virtual_reflections.sequence = True
    return scene, sphere, bpy.data.images[f"VR Map {sphere.name}"]


def _dominant(rgb):
    return int(np.argmax(rgb))


# --- pure helpers -------------------------------------------------------------------------------


def test_parse_frames(seq):
    assert frames.parse_frames("1-5") == [1, 2, 3, 4, 5]
    assert frames.parse_frames("1-10x3") == [1, 4, 7, 10]
    assert frames.parse_frames("5") == [5]
    assert frames.parse_frames("7-9,1,3,3") == [1, 3, 7, 8, 9]
    assert frames.parse_frames("-2-1") == [-2, -1, 0, 1]
    for bad in ("", "a", "3-1", "1-5x0", "1--", "1-3,", "1.5"):
        with pytest.raises(ValueError, match="frame range"):
            frames.parse_frames(bad)


def test_paths_of_frames(seq, tmp_path):
    assert frames.pattern_path("/p/plate.####.exr", 12) == "/p/plate.0012.exr"
    assert frames.pattern_path("/p/plate.%04d.jpg", 7) == "/p/plate.0007.jpg"
    assert frames.pattern_path("/p/v2/plate_#.png", 123) == "/p/v2/plate_123.png"
    assert frames.is_pattern("a.####.exr") and frames.is_pattern("a.%04d.exr")
    assert not frames.is_pattern("a.0001.exr") and frames.is_movie_path("clip.MOV")
    # Blender's own rule, through an image user on a camera background.
    plates = write_plates(tmp_path)
    image = bpy.data.images.load(str(plates[0]))
    image.source = "SEQUENCE"
    camera = bpy.data.cameras.new("C")
    entry = camera.background_images.new()
    entry.image = image
    for n in (1, 2, 17, 12345):
        entry.image_user.frame_current = n
        assert frames.sequence_path(str(plates[0]), n) == image.filepath_from_user(
            image_user=entry.image_user
        )


def test_user_frame_follows_blender(seq):
    assert frames.user_frame(7) == 7  # no frame range set up: the scene frame
    assert [frames.user_frame(f, 1, 3) for f in (0, 1, 3, 5)] == [0, 1, 3, 3]
    assert [frames.user_frame(f, 10, 3, 100) for f in (10, 12)] == [101, 103]
    assert [frames.user_frame(f, 1, 3, cyclic=True) for f in (1, 3, 4, 7)] == [1, 3, 1, 1]


def test_bounds_filter_smooths_and_rounds(seq):
    rng = np.random.default_rng(1)
    truth = np.array([100.0, 50.0, 200.0, 150.0])
    raw = [truth + rng.normal(0, 1.5, 4) for _ in range(60)]
    for smoothing in (0.0, 0.8):
        f = seq.BoundsFilter()
        held = np.array([f(i, box, smoothing) for i, box in enumerate(raw, 1)])
        assert np.all(held == np.round(held))  # whole pixels
        if smoothing == 0.0:
            jitter_raw = np.abs(np.diff(held, axis=0)).mean()
        else:
            jitter = np.abs(np.diff(held[10:], axis=0)).mean()
    assert jitter < 0.5 * jitter_raw
    f = seq.BoundsFilter()
    f(1, truth, 0.8)
    assert f(10, truth + 50, 0.8) == tuple(truth + 50)  # a jump in frames restarts the filter
    assert f(10, truth, 0.8) == tuple(truth + 50)  # the same frame again: no new step
    assert seq.preroll(0.0) == 0 and seq.preroll(0.5) == 10


# --- live update --------------------------------------------------------------------------------


def test_each_frame_gets_its_plates_map(live, seq):
    scene, _, image = live
    assert seq.installed() and scene.render.use_lock_interface
    seen = []
    for frame in (1, 2, 3, 2):
        scene.frame_set(frame)
        rgb = mean_rgb(image)
        seen.append(rgb)
        assert _dominant(rgb) == _dominant(COLOURS[frame - 1]), (frame, rgb)
        assert f"frame {frame}:" in seq.status(scene)
    assert np.allclose(seen[1], seen[3])  # frame 2 again: the same map
    assert not np.allclose(seen[0], seen[1]) and not np.allclose(seen[1], seen[2])


def test_animation_render_uses_each_frames_map(live, tmp_path):
    """render(animation=True): frame_change_post runs per frame with the render's depsgraph,
    before the engine syncs, so each rendered frame reflects its own plate."""
    scene, sphere, _ = live
    scene.render.filepath = str(tmp_path / "render_")
    scene.render.use_compositing = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(animation=True)
    for frame in (1, 2, 3):
        rgba = read(tmp_path / f"render_{frame:04d}.exr")
        on_sphere = rgba[rgba[..., 3] > 0.99][:, :3].mean(0)
        assert _dominant(on_sphere) == _dominant(COLOURS[frame - 1]), (frame, on_sphere)


def test_movie_plate(addon, seq, tmp_path):
    movie = write_movie(tmp_path, write_plates(tmp_path))
    if movie is None:
        pytest.skip("this Blender cannot write movies")
    scene = bpy.context.scene
    sphere = build_scene()
    image = bpy.data.images.load(str(movie))
    assert image.source == "MOVIE" and image.frame_duration == 3
    scene.virtual_reflections.plate_image = image
    scene.virtual_reflections.resolution = "256"
    module(addon, "compositor").setup_from_plate(scene, image)
    scene.frame_set(1)
    _generate(addon, scene, [sphere])
    scene.virtual_reflections.sequence = True
    cached = len(bpy.data.images)
    for frame in (1, 2, 3):
        scene.frame_set(frame)
        rgb = mean_rgb(bpy.data.images[f"VR Map {sphere.name}"])
        assert _dominant(rgb) == _dominant(COLOURS[frame - 1]), (frame, rgb)
    assert len(bpy.data.images) == cached  # no image per frame
    assert not image.is_dirty  # the artist's movie is never touched
    scene.frame_set(4)  # beyond the movie: the map stays, the status says why
    assert "frames 1-3" in seq.status(scene)


def test_table_reused_while_bounds_stay(live, addon):
    scene, _, _ = live
    lookup_table = importlib.import_module(f"{addon.__name__}.virtual_reflections").lookup_table
    scene.frame_set(1)
    before = lookup_table.cache_info()
    scene.frame_set(2)
    scene.frame_set(3)
    after = lookup_table.cache_info()
    assert after.misses == before.misses and after.hits == before.hits + 2


def test_smoothing_reduces_jitter_and_keeps_tables(live, seq, addon):
    """A sphere jittering by about a pixel (tracking noise): raw bounds move every
    frame; smoothed and rounded ones move less, and their tables come from the cache."""
    scene, sphere, image = live
    scene.virtual_reflections.sequence = False  # this test steps the frames itself
    edit = bpy.context.preferences.edit
    interpolation = edit.keyframe_new_interpolation_type
    edit.keyframe_new_interpolation_type = "CONSTANT"
    try:
        rng = np.random.default_rng(0)
        for frame in range(1, 31):
            sphere.location.x = float(rng.normal(0.0, 0.08))
            sphere.keyframe_insert("location", index=0, frame=frame)
    finally:
        edit.keyframe_new_interpolation_type = interpolation
    # one plate for all frames: only bounds move
    plate = module(addon, "scene.plate").frame(scene, 1)
    results = {}
    lookup_table = importlib.import_module(f"{addon.__name__}.virtual_reflections").lookup_table
    for smoothing in (0.0, 0.8):
        scene.virtual_reflections.smoothing = smoothing
        lookup_table.cache_clear()
        filters, boxes, built = {}, [], 0
        for frame in range(1, 31):
            scene.frame_set(frame)
            depsgraph = bpy.context.evaluated_depsgraph_get()
            update = seq.update(scene, depsgraph, filters=filters, frame=frame, plate_frame=plate)
            boxes.append(update.boxes[image.name])
            built += update.tables["built"]
        boxes = np.array(boxes)
        results[smoothing] = (np.abs(np.diff(boxes[5:], axis=0)).sum(), built)
    assert results[0.8][0] < 0.5 * results[0.0][0], results
    assert results[0.8][1] < results[0.0][1], results


def test_render_threads_policy(live, seq, monkeypatch):
    """Edits on the main thread without a render job; during a render job only with the
    interface locked; never from another thread without a job."""
    scene, _, image = live
    verdicts = {}
    for job in (False, True):
        for lock in (False, True):
            monkeypatch.setattr(seq, "_job_running", lambda job=job: job)
            scene.render.use_lock_interface = lock
            verdicts[job, lock, "main"] = seq.may_edit(scene)[0]
            box = {}
            worker = threading.Thread(target=lambda b=box: b.update(ok=seq.may_edit(scene)[0]))
            worker.start()
            worker.join()
            verdicts[job, lock, "thread"] = box["ok"]
    assert verdicts == {
        (False, False, "main"): True,
        (False, False, "thread"): False,
        (False, True, "main"): True,
        (False, True, "thread"): False,
        (True, False, "main"): False,
        (True, False, "thread"): False,
        (True, True, "main"): True,
        (True, True, "thread"): True,
    }
    # A render job with the interface unlocked: the handler leaves the maps alone.
    scene.frame_set(1)
    monkeypatch.setattr(seq, "_job_running", lambda: True)
    scene.render.use_lock_interface = False
    red = mean_rgb(image)
    scene.frame_set(2)
    assert np.allclose(mean_rgb(image), red)
    assert "Lock Interface" in seq.status(scene)


def test_handler_removed_on_unregister_and_on_load(addon, seq, tmp_path):
    scene = bpy.context.scene
    assert not seq.installed()
    scene.virtual_reflections.sequence = True
    assert seq.installed()
    path = tmp_path / "live.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    assert not seq.installed()  # load_pre removed it; the new file has no live scene
    bpy.ops.wm.open_mainfile(filepath=str(path))
    assert seq.installed()  # load_post: this file has live update on
    bpy.context.scene.virtual_reflections.sequence = False
    assert not seq.installed()
    bpy.context.scene.virtual_reflections.sequence = True
    addon.unregister()
    try:
        assert not seq.installed()
        handlers = bpy.app.handlers
        assert all(
            getattr(f, "__module__", "") != seq.__name__
            for name in ("frame_change_post", "render_init", "load_pre", "load_post")
            for f in getattr(handlers, name)
        )
    finally:
        addon.register()  # the fixture unregisters


def test_compositor_plate_node_spans_the_whole_sequence(addon, tmp_path):
    """Image.frame_duration stays 1 for a sequence loaded from Python; the compositor's plate
    node must still play every frame on disk, not hold frame 1."""
    plates = write_plates(tmp_path)
    image = bpy.data.images.load(str(plates[0]))
    image.source = "SEQUENCE"
    scene = bpy.context.scene
    module(addon, "compositor").setup_from_plate(scene, image)
    tree = getattr(scene, "compositing_node_group", None) or scene.node_tree
    nodes = [n for n in tree.nodes if n.bl_idname == "CompositorNodeImage" and n.image == image]
    assert len(nodes) == 1
    assert nodes[0].frame_duration == len(plates)
    assert nodes[0].frame_start == 1 and nodes[0].frame_offset == 0
