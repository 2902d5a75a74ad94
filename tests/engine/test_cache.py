"""The lookup tables' cache is bounded in bytes (virtual_reflections/cache.py)."""

import numpy as np
import pytest

from virtual_reflections import Params, cache, lookup_table


@pytest.fixture
def budget():
    before = cache.limit()
    lookup_table.cache_clear()
    yield
    cache.set_limit(before)
    lookup_table.cache_clear()


def table(i, size=256):
    return lookup_table(64, 36, (10.0 + i, 10.0, 30.0 + i, 30.0), Params(), "latlong", size)


def test_tables_beyond_the_budget_are_dropped_oldest_first(budget):
    one = cache.nbytes(table(0))
    assert one > 0
    lookup_table.cache_clear()
    cache.set_limit(int(2.5 * one))
    for i in range(5):
        table(i)
    assert cache.cached_bytes() <= cache.limit()
    assert lookup_table.cache_info().currsize == 2
    misses = lookup_table.cache_info().misses
    table(4)  # the newest is kept ...
    assert lookup_table.cache_info().misses == misses
    table(0)  # ... the oldest was dropped
    assert lookup_table.cache_info().misses == misses + 1


def test_a_table_larger_than_the_budget_is_returned_but_not_kept(budget):
    cache.set_limit(1000)
    t = table(0)
    assert isinstance(t.layers[0].samples.x, np.ndarray) and cache.cached_bytes() == 0
    assert lookup_table.cache_info().currsize == 0


def test_lowering_the_limit_evicts_now(budget):
    for i in range(3):
        table(i)
    assert cache.cached_bytes() > 0
    cache.set_limit(0)
    assert cache.cached_bytes() == 0
    with pytest.raises(ValueError):
        cache.set_limit(-1)


def test_the_bytes_counted_are_the_tables_arrays(budget):
    t = table(0, 512)
    tri = t.layers[0].samples
    arrays = [tri.x, tri.y, tri.upper, tri.rank]
    assert cache.nbytes(t) >= sum(a.nbytes for a in arrays)
