"""Compositing in NumPy: a render over its plate, pixel grids resized, boxes combined.

All arrays are scene-linear float32, top row first; boxes are (x0, y0, x1, y1) in plate
pixels (docs/conventions.md), x1/y1 exclusive.
"""

from __future__ import annotations

import numpy as np


def over(render_rgba: np.ndarray, plate: np.ndarray) -> np.ndarray:
    """Alpha-over a premultiplied render onto a plate.

    ``render.rgb + plate * (1 - render.alpha)``: Blender's Alpha Over node for a premultiplied
    foreground (its default) at factor 1.

    Parameters
    ----------
    render_rgba : (H, W, 4) ndarray
        Premultiplied RGBA, scene-linear.
    plate : (H, W, 3) ndarray
        Scene-linear, the render's size.

    Returns
    -------
    (H, W, 3) float32 ndarray

    Raises
    ------
    ValueError
        The render is not RGBA or the plate not RGB of the render's size.
    """
    render = np.asarray(render_rgba, dtype=np.float32)
    back = np.asarray(plate, dtype=np.float32)
    if render.ndim != 3 or render.shape[2] != 4:
        raise ValueError(f"the render must be (H, W, 4) RGBA, got shape {render.shape}")
    if back.ndim != 3 or back.shape[2] != 3 or back.shape[:2] != render.shape[:2]:
        raise ValueError(f"the plate must be (H, W, 3) like the render, got shape {back.shape}")
    out = back * (1.0 - render[..., 3:4])
    out += render[..., :3]
    return out


def nearest_rows(size: int, new_size: int) -> np.ndarray:
    """For each row (or column) of a resized image, the source row that holds its centre.

    Parameters
    ----------
    size : int
        Rows of the source.
    new_size : int
        Rows of the result.

    Returns
    -------
    (new_size,) int ndarray
    """
    return np.minimum(((np.arange(new_size) + 0.5) * size / new_size).astype(int), size - 1)


def resize_nearest(pixels: np.ndarray, height: int, width: int) -> np.ndarray:
    """Resize an image to the nearest pixel centres.

    Parameters
    ----------
    pixels : (H, W, C) ndarray
    height, width : int
        The new size.

    Returns
    -------
    (height, width, C) ndarray
        The array itself when the size is already right.
    """
    if pixels.shape[:2] == (height, width):
        return pixels
    ys, xs = nearest_rows(pixels.shape[0], height), nearest_rows(pixels.shape[1], width)
    return pixels[np.ix_(ys, xs)]


def union_box(boxes) -> tuple | None:
    """The smallest box holding every box given.

    Parameters
    ----------
    boxes : iterable of (x0, y0, x1, y1)

    Returns
    -------
    tuple of 4 floats or None
        None when there is no box.
    """
    boxes = [tuple(b) for b in boxes]
    if not boxes:
        return None
    return (
        min(b[0] for b in boxes),
        min(b[1] for b in boxes),
        max(b[2] for b in boxes),
        max(b[3] for b in boxes),
    )


def scale_box(box, sx: float, sy: float) -> tuple:
    """Scale a box's x and y (render -> plate pixels).

    Parameters
    ----------
    box : (x0, y0, x1, y1)
    sx, sy : float
        The scales of x and y.

    Returns
    -------
    tuple of 4 floats
    """
    x0, y0, x1, y1 = box
    return (x0 * sx, y0 * sy, x1 * sx, y1 * sy)
