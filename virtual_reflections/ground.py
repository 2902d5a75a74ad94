"""The ground method: the camera view, with the ground the object stands on seen from the
object (parallax).

The distant model (camera_view.py) treats everything as infinitely far: a direction from the
object reads the plate where the *camera* sees that direction. Half of what a mirror object
on the ground shows is the ground around it, a few metres away, which the plate does see, but
at another place. With the ground plane known (the add-on knows the camera and the scene), a
direction d from the object's centre O (camera frame, docs/conventions.md) that points down
meets the ground at

    P = O + t d,  t = -height / (up . d)   (up . d < 0; height: O above the ground plane)

and the plate shows P at the camera's projection of P (pinhole intrinsics fx, fy, cx, cy):

    px = cx - fx P.x / P.z,  py = cy - fy P.y / P.z   (P.z > 0).

Those texels are filtered over their footprint as the seen texels of the camera view are: the
mean of n x n bilinear samples (n = SAMPLES) at the ground points of n x n directions spread
over the texel, on the mip level where the samples are 2-4 pixels apart.
Where the ground point leaves the plate (behind the camera, beyond a border) the ground fades,
over `MARGIN` of the plate's height past the border, into the fill (by elevation above the
world's horizon, `Params.up`), so there is no seam; texels whose ground point is behind the
camera, or that point up, are the camera view's as before.

The object's contact shadow: the plate was shot without the object, so the ground it shows is
lit as if the object were not there. In the render the object hides part of the sky from the
ground around it. The object taken as a sphere of radius r (`Params.ground`'s fifth value,
else `height`: resting on the ground) at the map's origin, a ground point at distance
t = height / sin(b) along d (b its angle below the horizon) sees it under the form factor
(r / t)^2 cos = (r / height)^2 sin(b)^3; the ground's taps are weighted by the sky left,
1 - that (`sky_left`), under an even sky (the per-shading-point lookup does the same with the
object's box, operators/node_trees/ground_nodes.py). The artist can weaken it
(`Params.ground`'s sixth value, the panel's Contact Shadow: the hidden share times it), for
a plate that already shows the object's shadow.

What it does not model: the object's shadow from a directional light (a sun), things standing
on the ground (they are read where the camera sees them, as part of the ground), and the
ground hidden from the camera by something in front of it.
"""

from __future__ import annotations

import numpy as np

from .layouts import directions_at
from .seen_texels import mean_taps, supersample_levels

MARGIN = 0.25  # plate heights past the border over which the ground fades into the fill
SAMPLES = 2  # n: n x n bilinear samples over a ground texel's footprint (16 taps)


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def ground_points(directions, ground, up):
    """Where rays from the object along (..., 3) camera-frame ``directions`` meet the ground:
    ((..., 3) float64 points in the camera frame, (...,) bool: the ray goes down and meets it
    in front of the camera)."""
    d = np.asarray(directions, np.float64)
    o = np.asarray(ground[:3], np.float64)
    height = float(ground[3])
    u = _unit(up)
    down = d @ u
    hits = down < -1e-9
    t = np.where(hits, -height / np.where(hits, down, -1.0), 0.0)
    points = o + t[..., None] * d
    return points, hits & (points[..., 2] > 1e-6)


def sky_left(sine_below, ground):
    """(...,) float32: the share of an even sky that a sphere at the map's origin (``ground``:
    Params.ground) leaves a ground point seen from there at an angle b below the horizon
    (``sine_below`` = sin b): 1 - k min(1, (r / height)^2 sin(b)^3) (the module's docstring),
    k the shadow's strength (``ground``'s sixth value, default 1)."""
    height = float(ground[3])
    radius = float(ground[4]) if len(ground) > 4 else height
    strength = float(ground[5]) if len(ground) > 5 else 1.0
    s = np.clip(np.asarray(sine_below, np.float64), 0.0, 1.0)
    hidden = np.minimum((radius / height) ** 2 * s**3, 1.0)
    return (1.0 - strength * hidden).astype(np.float32)


