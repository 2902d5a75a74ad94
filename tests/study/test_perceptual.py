"""The study's perceptual metrics (study/evaluate/perceptual.py): known inputs, known outputs."""

import math

import numpy as np
import pytest

from study.evaluate import perceptual


def grey(values):
    """(H, W, 3) display image of grey levels ``values`` (H, W)."""
    return np.repeat(np.asarray(values, np.float64)[..., None], 3, axis=-1)


def test_flip_is_zero_for_identical_images_and_large_for_black_against_white():
    pytest.importorskip("flip_evaluator", reason="requirements/blender45.txt installs it")
    rng = np.random.default_rng(1)
    image = rng.random((24, 32, 3))
    mask = np.zeros((24, 32), bool)
    mask[4:20, 6:26] = True
    assert perceptual.flip_ldr(image, image, mask) == 0.0
    assert perceptual.flip_ldr(grey(np.zeros((24, 32))), grey(np.ones((24, 32))), mask) > 0.9
    # a small change costs less than a large one
    small = perceptual.flip_ldr(np.clip(image + 0.02, 0, 1), image, mask)
    large = perceptual.flip_ldr(np.clip(image + 0.3, 0, 1), image, mask)
    assert 0.0 < small < large


def test_erode_takes_pixels_off_the_rim_and_the_image_border():
    mask = np.zeros((11, 11), bool)
    mask[2:9, 2:9] = True  # 7 x 7
    eroded = perceptual.erode(mask, 2)
    assert eroded.sum() == 9 and eroded[4:7, 4:7].all()
    assert not perceptual.erode(np.ones((4, 4), bool), 2).any()  # the border is outside
    assert (perceptual.erode(mask, 0) == mask).all()


def test_upper_half_is_the_rows_above_the_middle_of_the_box():
    mask = np.zeros((10, 5), bool)
    mask[2:6, 1:4] = True  # rows 2..5
    upper = perceptual.upper_half(mask)
    assert upper[2:4, 1:4].all() and not upper[4:].any() and upper.sum() == 6


def test_detail_of_a_ramp_is_its_slope_and_a_flat_image_has_none():
    h, w = 20, 30
    ramp = grey(np.tile(0.01 * np.arange(w), (h, 1)))  # luminance rises 0.01 per pixel
    mask = np.zeros((h, w), bool)
    mask[3:17, 3:27] = True
    assert perceptual.detail(ramp, mask) == pytest.approx(0.01)
    assert perceptual.detail(grey(np.full((h, w), 0.4)), mask) == 0.0
    assert perceptual.detail_ratio(ramp, ramp, mask) == pytest.approx(1.0)
    assert perceptual.detail_ratio(grey(np.full((h, w), 0.4)), ramp, mask) == 0.0
    assert perceptual.detail_ratio(grey(0.5 * ramp[..., 0]), ramp, mask) == pytest.approx(0.5)
    assert math.isnan(perceptual.detail_ratio(ramp, grey(np.full((h, w), 0.4)), mask))


def test_detail_counts_only_inside_the_eroded_mask_and_the_part_asked():
    # a sharp edge just outside the eroded mask does not count; the upper half alone sees
    # only the upper half's texture
    h, w = 24, 24
    image = grey(np.zeros((h, w)))
    image[:, 12:] = 1.0  # an edge at column 12
    mask = np.zeros((h, w), bool)
    mask[2:22, 2:11] = True  # eroded: columns 4..8, the edge's gradient is at 11 and 12
    assert perceptual.detail(image, mask) == 0.0
    stripes = grey(np.tile((np.arange(h) % 2)[:, None] * 1.0, (1, w)))
    stripes[h // 2 - 2 :] = 0.3  # texture in the upper half only (rows 0..9; middle 12)
    full = np.zeros((h, w), bool)
    full[2:22, 2:22] = True
    upper = perceptual.upper_half(full)
    lower = full & ~upper
    assert perceptual.detail(stripes, full, lower) < 0.01 < perceptual.detail(stripes, full, upper)
