"""The mip pyramid: box filters with edge repetition, bordered levels, partial pyramids."""

import numpy as np
import pytest

from virtual_reflections import Params, backends, lookup_table
from virtual_reflections.mipmap import build_pyramid, level_shapes, level_view


def _skip_absent(use):
    if use != "numpy" and use not in backends.available_backends():
        pytest.skip(f"{use} not installed (optional)")


@pytest.mark.parametrize("use", ["numpy", "opencv", "numba"])
@pytest.mark.parametrize("h, w", [(8, 8), (7, 5), (1, 6), (5, 1), (1, 1), (37, 50), (36, 51)])
def test_levels_are_2x2_box_filters_with_repeated_edges(h, w, use, monkeypatch):
    """Every back end (OpenCV's area resize, Numba's kernels when installed; NumPy)."""
    _skip_absent(use)
    monkeypatch.setenv("VR_GATHER", use)
    rng = np.random.default_rng(h * 100 + w)
    plate = rng.random((h, w, 3), dtype=np.float32)
    flat, shapes = build_pyramid(plate), level_shapes(h, w)
    assert shapes[-1] == (1, 1)
    previous = plate
    for level in range(1, len(shapes)):
        p = np.pad(
            previous, ((0, previous.shape[0] % 2), (0, previous.shape[1] % 2), (0, 0)), mode="edge"
        )
        expected = p.reshape(p.shape[0] // 2, 2, p.shape[1] // 2, 2, 3).mean((1, 3))
        got = level_view(flat, shapes, level)
        assert np.allclose(got, expected, atol=1e-6)
        previous = got
    assert np.array_equal(level_view(flat, shapes, 0), plate)


@pytest.mark.parametrize("use", ["numpy", "opencv", "numba"])
@pytest.mark.parametrize("h, w", [(37, 50), (40, 48), (64, 96)])
@pytest.mark.parametrize("first", [2, 3])
def test_partial_pyramid_holds_the_same_coarse_levels(h, w, first, use, monkeypatch):
    """Level `first` comes straight from the plate when its sides are multiples of
    2^first (the means of 2^first-wide blocks: equal to rounding), else by halving."""
    _skip_absent(use)
    monkeypatch.setenv("VR_GATHER", use)
    plate = np.random.default_rng(h + w).random((h, w, 3), dtype=np.float32)
    shapes = level_shapes(h, w)
    full, part = build_pyramid(plate), build_pyramid(plate, first=first)
    assert part.shape[0] < full.shape[0] / 8
    k = 1 << first
    if h % k == 0 and w % k == 0:
        blocks = plate.reshape(h // k, k, w // k, k, 3).mean((1, 3))
        assert np.allclose(level_view(part, shapes, first, first), blocks, rtol=0, atol=1e-6)
    for level in range(first, len(shapes)):
        got, want = level_view(part, shapes, level, first), level_view(full, shapes, level)
        if h % k or w % k:  # halved all the way: the same to the bit
            assert np.array_equal(got, want)
        else:
            assert np.allclose(got, want, rtol=0, atol=1e-6)


def test_small_maps_skip_the_fine_levels():
    """A 128-wide map of a 1920x1080 plate never reads the plate's full resolution."""
    table = lookup_table(1920, 1080, (800.0, 400.0, 1100.0, 700.0), Params(), "latlong", 128)
    assert table.first_level >= 1
    assert (
        lookup_table(192, 108, (80.0, 40.0, 110.0, 70.0), Params(), "latlong", 512).first_level == 0
    )
