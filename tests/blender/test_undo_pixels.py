"""The maps' pixels come back after undo and redo (operators/scene/undo_pixels.py). Blender's undo
needs its window, so the undo itself is tested in tests/e2e/test_ui.py; here the memory."""

import numpy as np
from shots import addon_part


def test_restore_writes_back_what_was_written_under_the_images_token(addon):
    maps = addon_part("operators.scene.maps")
    undo_pixels = addon_part("operators.scene.undo_pixels")
    env = np.random.default_rng(1).random((8, 16, 3), dtype=np.float32)
    image = maps.store_map("VR Map Test", env)
    first = image[undo_pixels.TOKEN]
    image.pixels.foreach_set(np.zeros(len(image.pixels), np.float32))  # as undo leaves it
    assert undo_pixels.restore() == 1
    back = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(back)
    assert np.array_equal(back.reshape(8, 16, 4)[::-1, :, :3], env)
    # A new Generate is a new token; the older pixels stay for an undo back to them.
    maps.store_map("VR Map Test", env * 0.5)
    assert image[undo_pixels.TOKEN] != first
    image[undo_pixels.TOKEN] = first  # undo back to the first Generate
    undo_pixels.restore()
    image.pixels.foreach_get(back)
    assert np.array_equal(back.reshape(8, 16, 4)[::-1, :, :3], env)


def test_memory_keeps_the_most_recent_within_the_budget(addon, monkeypatch):
    maps = addon_part("operators.scene.maps")
    undo_pixels = addon_part("operators.scene.undo_pixels")
    monkeypatch.setattr(undo_pixels, "BUDGET_BYTES", 3 * 8 * 16 * 3 * 4)  # three maps
    env = np.ones((8, 16, 3), np.float32)
    images = [maps.store_map(f"VR Map {i}", env) for i in range(5)]
    for image in images:
        image.pixels.foreach_set(np.zeros(len(image.pixels), np.float32))
    assert undo_pixels.restore() == 3  # the first two were dropped
    assert max(images[0].pixels[:3]) == 0.0 and images[4].pixels[0] == 1.0