def ground_pixels(directions, ground, up, intrinsics):
    """((...,) px, (...,) py, (...,) bool valid): the plate positions of the ground points of
    ``directions`` (continuous plate pixels; meaningless where not valid)."""
    fx, fy, cx, cy = intrinsics
    points, valid = ground_points(directions, ground, up)
    z = np.where(valid, points[..., 2], 1.0)
    return cx - fx * points[..., 0] / z, cy - fy * points[..., 1] / z, valid


def ground_weight(px, py, valid, width, height, margin=MARGIN):
    """(...,) float32 weight of the ground: 1 where its point is on the plate, falling with a
    smoothstep to 0 at ``margin`` plate heights past the nearest border; 0 where not valid."""
    outside = np.maximum.reduce([np.zeros_like(px), -px, px - width, -py, py - height]) / max(
        margin * height, 1e-9
    )
    t = np.clip(outside, 0.0, 1.0)
    w = 1.0 - t * t * (3.0 - 2.0 * t)
    return np.where(valid, w, 0.0).astype(np.float32)


def ground_taps(
    layout, size, directions, ground, up, intrinsics, width, height, shapes, offsets, first, last
):
    """The ground's part of a table: (ids (G,) int64 texels whose ground point the plate shows or
    nearly, weight (G,) float32 of the ground in them (`ground_weight`), index (G, 4 n^2) int32
    and taps' weights (G, 4 n^2) float32 summing to the sky left (`sky_left`): n x n bilinear
    samples over the texel's footprint on the ground, on mip levels ``first`` .. ``last``)."""
    px, py, valid = ground_pixels(directions, ground, up, intrinsics)
    weight = ground_weight(px, py, valid, width, height)
    ids = np.flatnonzero(weight > 0)
    taps = 4 * SAMPLES**2
    if not ids.size:
        return ids, weight[ids], np.empty((0, taps), np.int32), np.empty((0, taps), np.float32)
    centre = (np.clip(px[ids], 0, width), np.clip(py[ids], 0, height))
    # The ground points of n x n directions spread over each texel; a sample whose ray misses
    # the ground (the texel straddles the horizon) reads the centre's; all held on the plate.
    positions = []
    for sy in range(SAMPLES):
        for sx in range(SAMPLES):
            d = directions_at(
                layout, size, ids, (sx + 0.5) / SAMPLES - 0.5, (sy + 0.5) / SAMPLES - 0.5
            )
            x, y, ok = ground_pixels(d, ground, up, intrinsics)
            positions.append(
                (
                    np.clip(np.where(ok, x, centre[0]), 0, width),
                    np.clip(np.where(ok, y, centre[1]), 0, height),
                )
            )
    # The footprint: the samples' spread, scaled from their span (1 - 1/n of the texel) to the
    # whole texel, never under a pixel.
    xs = np.stack([p[0] for p in positions])
    ys = np.stack([p[1] for p in positions])
    grow = SAMPLES / max(SAMPLES - 1, 1)
    span = np.maximum(np.ptp(xs, 0), np.ptp(ys, 0)) * grow
    rect = np.stack((np.zeros_like(span), np.maximum(span, 1.0), np.zeros_like(span), span))
    level = np.clip(supersample_levels(rect, shapes, SAMPLES), first, last).astype(np.int32)
    index, taps_weight = mean_taps(positions, level, shapes, offsets)
    d = np.asarray(directions[ids], np.float64)
    sine = -(d @ _unit(up)) / np.linalg.norm(d, axis=-1)
    taps_weight *= sky_left(sine, ground)[:, None]
    return ids, weight[ids], index, taps_weight


