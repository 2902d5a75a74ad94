"""How big a map an object needs: no more than its size on screen can show (issue 5, item 6).

A mirror sphere D pixels across turns its reflection by 4 / D radians per pixel at its centre
(twice the normal's turn), faster toward the rim; a lat-long W texels wide has 2π / W radians
per texel. Two texels per pixel at the centre (bilinear lookups, a renderer's many samples)
gives W = π D, rounded up to a power of two. The accuracy study measured the rule
(docs/accuracy.md, "Model no more than a scene needs"): the maps it picks render within
0.1 dB of a 2048-wide map against the truth, at 2-20 % of its cost. Below 256 even a tiny
sphere's render changes visibly (a supersampled pixel integrates more than its centre's
footprint), so 256 is the floor.
"""

from __future__ import annotations

import math

MIN_WIDTH = 256
MAX_WIDTH = 4096
WIDTHS = (256, 512, 1024, 2048, 4096)  # the lat-long widths an artist can choose


def auto_map_width(object_px: float, minimum: int = MIN_WIDTH, maximum: int = MAX_WIDTH) -> int:
    """The lat-long width for a curved object of a given size on screen (the module's rule).

    Parameters
    ----------
    object_px : float
        The object's size across on screen, in pixels.
    minimum, maximum : int, optional
        The width's bounds.

    Returns
    -------
    int
        A power of two from `minimum` to `maximum`.
    """
    want = max(float(object_px), 1.0) * math.pi
    return int(min(max(2 ** math.ceil(math.log2(want)), minimum), maximum))
