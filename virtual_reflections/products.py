"""Matrix products in pieces that the BLAS works on the calling thread.

NumPy hands a product to its BLAS (OpenBLAS in NumPy's PyPI wheels), which spreads one of
more than ~2^18 multiply-adds over every core and then keeps its threads spinning for a
while. The engine's per-frame work runs on its own threads (parallel.py), so on a 2-core
machine the steps after such a product ran on what the spinning threads left: Camera View's
frame at 2048 wide took 48-64 ms against 44-47 with one BLAS thread (`OPENBLAS_NUM_THREADS=1`,
measured). The products here are split into pieces of at most PIECE multiply-adds, each
below that threshold, and the pieces shared over the engine's threads: as fast alone (these
products write far more than they compute) and nothing left spinning.
"""

from __future__ import annotations

import numpy as np

from .parallel import for_blocks

PIECE = 1 << 17  # multiply-adds per BLAS call: below OpenBLAS's threshold for its threads
ROWS = 128  # rows a piece has at least, unless it is narrower than PIECE allows (fewer calls)


def matmul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """out (m, n) = a (m, k) @ b (k, n), in pieces of rows and columns (each at most PIECE
    multiply-adds) shared over the engine's threads; out may be a view with rows apart in
    memory. Not for a caller that is itself one of those threads."""
    m, k = a.shape
    n = b.shape[1]
    cols = min(n, max(1, PIECE // (k * ROWS)))  # pieces at least ROWS high where they can be
    rows = max(1, PIECE // (k * cols))

    def block(s, e):
        for r in range(s, e, rows):
            t = min(r + rows, e)
            for c in range(0, n, cols):
                np.matmul(a[r:t], b[:, c : c + cols], out=out[r:t, c : c + cols])

    for_blocks(block, m, min_rows=rows)