def ground_taps_latlong(size, ground, up, intrinsics, width, height, shapes, offsets, first, last):
    """`ground_taps` for a lat-long map of width ``size``, from the ground points of the texel
    corners alone: one grid of (size / 2 + 1) x (size + 1) rays (directions from separable
    sines and cosines, no per-texel trigonometry), each texel's n x n samples interpolated
    bilinearly between its four corners' plate positions and its footprint their extent. A
    texel counts as ground when the rays through all four corners meet the ground in front of
    the camera; its weight (`ground_weight`) is taken at the mean of the corners."""
    h = size // 2
    lat = -np.pi * (np.arange(h + 1, dtype=np.float64) / h - 0.5)
    lon = -2.0 * np.pi * (np.arange(size + 1, dtype=np.float64) / size - 0.5)
    cos_lat, sin_lat = np.cos(lat)[:, None], np.sin(lat)[:, None]
    sin_lon, cos_lon = np.sin(lon)[None, :], np.cos(lon)[None, :]
    u = _unit(up)
    o = np.asarray(ground[:3], np.float64)
    fx, fy, cx, cy = intrinsics
    # Corner rays: d = (sin lon cos lat, sin lat, cos lon cos lat); down = u . d.
    dx, dz = sin_lon * cos_lat, cos_lon * cos_lat
    down = u[0] * dx + u[1] * sin_lat + u[2] * dz
    hits = down < -1e-9
    t = np.where(hits, -float(ground[3]) / np.where(hits, down, -1.0), 0.0)
    pz = o[2] + t * dz
    ok = hits & (pz > 1e-6)
    pz = np.where(ok, pz, 1.0)
    px = cx - fx * (o[0] + t * dx) / pz
    py = cy - fy * (o[1] + t * sin_lat) / pz
    # Texels: all four corners on the ground.
    valid = ok[:-1, :-1] & ok[1:, :-1] & ok[:-1, 1:] & ok[1:, 1:]
    corners = [
        (px[a : a + h, b : b + size], py[a : a + h, b : b + size]) for a in (0, 1) for b in (0, 1)
    ]
    mx = 0.25 * sum(c[0] for c in corners)
    my = 0.25 * sum(c[1] for c in corners)
    weight = ground_weight(mx, my, valid, width, height)
    ids = np.flatnonzero(weight > 0)
    taps = 4 * SAMPLES**2
    if not ids.size:
        return (
            ids,
            weight.ravel()[ids],
            np.empty((0, taps), np.int32),
            np.empty((0, taps), np.float32),
        )
    (x00, y00), (x01, y01), (x10, y10), (x11, y11) = (
        (c[0].ravel()[ids], c[1].ravel()[ids]) for c in corners
    )
    positions = []
    for sy in range(SAMPLES):
        b = (sy + 0.5) / SAMPLES
        for sx in range(SAMPLES):
            a = (sx + 0.5) / SAMPLES
            x = (1 - b) * ((1 - a) * x00 + a * x01) + b * ((1 - a) * x10 + a * x11)
            y = (1 - b) * ((1 - a) * y00 + a * y01) + b * ((1 - a) * y10 + a * y11)
            positions.append((np.clip(x, 0, width), np.clip(y, 0, height)))
    xs = np.stack((x00, x01, x10, x11))
    ys = np.stack((y00, y01, y10, y11))
    span = np.maximum(np.ptp(np.clip(xs, 0, width), 0), np.ptp(np.clip(ys, 0, height), 0))
    rect = np.stack((np.zeros_like(span), np.maximum(span, 1.0), np.zeros_like(span), span))
    level = np.clip(supersample_levels(rect, shapes, SAMPLES), first, last).astype(np.int32)
    index, taps_weight = mean_taps(positions, level, shapes, offsets)
    corner_down = [down[a : a + h, b : b + size].ravel()[ids] for a in (0, 1) for b in (0, 1)]
    taps_weight *= sky_left(-0.25 * sum(corner_down), ground)[:, None]
    return ids, weight.ravel()[ids], index, taps_weight
