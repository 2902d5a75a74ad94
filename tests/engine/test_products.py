"""The engine's matrix products in pieces and its weighted sums of taps: the same numbers as
one NumPy product, whatever the shapes (pieces of rows and columns, views for outputs)."""

import numpy as np
import pytest

from virtual_reflections.products import PIECE, matmul
from virtual_reflections.taps import MATMUL_TAPS, weighted_sum


@pytest.mark.parametrize(
    "m, k, n",
    [
        (1, 6, 3),
        (7281 * 3 + 5, 6, 3),
        (513, 6, 3 * 2048),
        (1024, 6, 3 * 1023),
        (3, 3, 1),
        (0, 6, 3),
    ],
)
def test_matmul_in_pieces_is_the_whole_product(m, k, n):
    rng = np.random.default_rng(m + n)
    a = rng.random((m, k), dtype=np.float32)
    b = rng.random((k, n), dtype=np.float32)
    out = np.full((m, n), np.nan, np.float32)
    matmul(a, b, out)
    np.testing.assert_allclose(out, a @ b, rtol=1e-6, atol=1e-6)


def test_matmul_writes_into_a_view_with_rows_apart():
    rng = np.random.default_rng(1)
    a = rng.random((300, 6), dtype=np.float32)
    b = rng.random((6, PIECE // 6 + 7), dtype=np.float32)  # wider than one piece
    big = np.zeros((300, b.shape[1] + 10), np.float32)
    matmul(a, b, big[:, 5:-5])
    np.testing.assert_allclose(big[:, 5:-5], a @ b, rtol=1e-6, atol=1e-6)
    assert not big[:, :5].any() and not big[:, -5:].any()  # nothing written beside the view


@pytest.mark.parametrize("taps", [4, 8, MATMUL_TAPS - 1, MATMUL_TAPS, 64])
def test_weighted_sum_either_way_is_the_sum(taps):
    rng = np.random.default_rng(taps)
    values = rng.random((257, taps, 3), dtype=np.float32)
    weight = rng.random((257, taps), dtype=np.float32)
    want = np.einsum("tk,tkc->tc", weight.astype(np.float64), values.astype(np.float64))
    out = np.empty((257, 3), np.float32)
    weighted_sum(values, weight, out)
    np.testing.assert_allclose(out, want, rtol=1e-5)
    planes = np.ascontiguousarray(values.transpose(1, 0, 2))
    weighted_sum(planes, np.ascontiguousarray(weight.T), out, rows_first=False)
    np.testing.assert_allclose(out, want, rtol=1e-5)
