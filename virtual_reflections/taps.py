"""The weighted sum of gathered pyramid taps, the last step of every NumPy gather.

(An RGBA pyramid would let NumPy's `take` move a row as one 16-byte item, 2.4 times faster
than 12-byte RGB rows; but writing 4-channel levels from a 3-channel plate costs NumPy more
per frame than that saves: 51 against 28 ms for a 1080p pyramid, measured.)
"""

from __future__ import annotations

import numpy as np

MATMUL_TAPS = 32  # from this many taps per texel (rows first) a batched matmul is faster


def weighted_sum(taps, weight, out, rows_first: bool = True) -> None:
    """out (n, 3) = the weighted sums of the taps: taps (n, K, 3) with weight (n, K), or with
    rows_first False, taps (K, n, 3) with weight (K, n). Channel by channel: NumPy's einsum
    over a channel (a strided 2-D view) runs its fast inner loop, over (.., 3) it does not
    (about 2.5 times slower). With many taps per texel (the seen texels' 64), rows first, one
    batched matmul (n of (1, K) @ (K, 3)) is faster still: 1.5-1.7 against 3.1-3.7 ns a tap
    for K = 64, slower below ~24 (measured with NumPy 1.26 and 2.x)."""
    if rows_first and taps.shape[1] >= MATMUL_TAPS:
        np.matmul(weight[:, None, :], taps, out=out[:, None, :])
        return
    spec = "tk,tk->t" if rows_first else "kt,kt->t"
    for c in range(3):
        np.einsum(spec, taps[..., c], weight, out=out[:, c])


_RGB = np.dtype((np.void, 12))  # one float32 RGB row as a single item


def put_rows(out, texels, rows) -> None:
    """out[texels] = rows, for out (T, 3) C-contiguous float32 and rows (n, 3) float32: each
    row moved as one 12-byte item (NumPy's fancy assignment of (n, 3) rows is ~2.5 times
    slower)."""
    items = np.ascontiguousarray(rows, np.float32).view(_RGB).ravel()
    np.put(out.view(_RGB).ravel(), texels, items)


def take_rows(source, texels) -> np.ndarray:
    """source[texels] as a new (n, 3) float32 array, for source (T, 3) C-contiguous float32,
    each row read as one 12-byte item (~3 times faster than fancy indexing)."""
    return np.take(source.view(_RGB).ravel(), texels).view(np.float32).reshape(-1, 3)
