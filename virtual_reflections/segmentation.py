"""The paper's segmentation of the plate (§3.1–3.2) from the object's bounding box.

Plate coordinates are continuous: the plate covers [0, W] x [0, H], origin at the top-left,
x to the right, y *down*; pixel (px, py) has its centre at (px + 0.5, py + 0.5).

Regions (paper Fig. 2b, 3a):
- X, the back face: the object's box enlarged by `enlarge`, kept `border` away from every
  edge (so near a border X can be smaller than the box), never empty.
- The inner boundary of F (`inner`) bisects the distance between X and the image border.
- L, R, T, B: the trapezoids between X and `inner` -> the side faces.
- F_L, F_R, F_T, F_B: the trapezoids between `inner` and the image border -> the front face.
- The object's centre lines (`centre`) split the side regions: left/right faces at the
  centre row, top/bottom faces at the centre column, so what is left of the object
  reflects on its left.
"""

from __future__ import annotations

from dataclasses import dataclass

from .params import Params


@dataclass(frozen=True)
class Rect:
    """An axis-aligned rectangle in continuous plate coordinates (origin top-left, y down).

    Attributes
    ----------
    x0, y0, x1, y1 : float
        The left, top, right and bottom edges in plate pixels.
    width, height : float
        x1 - x0 and y1 - y0.
    """

    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        return self.y1 - self.y0


@dataclass(frozen=True)
class Segmentation:
    """The paper's regions for one object on a W x H plate (Fig. 2b, 3a).

    Attributes
    ----------
    width, height : int
        The plate's size in pixels.
    bbox : Rect
        The object's bounds as given.
    x : Rect
        Region X, the back face.
    inner : Rect
        The inner boundary of the outer ring F.
    centre : tuple of 2 floats
        (cx, cy), the object's centre lines, kept strictly inside X.
    shrunk : bool
        True where X had to be made smaller than the object's box (near a border).
    """

    width: int
    height: int
    bbox: Rect
    x: Rect
    inner: Rect
    centre: tuple[float, float]
    shrunk: bool


def _region_x_1d(lo: float, hi: float, size: float, enlarge: float, border: float):
    """One axis of region X: enlarged, kept `border` from the edges, never empty."""
    margin, keep = enlarge * size, border * size
    a, b = max(lo - margin, keep), min(hi + margin, size - keep)
    room = size - 2.0 * keep  # > 0 since border < 0.5
    least = min(max(2.0 * margin, 1.0), room)
    if b - a < least:  # box tiny, or outside the allowed band: a small X near the object
        c = min(max(0.5 * (lo + hi), keep + 0.5 * least), size - keep - 0.5 * least)
        a, b = c - 0.5 * least, c + 0.5 * least
    centre = min(max(0.5 * (lo + hi), a + 0.1 * (b - a)), b - 0.1 * (b - a))
    shrunk = a > lo or b < hi
    return a, b, centre, shrunk


def segment(width: int, height: int, bbox, params: Params = Params()) -> Segmentation:
    """Cut a plate into the paper's regions around an object's bounds (§3.2).

    Parameters
    ----------
    width, height : int
        The plate's size in pixels (at least 1 each).
    bbox : sequence of 4 floats
        (x0, y0, x1, y1) in plate pixels (origin top-left, y down, x1/y1 exclusive); it may
        reach outside the plate or have zero area, but x0 <= x1 and y0 <= y1.
    params : Params, optional
        Its `enlarge` and `border` are read.

    Returns
    -------
    Segmentation

    Raises
    ------
    ValueError
        An empty plate, a box that is not finite or has x0 > x1 or y0 > y1.
    """
    if width < 1 or height < 1:
        raise ValueError(f"the plate is empty ({width}x{height} pixels)")
    x0, y0, x1, y1 = (float(v) for v in bbox)
    if not all(abs(v) < 1e12 for v in (x0, y0, x1, y1)):
        raise ValueError(f"bounding box is not finite: {bbox}")
    if x0 > x1 or y0 > y1:
        raise ValueError(f"bounding box must have x0 <= x1 and y0 <= y1, got {bbox}")
    ax, bx, cx, shrunk_x = _region_x_1d(x0, x1, width, params.enlarge, params.border)
    ay, by, cy, shrunk_y = _region_x_1d(y0, y1, height, params.enlarge, params.border)
    inner = Rect(0.5 * ax, 0.5 * ay, 0.5 * (bx + width), 0.5 * (by + height))
    return Segmentation(
        width=int(width),
        height=int(height),
        bbox=Rect(x0, y0, x1, y1),
        x=Rect(ax, ay, bx, by),
        inner=inner,
        centre=(cx, cy),
        shrunk=shrunk_x or shrunk_y,
    )
