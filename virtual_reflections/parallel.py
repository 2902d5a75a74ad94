"""Split row-wise NumPy work over the machine's cores.

NumPy releases the GIL inside its loops over large arrays, so a few threads each working on
a block of rows run truly in parallel. Work is split only when it is large enough to pay
for the threads.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

MIN_ROWS = 65536  # texels: below this, one thread is faster
CHUNK = 32768  # texels per block when working in chunks: temporaries stay small and cached
_pool: ThreadPoolExecutor | None = None


def workers() -> int:
    """Threads to use: the cores this process may run on, at most 8 (VR_THREADS overrides)."""
    env = os.environ.get("VR_THREADS")
    if env and env.isdigit() and int(env) > 0:
        return int(env)
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, 8))


def for_blocks(fn, rows: int, min_rows: int = MIN_ROWS, max_rows: int | None = None) -> None:
    """Call fn(start, stop) over consecutive blocks covering range(rows), in parallel;
    each block gets at least `min_rows` rows and, with `max_rows`, at most that many (the
    blocks then outnumber the threads, which take them in turn: a caller working on large
    arrays keeps its temporaries small, so they are neither fresh memory nor out of cache)."""
    n = min(workers(), max(1, rows // min_rows))
    blocks = n if max_rows is None else max(n, -(-rows // max_rows))
    if blocks == 1:
        fn(0, rows)
        return
    if n == 1:
        for i in range(blocks):
            fn(rows * i // blocks, rows * (i + 1) // blocks)
        return
    global _pool
    if _pool is None or _pool._max_workers < n:
        _pool = ThreadPoolExecutor(max_workers=n, thread_name_prefix="vr")
    bounds = [rows * i // blocks for i in range(blocks + 1)]
    futures = [_pool.submit(fn, a, b) for a, b in zip(bounds, bounds[1:])]
    for f in futures:
        f.result()


def chunks(count: int, size: int = 32768):
    """(start, stop) of consecutive blocks of `size` rows: per-texel work on large maps in
    blocks keeps its temporaries small (cached, not fresh memory)."""
    return ((a, min(a + size, count)) for a in range(0, count, size))
