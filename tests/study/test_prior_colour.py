"""`prior_colour.tint_factors` tints a neutral prior toward the plate's mean colour and keeps
its luminance (no bpy)."""

import numpy as np
import pytest

from study.scenes3d import prior_colour
from virtual_reflections.fill import REC709_LUMA


def test_a_tint_keeps_the_luminance_and_moves_toward_the_plates_colour():
    mean = np.array([0.4, 0.2, 0.1])
    neutral = prior_colour.tint_factors(mean, 0.0)
    assert neutral == pytest.approx(np.ones(3))
    half, whole = prior_colour.tint_factors(mean, 0.5), prior_colour.tint_factors(mean, 1.0)
    for factors in (half, whole):
        assert float(factors @ REC709_LUMA) == pytest.approx(1.0)
    # the whole tint is the plate's chromaticity; half of it lies half-way
    assert whole == pytest.approx(mean / float(mean @ REC709_LUMA))
    assert half == pytest.approx(0.5 * (neutral + whole))
    assert half[0] > 1.0 > half[2]  # a warm plate: more red, less blue


def test_a_black_plate_leaves_the_prior_neutral():
    assert prior_colour.tint_factors([0.0, 0.0, 0.0], 0.5) == pytest.approx(np.ones(3))


def test_the_tint_scores_are_the_rendered_difference_at_no_tint():
    rng = np.random.default_rng(3)
    dark = rng.uniform(0, 0.3, (8, 8, 3)).astype(np.float32)
    full = dark + rng.uniform(0, 0.4, (8, 8, 3)).astype(np.float32)
    truth = rng.uniform(0, 1, (8, 8, 3)).astype(np.float32)
    mask = np.ones((8, 8), bool)
    scores = prior_colour.tint_scores(full, dark, truth, mask, (0, 8, 0, 8), 10.0, [0.3, 0.2, 0.1])
    from study.evaluate.metrics import psnr, to_display

    assert scores[0] == pytest.approx(float(psnr(to_display(full), to_display(truth), mask)) - 10.0)
    assert scores[1] != pytest.approx(scores[0])


def test_the_colour_table_needs_the_auto_gain():
    assert "Auto gain only" in prior_colour.colour_table({"sky_gain": 1.0, "scenes": []})
