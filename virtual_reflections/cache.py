"""The lookup tables' cache, bounded in bytes rather than in entries.

A 4096-wide camera-view table holds hundreds of MB; a cache of a fixed number of entries can
then keep gigabytes. `bounded` memoizes a table-building function; every function it wraps
shares one budget (`set_limit`, default DEFAULT_LIMIT bytes; the add-on's preference sets it),
and the least recently used tables go first when a new one would exceed it. A table larger
than the whole budget is returned but not kept.

The wrapped function keeps `functools.lru_cache`'s `cache_info()` (hits, misses, maxsize None,
currsize) and `cache_clear()`.
"""

from __future__ import annotations

import collections
import functools
import threading

import numpy as np

DEFAULT_LIMIT = 512 * 2**20

CacheInfo = collections.namedtuple("CacheInfo", "hits misses maxsize currsize")

_lock = threading.RLock()
_entries: collections.OrderedDict = collections.OrderedDict()  # (fn, args) -> (value, bytes)
_state = {"limit": DEFAULT_LIMIT, "bytes": 0}


def nbytes(value) -> int:
    """The bytes of the NumPy arrays a value holds.

    Parameters
    ----------
    value : object
        An array, a tuple or list of values, or a dataclass whose fields are values; an array
        sharing a base with one already counted is counted once.

    Returns
    -------
    int
    """
    seen, total, stack = set(), 0, [value]
    while stack:
        item = stack.pop()
        if isinstance(item, np.ndarray):
            base = item if item.base is None else item.base
            if id(base) not in seen:
                seen.add(id(base))
                total += getattr(base, "nbytes", item.nbytes)
        elif isinstance(item, (tuple, list)):
            stack.extend(item)
        elif hasattr(item, "__dataclass_fields__"):
            stack.extend(getattr(item, name) for name in item.__dataclass_fields__)
    return total


def set_limit(limit: int) -> None:
    """Set the budget in bytes shared by every bounded cache; tables beyond it are dropped now.

    Parameters
    ----------
    limit : int
        Bytes, at least 0 (0 keeps nothing).

    Raises
    ------
    ValueError
        A negative limit.
    """
    if limit < 0:
        raise ValueError(f"the cache limit must be >= 0 bytes, got {limit}")
    with _lock:
        _state["limit"] = int(limit)
        _evict(0)


def limit() -> int:
    """The budget in bytes shared by every bounded cache (`set_limit`).

    Returns
    -------
    int
    """
    return _state["limit"]


def cached_bytes() -> int:
    """Bytes held by every bounded cache together.

    Returns
    -------
    int
    """
    return _state["bytes"]


def _evict(room: int) -> None:
    while _entries and _state["bytes"] + room > _state["limit"]:
        _, (_, size) = _entries.popitem(last=False)
        _state["bytes"] -= size


def bounded(fn):
    """Memoize a function in the shared, byte-bounded cache.

    Parameters
    ----------
    fn : callable
        Called with positional, hashable arguments; its value's arrays are counted (`nbytes`).

    Returns
    -------
    callable
        `fn` memoized, with `cache_info()` and `cache_clear()` as `functools.lru_cache`'s.
    """
    stats = {"hits": 0, "misses": 0}

    @functools.wraps(fn)
    def wrapper(*args):
        key = (fn, args)
        with _lock:
            hit = _entries.get(key)
            if hit is not None:
                _entries.move_to_end(key)
                stats["hits"] += 1
                return hit[0]
            stats["misses"] += 1
        value = fn(*args)
        size = nbytes(value)
        with _lock:
            if size <= _state["limit"] and key not in _entries:
                _evict(size)
                _entries[key] = (value, size)
                _state["bytes"] += size
        return value

    def cache_info():
        with _lock:
            mine = sum(1 for k in _entries if k[0] is fn)
        return CacheInfo(stats["hits"], stats["misses"], None, mine)

    def cache_clear():
        with _lock:
            for key in [k for k in _entries if k[0] is fn]:
                _state["bytes"] -= _entries.pop(key)[1]
            stats["hits"] = stats["misses"] = 0

    wrapper.cache_info = cache_info
    wrapper.cache_clear = cache_clear
    return wrapper
