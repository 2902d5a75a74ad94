"""The camera view's edge extension: the texels near the plate's view, stored compactly.

Within `Params.extend_fade` degrees of the plate's view a texel is the plate's edge, blurred
and extended (one trilinear sample of the mip pyramid), faded into the fill by a weight that
falls from 1 at the view's edge to 0 at the reach. The fill is written over every texel
before (fill.fill_values on a lat-long, the fill's taps on a cube), so the extension
keeps only its trilinear samples (trilinear.py: 14 bytes a texel, read by NumPy, OpenCV or
Numba)
and its weight; per frame, out = fill + weight (extension - fill). Without a fill
(extend_fade None) there is no weight: the extension alone.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .backends import backend, given, kernels, run
from .taps import put_rows, take_rows
from .trilinear import ROW, Trilinear, compiled_args, gather_runs, trilinear_samples


@dataclass(frozen=True, eq=False)
class Extension:
    """samples: the trilinear samples, read in their runs' order (`gather_runs`); counts:
    per run, how many of its first rows are texels (the rest is padding); texels: (n,) int32
    flat map indices of those rows, run after run; weight: (n,) float32, in the same order,
    the extension's share (the fill's is 1 - weight), or None for the extension alone."""

    samples: Trilinear
    counts: tuple
    texels: np.ndarray
    weight: np.ndarray | None

    def without(self, drop: np.ndarray) -> Extension | None:
        """This extension without the texels where the (T,) bool mask `drop` is set (None
        when none is left)."""
        keep = ~drop[self.texels]
        if not keep.any():
            return None
        firsts = np.cumsum(self.counts) - self.counts  # every run holds texels
        counts = tuple(int(n) for n in np.add.reduceat(keep, firsts) if n)
        samples = self.samples.keep_rows(keep, self.counts)
        weight = None if self.weight is None else self.weight[keep]
        return _frozen(Extension(samples, counts, self.texels[keep], weight))


def _frozen(ext: Extension) -> Extension:
    for a in (ext.texels, ext.weight):
        if a is not None:
            a.flags.writeable = False
    return ext


def extension(texels, px, py, lod, top: int, weight=None) -> Extension | None:
    """The extension of `texels` (n,) read at level-0 plate positions (px, py) (n,) with mip
    level `lod` (n,) in [0, top]; `weight` (n,): its share over the fill (None: no fill)."""
    texels = np.asarray(texels, np.int64)
    if texels.size == 0:
        return None
    px, py, lod = (np.asarray(v, np.float32) for v in (px, py, lod))
    samples = trilinear_samples(px, py, lod, top, (texels.size, 1))
    # Each texel's row of the runs; the texels and weights put in that order, so a frame
    # reads the runs' values in place (no way back to map order but the texels themselves).
    rank = samples.rank.reshape(-1, 2)
    rows = rank[:, 1].astype(np.int64) * ROW + rank[:, 0]
    order = np.argsort(rows, kind="stable")
    run = np.searchsorted(np.asarray(samples.starts), rows[order], side="right") - 1
    counts = np.bincount(run, minlength=len(samples.levels))
    share = None if weight is None else np.asarray(weight, np.float32)[order]
    compact = dataclasses.replace(samples, rank=None)  # read in run order: no rank kept
    return _frozen(
        Extension(compact, tuple(int(c) for c in counts), texels[order].astype(np.int32), share)
    )


def apply(ext: Extension, source, shapes, offsets, out) -> None:
    """out[texels] (out: (T, 3) float32, the fill already written there) = the extension
    read from the flat bordered pyramid `source`, faded into the fill by its weight."""
    if backend() == "numba":  # one compiled pass: sample, fade, write
        x, y, upper, shares, geometry, source, plate = compiled_args(
            ext.samples, source, shapes, offsets
        )
        counts = np.asarray(ext.counts, np.int64)
        done = np.concatenate(([0], np.cumsum(counts)))
        firsts = np.asarray(ext.samples.starts[:-1], np.int64)
        run(kernels().extension_runs, x, y, upper, shares, firsts, counts, done, geometry,
            ext.texels, given(ext.weight), source, plate, out)  # fmt: skip
        return
    values = gather_runs(ext.samples, source, shapes, offsets, counts=ext.counts)
    done = 0
    for r, count in enumerate(ext.counts):
        a = ext.samples.starts[r]
        mine = values[a : a + count]
        texels = ext.texels[done : done + count]
        if ext.weight is not None:
            fill = take_rows(out, texels)
            mine -= fill
            mine *= ext.weight[done : done + count, None]
            mine += fill
        put_rows(out, texels, mine)
        done += count
