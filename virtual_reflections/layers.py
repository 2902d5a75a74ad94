"""The parts of a lookup table, each writing its texels of the map for one frame.

A table (table.py) is a list of layers, written in order, each over what the ones before it
wrote: the paper's table is one layer (every texel a trilinear sample); the camera view's is
the fill everywhere, then the blurred edge extension near the plate's view, then the seen
texels' supersamples; the ground method's adds the texels that see the ground. Every layer
answers the same small protocol (`Layer`): `write(frame, out)` and `without(drop)` (the
layer without some texels, for the ground's table built on the camera view's).

A `Frame` holds what a frame's layers read: the plate, its bordered mip pyramid (mipmap.py)
and, after it, the fill profile's rows (`FillProfile`, computed per frame).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .backends import backend, given, kernels, run
from .extension import Extension
from .extension import apply as apply_extension
from .fill import FILL_BINS, fill_lookup, fill_profile, fill_values
from .mipmap import level_view
from .parallel import CHUNK, for_blocks
from .sky_texture import modulate
from .supersample import Supersample
from .supersample import gather as gather_supersample
from .taps import put_rows, weighted_sum
from .trilinear import Trilinear
from .trilinear import gather as gather_trilinear

_local = threading.local()


def scratch(name: str, shape: tuple) -> np.ndarray:
    """A float32 buffer reused by the calling thread across frames and tables.

    A new frame or a new table then does not pay for fresh memory (page faults) every time.

    Parameters
    ----------
    name : str
        The buffer's name: one buffer per name and thread.
    shape : tuple of int
        The shape wanted; the buffer grows when it is too small.

    Returns
    -------
    float32 ndarray
        A view of the buffer of that shape (its values are left from before).
    """
    pool = _local.__dict__.setdefault("pool", {})
    size = int(np.prod(shape))
    buf = pool.get(name)
    if buf is None or buf.size < size:
        buf = pool[name] = np.empty(size, np.float32)
    return buf[:size].reshape(shape)


@dataclass(frozen=True)
class Frame:
    """What a frame's layers read.

    Attributes
    ----------
    plate : (H, W, 3) float32 ndarray
        The clean plate.
    source : (R, 3) float32 ndarray
        The flat bordered pyramid (mipmap.py), then the fill profile's rows (`FillProfile.base`).
    pyramid : (P, 3) float32 ndarray
        The pyramid's rows of `source`.
    shapes, offsets : tuple
        The pyramid's level shapes and their first rows (mipmap.level_shapes, level_offsets).
    shape : (int, int)
        (h, w) of the map.
    level0 : (H, W, 3) float32 ndarray or None
        The plate, when a layer reads level 0 from it rather than from the pyramid
        (`Layer.plate_level0`), else None.
    """

    plate: np.ndarray
    source: np.ndarray
    pyramid: np.ndarray
    shapes: tuple
    offsets: tuple
    shape: tuple
    level0: np.ndarray | None = None


class Layer(Protocol):
    """One part of a table: some texels of the map, written over the layers before it.

    Attributes
    ----------
    plate_level0 : bool
        With OpenCV or Numba, level 0 can be read from the plate itself (their reads repeat
        the edge), so a table of such layers alone needs no copy of it in the pyramid.
    """

    plate_level0: bool

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """Write this layer's texels of the map.

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
            The map's texels in order, the layers before this one written.
        """

    def without(self, drop: np.ndarray) -> Layer | None:
        """This layer without some texels (a layer of every texel, written first, is kept).

        Parameters
        ----------
        drop : (h w,) bool ndarray
            The texels to leave to a later layer.

        Returns
        -------
        Layer or None
            None when no texel is left.
        """


def _frozen(*arrays):
    for a in arrays:
        if a is not None:
            a.flags.writeable = False


@dataclass(frozen=True, eq=False)
class FillProfile:
    """The camera-view method's fill profile: where it comes from and goes, per frame.

    Computed on pyramid level `level` (fill.fill_geometry's bins, window and counts) and
    written to rows `base` .. `base` + FILL_BINS x `sides` - 1 of the frame's source, read by
    the layers (`FillSteps`, a cube's fill `Taps`, the ground's blend).
    """

    level: int
    base: int
    saturation: float
    sides: int
    energy: float
    bins: np.ndarray
    window: np.ndarray
    counts: np.ndarray
    sky: np.ndarray | None = None  # sky_share, with a world horizon (Params.up)
    sky_gain: float = 1.0
    sky_tint: tuple = (1.0, 1.0, 1.0)  # Params.sky_tint
    sky_from_plate: float = 0.0  # Params.sky_from_plate
    sky_tint_share: float = 0.0  # Params.sky_tint_share

    def write_profile(self, pyramid, shapes, first: int, source) -> None:
        """Compute the profile of a frame's pyramid into its rows of `source`.

        Parameters
        ----------
        pyramid : (P, 3) float32 ndarray
            The frame's pyramid, levels `first` on.
        shapes : tuple
            Its level shapes.
        first : int
            Its first level.
        source : (R, 3) float32 ndarray
            The pyramid and the rows after it, written from row `base`.
        """
        fill_profile(
            level_view(pyramid, shapes, self.level, first),
            self.bins,
            self.window,
            self.counts,
            self.saturation,
            out=source[self.base :],
            energy=self.energy,
            sky=self.sky,
            sky_gain=self.sky_gain,
            sky_tint=self.sky_tint,
            sky_from_plate=self.sky_from_plate,
            sky_tint_share=self.sky_tint_share,
        )


@dataclass(frozen=True, eq=False)
class FillSteps:
    """A lat-long's fill for every texel, written first (the camera view's, compact).

    Attributes
    ----------
    steps : (h w,) or (h,) uint16 ndarray
        Each texel's elevation step (fill.fill_bins_latlong), or without a world horizon one
        per row.
    side : (3 w,) float32 ndarray or None
        The left side's weight per column, repeated for R, G, B (fill.side_weight); None
        with one side.
    base, sides : int
        The fill profile's rows in the frame's source (`FillProfile`).
    """

    steps: np.ndarray
    side: np.ndarray | None
    base: int
    sides: int
    plate_level0 = False

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """The fill at every texel (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        rows = frame.source[self.base : self.base + FILL_BINS * self.sides]
        lookup = fill_lookup(rows.reshape(-1, FILL_BINS, 3))
        height, width = frame.shape
        steps, side = self.steps, self.side

        def fill_rows(a, b):
            texels = slice(a * width, b * width)
            fill_values(steps[texels], side, lookup, out[texels])

        if backend() == "numba":  # one compiled pass over the map
            run(kernels().fill_rows, steps, given(side), lookup, width, out)
        elif steps.size == height:  # one step per row: one matrix product
            fill_values(steps, side, lookup, out)
        else:
            # (blocks of 8192 texels took twice as long on a 4096-wide map: the pool's cost)
            for_blocks(fill_rows, height, min_rows=8, max_rows=max(1, CHUNK // width))

    def without(self, drop: np.ndarray) -> FillSteps:
        """Every texel's fill, kept: the layers after it write over it (`Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        FillSteps
        """
        return self


@dataclass(frozen=True, eq=False)
class Taps:
    """Texels each the weighted sum of rows of the frame's source (pyramid or fill rows).

    Attributes
    ----------
    texels : (n,) int64 ndarray or None
        Flat map indices; None: every texel in order.
    index : (n, K) int32 ndarray
        Rows of the source.
    weight : (n, K) float32 ndarray
        Their weights, each texel's summing to 1.
    """

    texels: np.ndarray | None
    index: np.ndarray
    weight: np.ndarray
    plate_level0 = False

    def __post_init__(self):
        _frozen(self.texels, self.index, self.weight)

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """out[texels] = the weighted sums (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        gather_taps(frame.source, self.texels, self.index, self.weight, out)

    def without(self, drop: np.ndarray) -> Taps | None:
        """These taps without the texels `drop` (taps of every texel are kept: `Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        Taps or None
        """
        if self.texels is None:  # every texel (the fill): the layers after it write over these
            return self
        keep = ~drop[self.texels]
        if not keep.any():
            return None
        return Taps(self.texels[keep], self.index[keep], self.weight[keep])


def gather_taps(source, texels, index, weight, out) -> None:
    """out[texels] = the weighted sum of source[index] per row.

    Parameters
    ----------
    source : (R, 3) float32 ndarray
    texels : (n,) int64 ndarray or None
        The rows of `out` written; None: every row.
    index : (n, K) int32 ndarray
    weight : (n, K) float32 ndarray
    out : (T, 3) float32 ndarray
    """
    if backend() == "numba":
        every = given(texels, dtype=np.int64)  # empty: every row
        run(kernels().weighted_rows, source, index, weight, every, out)
        return
    buffer = scratch("taps", index.shape + (3,))

    def gather(a, b):  # one block of texels: its taps, then their weighted sum
        taps = np.take(source, index[a:b], axis=0, mode="clip", out=buffer[a:b])
        if texels is None:
            weighted_sum(taps, weight[a:b], out[a:b])
        else:
            sums = np.empty((b - a, 3), np.float32)
            weighted_sum(taps, weight[a:b], sums)
            put_rows(out, texels[a:b], sums)

    for_blocks(gather, index.shape[0])


@dataclass(frozen=True, eq=False)
class TrilinearTexels:
    """The paper's method: every texel one trilinear sample, stored compactly (trilinear.py).

    Attributes
    ----------
    samples : Trilinear
    """

    samples: Trilinear
    plate_level0 = True

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """Every texel's sample (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        gather_trilinear(
            self.samples, frame.pyramid, frame.shapes, frame.offsets, out, plate=frame.level0
        )

    def without(self, drop: np.ndarray) -> TrilinearTexels:
        """Every texel's sample, kept: the layers after it write over it (`Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        TrilinearTexels
        """
        return self


@dataclass(frozen=True, eq=False)
class EdgeExtension:
    """The camera view's texels near the plate's view: the blurred edge extension faded into
    the fill written before it (extension.py).

    Attributes
    ----------
    extension : extension.Extension
    """

    extension: Extension
    plate_level0 = False

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """The extension over the fill (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        apply_extension(self.extension, frame.pyramid, frame.shapes, frame.offsets, out)

    def without(self, drop: np.ndarray) -> EdgeExtension | None:
        """The extension without the texels `drop` (`Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        EdgeExtension or None
        """
        rest = self.extension.without(drop)
        return None if rest is None else EdgeExtension(rest)


@dataclass(frozen=True, eq=False)
class SkyTexture:
    """The camera view's unseen sky given the plate's texture (sky_texture.py), over the
    prior the fill wrote there.

    Attributes
    ----------
    extension : extension.Extension
        The sky texels' samples of the pyramid, read without a fade.
    weight : (n,) float32 ndarray
        Their weights in the log-average, in its order: solid angle times `fade`, summing to 1.
    fade : (n,) float32 ndarray
        The texture's weight w per texel (1 up to the plate's highest elevation, fading out
        above it).
    contrast : float
        Params.sky_texture.
    """

    extension: Extension
    weight: np.ndarray
    fade: np.ndarray
    contrast: float
    plate_level0 = False

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """The prior times the plate's texture (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        modulate(
            self.extension, self.weight, self.fade, self.contrast, frame.pyramid,
            frame.shapes, frame.offsets, out, scratch("sky texture", out.shape),
        )  # fmt: skip

    def without(self, drop: np.ndarray) -> SkyTexture | None:
        """This texture without the texels `drop` (`Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        SkyTexture or None
        """
        keep = ~drop[self.extension.texels]
        rest = self.extension.without(drop)
        if rest is None:
            return None
        weight, fade = self.weight[keep] / self.weight[keep].sum(), self.fade[keep]
        for array in (weight, fade):
            array.flags.writeable = False
        return SkyTexture(rest, weight, fade, self.contrast)


@dataclass(frozen=True, eq=False)
class Supersamples:
    """The camera view's seen texels: the mean of n x n bilinear samples each, level 0 read
    from the plate itself (supersample.py).

    Attributes
    ----------
    samples : supersample.Supersample
    """

    samples: Supersample
    plate_level0 = False

    def write(self, frame: Frame, out: np.ndarray) -> None:
        """The seen texels (`Layer.write`).

        Parameters
        ----------
        frame : Frame
        out : (h w, 3) float32 ndarray
        """
        rows = np.ascontiguousarray(frame.plate, np.float32).reshape(-1, 3)
        gather_supersample(self.samples, frame.source, out, plate=rows)

    def without(self, drop: np.ndarray) -> Supersamples | None:
        """These samples without the texels `drop` (`Layer.without`).

        Parameters
        ----------
        drop : (h w,) bool ndarray

        Returns
        -------
        Supersamples or None
        """
        rest = self.samples.without(drop)
        return Supersamples(rest) if rest.texels.size else None
