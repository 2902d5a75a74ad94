"""The camera view's fill (camera_view.py): what the plate says of the directions it does not
show, a robust average of the plate by elevation and side (in the camera frame).

Per elevation: the log-average (per channel) of the plate pixels within `fill_width` degrees of
the texel's elevation, the window's centre held inside the plate's own range of elevations, so
near the horizon it is the rows at that elevation and above or below the plate the top or bottom
band; beyond the plate the window widens by `fill_spread` degrees per degree, so far from the
plate the fill tends to the whole plate's. A log-average because a sun or a lit window in view
makes a plain mean far too bright for the directions that show neither; but a log-average is
darker than the light the plate holds, so it is brightened toward the arithmetic mean's luminance
by `fill_energy` (0.5: the geometric mean of the two). Per side (`fill_sides`): the plate's left
half gives the profile for the left, its right half for the right (`side_weight`: ahead of the
camera by the azimuth up to the plate's edges, behind it returning to an even blend straight
behind); both share the band's brightness, so only their colour differs, and `fill_saturation`
desaturates the tint they share while keeping the difference between them. With a world horizon
(`up`), the profile above it is a sky prior alone (`sky_share`, `fill_profile`'s `sky_gain`;
docs/scenes3d.md).

The profile is built per frame (`fill_profile`) from a coarse mip level (`fill_level`); a table
keeps, per texel, only where to read it: taps (`fill_taps`) or, on a lat-long, one elevation
step per texel or per row (`fill_bins_latlong`, read by `fill_lookup` and `fill_values`).
"""

from __future__ import annotations

import math

import numpy as np

from .parallel import chunks
from .params import AUTO_SKY_GAIN, SKY_GAINS
from .products import matmul

FILL_BINS = 181  # the fill profile: 1-degree bins of camera-frame elevation, -90 .. 90


FILL_ROWS = 96  # the fill is computed on the first mip level at most this many rows high


def fill_level(shapes) -> int:
    """The mip level the fill is computed on: the first at most FILL_ROWS rows high.

    Parameters
    ----------
    shapes : sequence of (h, w)
        The pyramid's level shapes (`mipmap.level_shapes`), finest first.

    Returns
    -------
    int
    """
    for i, (h, _) in enumerate(shapes):
        if h <= FILL_ROWS:
            return i
    return len(shapes) - 1


def elevation_deg(directions, up=None) -> np.ndarray:
    """Elevation in degrees of (..., 3) directions above the horizon whose normal is ``up``
    (camera frame), or above the camera's own horizontal plane (up = +Y) without one."""
    d = np.asarray(directions, np.float64)
    norm = np.sqrt(np.einsum("...i,...i->...", d, d))
    norm = np.where(norm > 0, norm, 1.0)
    if up is None:
        height = d[..., 1]
    else:
        u = np.asarray(up, np.float64)
        height = d @ (u / np.linalg.norm(u))
    return np.degrees(np.arcsin(np.clip(height / norm, -1.0, 1.0)))


def sky_in_view(intrinsics, width: int, height: int, up) -> float:
    """The share of the plate's rows whose highest point is above the world's horizon.

    0 when the camera sees no sky at all (ground and walls only): the fill's sky is then the prior
    alone (`fill_profile`'s `sky_gain`). A row's elevation is highest at one of its ends, so only
    the ends are tested.

    Parameters
    ----------
    intrinsics : (fx, fy, cx, cy)
        The plate camera in plate pixels.
    width, height : int
        The plate's size in pixels.
    up : (x, y, z)
        The horizon's normal in the camera frame.

    Returns
    -------
    float
        0..1.
    """
    fx, fy, cx, cy = intrinsics
    rows = np.arange(height) + 0.5
    ends = [
        np.stack((np.full_like(rows, -(x - cx) / fx), -(rows - cy) / fy, np.ones_like(rows)), -1)
        for x in (0.0, float(width))
    ]
    above = (elevation_deg(ends[0], up) > 0) | (elevation_deg(ends[1], up) > 0)
    return float(above.mean()) if height > 0 else 0.0


def fill_geometry(
    shape,
    level: int,
    intrinsics,
    width_deg: float,
    spread: float = 0.0,
    sides: int = 1,
    up=None,
):
    """What the fill needs of a plate's geometry at one mip level.

    A profile bin's window is the bins within `width_deg` of its elevation, its centre held
    `width_deg` inside the plate's own elevations (above the plate: the top band; below: the
    bottom band), widening by `spread` degrees per degree beyond.

    Parameters
    ----------
    shape : (h, w)
        The level's shape.
    level : int
        The mip level (the level's pixels are 2**level plate pixels wide).
    intrinsics : (fx, fy, cx, cy)
        The plate camera in plate pixels.
    width_deg : float
        Half-width of the elevation window (`Params.fill_width`).
    spread : float, optional
        `Params.fill_spread`.
    sides : {1, 2}, optional
        2: the plate's left and right halves give separate profiles.
    up : (x, y, z), optional
        The horizon's normal in the camera frame; None: the camera's own, +Y.

    Returns
    -------
    bins : (h * w,) int64 ndarray
        Each pixel's 1-degree elevation bin, plus FILL_BINS x its side (0: the plate's left
        half, 1: its right half; with `sides` = 1 every pixel is side 0).
    window : (sides, 2, FILL_BINS) int64 ndarray
        For every side and bin of the profile, the half-open range [lo, hi) of bins it averages.
    counts : (sides, FILL_BINS + 1) float64 ndarray
        Cumulative pixel counts per elevation bin.
    """
    fx, fy, cx, cy = intrinsics
    h, w = shape
    s = 2.0**level
    py, px = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = -((px + 0.5) * s - cx) / fx, -((py + 0.5) * s - cy) / fy
    elevation = elevation_deg(np.stack((dx, dy, np.ones_like(dx)), -1), up).ravel()
    ebin = np.clip(np.rint(elevation + 90.0), 0, FILL_BINS - 1).astype(np.int64)
    if sides == 2:
        side = ((px + 0.5) * s >= cx).ravel().astype(np.int64)  # 0: left (+X), 1: right
    else:
        side = np.zeros(ebin.size, np.int64)
    windows, counts = [], []
    for k in range(sides):
        mine = side == k
        if not mine.any():  # a plate one pixel wide: both sides are the whole plate
            mine = np.ones(ebin.size, bool)
        b, e = ebin[mine], elevation[mine]
        count = np.concatenate(([0.0], np.cumsum(np.bincount(b, minlength=FILL_BINS))))
        lo_e, hi_e = e.min() + width_deg, e.max() - width_deg
        centre = np.arange(FILL_BINS) - 90.0
        centre = (
            np.clip(centre, lo_e, hi_e) if lo_e <= hi_e else np.full(FILL_BINS, 0.5 * (lo_e + hi_e))
        )
        half = width_deg + spread * np.abs(np.arange(FILL_BINS) - 90.0 - centre)
        lo = np.clip(np.rint(centre - half + 90.0), 0, FILL_BINS - 1).astype(np.int64)
        hi = np.clip(np.rint(centre + half + 90.0), 0, FILL_BINS - 1).astype(np.int64) + 1
        # Never an empty window: widen to the nearest bins that hold pixels.
        empty = count[hi] - count[lo] <= 0
        if empty.any():
            lo[empty], hi[empty] = b.min(), b.max() + 1
        windows.append(np.stack((lo, hi)))
        counts.append(count)
    bins = ebin + FILL_BINS * side
    return bins, np.stack(windows), np.stack(counts)


REC709_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


HORIZON_BIN = 90  # the bin of elevation 0: bins above it look above the horizon
# The sky prior's level is the plate's GROUND_BAND_DEG (degrees below the world's horizon), as
# study/sky_prior.py measures each HDRI's lower hemisphere to derive the gain; the whole plate
# when under MIN_GROUND_SHARE of it lies in that band (a camera looking up).
GROUND_BAND_DEG = (5.0, 40.0)
MIN_GROUND_SHARE = 0.05


def sky_share(sides: int) -> np.ndarray:
    """(sides * FILL_BINS,) float32: how much of each bin's fill is the plate's (elevations
    from the world's horizon, `fill_geometry` with `up`): 1 at and below the horizon, 0 above
    it, where `fill_profile` puts the sky prior alone. The plate's own sky shows where the
    plate sees it (the camera view's texels); continued behind the camera, per elevation, it
    was mostly the skyline, trees and neighbours the plate shows just above the horizon —
    darker than the sky above and behind the camera — and the prior, derived for the whole
    upper hemisphere, predicts that better (docs/scenes3d.md, "The unseen sky")."""
    out = np.ones((sides, FILL_BINS), np.float32)
    out[:, HORIZON_BIN + 1 :] = 0.0
    return out.ravel()


def fill_profile(
    level_pixels: np.ndarray,
    bins,
    window,
    counts,
    saturation: float = 1.0,
    out=None,
    energy: float = 0.0,
    sky=None,
    sky_gain: float = 1.0,
    sky_tint=None,
    sky_from_plate: float = 0.0,
    sky_tint_share: float = 0.0,
) -> np.ndarray:
    """The fill (sides * FILL_BINS, 3) float32 of one frame, sides = len(window): per side and
    elevation bin the log-average (per channel) of the pixels `level_pixels` (h, w, 3) in its
    window (see fill_geometry), brightened toward the arithmetic mean's luminance by `energy`
    (0: the log-average, robust but darker than the light the plate holds; 1: the mean's
    luminance; between: their geometric blend), its colour kept by `saturation` (0: grey of
    the same luminance).

    With two sides (the plate's left and right halves), both share the band's brightness (the
    mean of their R, G, B means) and differ only in colour: `saturation` then desaturates what
    they share and keeps the difference between them (a plate red on the left and blue on the
    right stays red on the left).

    `sky` ((sides * FILL_BINS,) from `sky_share`): where under 1, the bin is blended toward a
    neutral sky `sky_gain` times as bright as the whole plate (its log-average brightened by
    `energy` as above); with `sky_share`, every bin above the horizon is that sky alone
    (docs/scenes3d.md, "The unseen sky"). `sky_tint` (R, G, B; None: neutral) colours that sky,
    its luminance kept. `sky_from_plate` and `sky_tint_share`: `sky_prior`'s.
    """
    sides = window.shape[0]
    size = sides * FILL_BINS
    pixels = np.maximum(level_pixels.reshape(-1, 3), 0.0)
    eps = 1e-3 * pixels.mean(0) + 1e-12  # scale-free: black pixels count as 1/1000 of the mean
    logs = np.log(pixels + eps)
    out = np.empty((size, 3), np.float32) if out is None else out
    # Per channel, the sums of the logs (and of the pixels) in every bin of every side, once.
    sums = [
        [np.bincount(bins, source[:, c], size) for c in range(3)]
        for source in ((logs, pixels) if energy > 0 else (logs,))
    ]
    for k in range(sides):
        lo, hi = window[k]
        n = counts[k][hi] - counts[k][lo]
        rows = slice(k * FILL_BINS, (k + 1) * FILL_BINS)
        mean = np.empty((FILL_BINS, 3), np.float64)
        for c in range(3):
            for per_bin, target in zip(sums, (out, mean)):
                total = np.concatenate(([0.0], np.cumsum(per_bin[c][rows])))
                target[rows if target is out else slice(None), c] = (total[hi] - total[lo]) / n
            out[rows, c] = np.exp(out[rows, c]) - eps[c]
        if energy > 0:
            ratio = np.maximum(mean @ REC709_LUMA, 1e-30) / np.maximum(
                out[rows] @ REC709_LUMA, 1e-30
            )
            out[rows] *= (ratio**energy)[:, None].astype(np.float32)
    np.maximum(out, 0.0, out=out)
    if sides == 2:
        left, right = out[:FILL_BINS], out[FILL_BINS:]
        shared = 0.5 * (left.mean(1) + right.mean(1))[:, None]
        left *= shared / np.maximum(left.mean(1), 1e-30)[:, None]
        right *= shared / np.maximum(right.mean(1), 1e-30)[:, None]
        if saturation != 1.0:
            common = 0.5 * (left + right)
            luma = (common @ REC709_LUMA)[:, None]
            shift = np.float32(saturation - 1.0) * (common - luma)
            np.maximum(left + shift, 0.0, out=left)
            np.maximum(right + shift, 0.0, out=right)
    elif saturation != 1.0:
        luma = (out @ REC709_LUMA)[:, None]
        out[:] = luma + np.float32(saturation) * (out - luma)
    if sky is not None and (sky < 1).any():
        prior = sky_prior(pixels, bins, energy, sky_gain, sky_tint, sky_from_plate, sky_tint_share)
        share = sky[:, None]
        out[:] = share * out + (1.0 - share) * prior
    return out


def sky_prior(pixels, bins, energy, gain, tint=None, from_plate=0.0, share=0.0) -> np.ndarray:
    """The sky prior's colour: where the plate does not show the sky (`fill_profile`).

    Parameters
    ----------
    pixels : (n, 3) float32 ndarray
        The fill's mip level, scene-linear, >= 0.
    bins, energy
        As for `prior_level`.
    gain : float
        `Params.sky_gain`: times the level.
    tint : (r, g, b) or None
        `Params.sky_tint`, its luminance taken out.
    from_plate : float
        `Params.sky_from_plate`, the level's source: 0, `prior_level` (the ground near the
        horizon); 1, the whole plate's mean luminance, each pixel clipped at 1 (display white:
        a sun or a lamp in an HDR plate counts as white), over AUTO_SKY_GAIN where the plate
        shows no ground (a camera looking up: the plate is the sky, as `prior_level`'s);
        between, a geometric blend.
    share : float
        `Params.sky_tint_share`: how far the colour goes from grey to the plate mean's hue.

    Returns
    -------
    (3,) float32 ndarray
    """
    if from_plate <= 0.0 and share <= 0.0:  # the ground band's neutral sky
        return np.float32(gain * prior_level(pixels, bins, energy)) * tint_colour(tint)
    mean = np.minimum(pixels.reshape(-1, 3), 1.0).mean(0, dtype=np.float64)
    level = float(mean @ REC709_LUMA)
    hue = mean / level if level > 1e-30 else np.ones(3)
    if not shows_ground(bins):
        level /= AUTO_SKY_GAIN
    if from_plate < 1.0:
        ground = prior_level(pixels, bins, energy)
        level = max(level, 1e-30) ** from_plate * max(ground, 1e-30) ** (1.0 - from_plate)
    colour = (1.0 - share) + share * hue
    return np.float32(gain * level) * colour.astype(np.float32) * tint_colour(tint)


def tint_colour(tint) -> np.ndarray:
    """A colour scaled to luminance 1 (Rec.709).

    Parameters
    ----------
    tint : (r, g, b) or None
        Linear, not black; None: neutral.

    Returns
    -------
    (3,) float32 ndarray
    """
    if tint is None:
        return np.ones(3, np.float32)
    colour = np.asarray(tint, np.float32)
    return colour / np.float32(max(float(colour @ REC709_LUMA), 1e-30))


def prior_level(level_pixels: np.ndarray, bins: np.ndarray, energy: float = 0.0) -> float:
    """The sky prior's level at gain 1 (`fill_profile`), from the plate's ground.

    `sky_level` of the pixels GROUND_BAND_DEG below the horizon, the band the gain was derived on.
    Under MIN_GROUND_SHARE of the plate there (a camera looking up): the whole plate's level over
    Auto's mirror gain (SKY_GAINS["auto"]; docs/scenes3d.md, "Where it fails").

    Parameters
    ----------
    level_pixels : (..., 3) float32 ndarray
        The fill's mip level, scene-linear.
    bins : ndarray
        Their elevation bins (`fill_geometry` with `up`).
    energy : float, optional
        `Params.fill_energy`: the log-average brightened toward the mean's luminance.

    Returns
    -------
    float
    """
    pixels = level_pixels.reshape(-1, 3)
    band = ground_band(bins)
    if band.mean() >= MIN_GROUND_SHARE:
        return sky_level(pixels[band], energy)
    return sky_level(pixels, energy) / SKY_GAINS["auto"]


def ground_band(bins: np.ndarray) -> np.ndarray:
    """Which of the fill's pixels lie GROUND_BAND_DEG below the world's horizon.

    Parameters
    ----------
    bins : ndarray
        Their elevation bins (`fill_geometry` with `up`).

    Returns
    -------
    bool ndarray
    """
    below = HORIZON_BIN - bins % FILL_BINS  # degrees below the horizon (1-degree bins)
    return (below >= GROUND_BAND_DEG[0]) & (below <= GROUND_BAND_DEG[1])


def shows_ground(bins: np.ndarray) -> bool:
    """Whether MIN_GROUND_SHARE of the fill's pixels lie in the ground band (not a camera
    looking up).

    Parameters
    ----------
    bins : ndarray
        As for `ground_band`.

    Returns
    -------
    bool
    """
    return bool(ground_band(bins).mean() >= MIN_GROUND_SHARE)


def sky_level(level_pixels: np.ndarray, energy: float = 0.0) -> float:
    """The sky prior's level at gain 1 (`fill_profile`): the log-average luminance of the
    pixels `level_pixels` (..., 3), brightened toward their mean's by `energy`."""
    pixels = np.maximum(level_pixels.reshape(-1, 3), 0.0)
    eps = 1e-3 * pixels.mean(0) + 1e-12
    luma = pixels @ REC709_LUMA
    level = math.exp(float(np.log(luma + float(eps @ REC709_LUMA)).mean()))
    if energy > 0:
        level *= (max(float(luma.mean()), 1e-30) / max(level, 1e-30)) ** energy
    return level


def side_weight(directions, intrinsics, width: int) -> np.ndarray:
    """(T,) float32 weight of the plate's left half in the fill of each camera-frame
    direction: 1 at and beyond the plate's left edge (azimuth), 0 at and beyond its right,
    0.5 straight ahead; behind the camera it returns linearly to 0.5 (straight behind: both
    halves alike)."""
    fx, _, cx, _ = intrinsics
    left, right = math.sin(math.atan(cx / fx)), math.sin(math.atan((width - cx) / fx))
    out = np.empty(len(directions), np.float32)
    for a, b in chunks(out.size):  # the sine of the azimuth without the trigonometry
        d = np.asarray(directions[a:b], np.float64)
        x, z = d[:, 0], d[:, 2]
        r = np.hypot(x, z)
        sin_az = np.divide(x, r, out=np.zeros_like(r), where=r > 0)
        ahead = sin_az / np.where(x >= 0, left, right)
        s = np.where(z >= 0, np.clip(ahead, -1.0, 1.0), sin_az)
        out[a:b] = 0.5 + 0.5 * s
    return out


def fill_taps(directions, base: int, side=None, up=None):
    """The taps (T, 2) int32 and their weights (T, 2) float32 that interpolate the fill
    profile (rows `base` .. `base` + FILL_BINS - 1 of the source) at each direction's elevation.
    With `side` ((T,) weight of the left half, `side_weight`): (T, 4) taps, the left profile's
    two and the right profile's (rows `base` + FILL_BINS ..), weighted by side and 1 - side.
    Elevations are above the horizon whose normal is `up` (None: the camera's own)."""
    count = len(directions)
    index = np.empty((count, 2 if side is None else 4), np.int32)
    weight = np.empty(index.shape, np.float32)
    for a, b in chunks(count):
        elevation = elevation_deg(directions[a:b], up).astype(np.float32)
        _taps_at(elevation, base, None if side is None else side[a:b], index[a:b], weight[a:b])
    return index, weight


FILL_STEPS = 64  # a lat-long's fill is read at elevations rounded to 1/64 of a bin


def fill_bins_latlong(size: int, up=None, rows=None, out=None):
    """Where the fill profile is read for the texel centres of a `size`-wide lat-long, rows
    `rows` (a slice; default all), texels row by row: (n,) uint16, the elevation in bins
    above -90 degrees times FILL_STEPS (rounded: 0.008 degrees at most), the compact form of
    `fill_taps` (whose side weight is the texel's column's). Without `up` a texel's elevation
    is its row's: then one value per row. `out`: (n,) uint16 to write into."""
    h = size // 2
    rows = range(h)[rows or slice(None)]
    el = -np.pi * ((np.arange(rows.start, rows.stop, rows.step) + 0.5) / h - 0.5)  # (n,)
    if up is None:  # one value per row
        steps = _steps(np.degrees(el).astype(np.float32))
    else:  # d . up = cos(el) (sin(az) ux + cos(az) uz) + sin(el) uy, d a unit vector
        ux, uy, uz = np.asarray(up, np.float64) / np.linalg.norm(up)
        az = -2.0 * np.pi * ((np.arange(size) + 0.5) / size - 0.5)
        across = (np.sin(az) * ux + np.cos(az) * uz).astype(np.float32)
        # A camera without roll (ux = 0) has its columns in mirrored pairs: the arcsines of
        # one half are the other's (taken only when the values agree exactly).
        half = size // 2
        mirrored = size % 2 == 0 and np.array_equal(across[:half], across[::-1][:half])
        cols = across[:half] if mirrored else across
        height = np.cos(el).astype(np.float32)[:, None] * cols
        height += np.float32(uy) * np.sin(el).astype(np.float32)[:, None]
        elevation = np.clip(height, -1.0, 1.0, out=height)
        np.arcsin(elevation, out=elevation)
        np.degrees(elevation, out=elevation)
        steps = _steps(elevation)
        if mirrored:  # the other half of the columns, mirrored
            steps = np.concatenate((steps, steps[:, ::-1]), axis=1)
    out = np.empty(steps.size, np.uint16) if out is None else out
    out[:] = steps.ravel()
    return out


def _steps(elevation: np.ndarray) -> np.ndarray:
    """float32 elevations in degrees (worked on in place) as `fill_bins_latlong`'s steps."""
    e = elevation
    e += np.float32(90.0)
    np.clip(e, 0, FILL_BINS - 1, out=e)
    e *= np.float32(FILL_STEPS)
    np.rint(e, out=e)
    return e


def fill_lookup(profile) -> np.ndarray:
    """The fill profile (sides, FILL_BINS, 3) float32 interpolated at every step of
    `fill_bins_latlong`: (sides, (FILL_BINS - 1) * FILL_STEPS + 1, 3) float32, per frame."""
    p = np.ascontiguousarray(profile, np.float32)
    sides = p.shape[0]
    out = np.empty((sides, (FILL_BINS - 1) * FILL_STEPS + 1, 3), np.float32)
    t = (np.arange(FILL_STEPS) * (1.0 / FILL_STEPS)).astype(np.float32)
    step = p[:, 1:] - p[:, :-1]  # (sides, FILL_BINS - 1, 3)
    # Steps last while computing (long inner loops), then into place.
    ramp = step[..., None] * t  # (sides, FILL_BINS - 1, 3, FILL_STEPS)
    ramp += p[:, :-1, :, None]
    out[:, :-1].reshape(sides, FILL_BINS - 1, FILL_STEPS, 3)[:] = ramp.transpose(0, 1, 3, 2)
    out[:, -1] = p[:, -1]
    return out


def fill_values(steps, side, lookup, out) -> None:
    """The fill at lat-long texels from the compact form: out (n, 3) float32 = `lookup`
    (`fill_lookup`) at each texel's steps (`fill_bins_latlong`; or one per row), the two
    sides blended by `side` ((3 W,) float32: the left side's weight per column, repeated for
    R, G, B; n a whole number of rows), or one side's (side None)."""
    if steps.size < out.shape[0]:  # one step per row: each row's colours by column
        left = np.take(lookup[0], steps, axis=0)  # (rows, 3)
        if side is None:
            out.reshape(steps.size, -1, 3)[:] = left[:, None]
            return
        right = np.take(lookup[1], steps, axis=0)
        # Rows of 3 W floats = left * side + right * (1 - side), per channel: one matrix
        # product (rows, 6) @ (6, 3 W) writes them in order (BLAS, in pieces over the cores).
        mix = np.zeros((6, side.size), np.float32)
        for c in range(3):
            mix[c, c::3] = side[c::3]
            mix[3 + c, c::3] = 1 - side[c::3]
        matmul(np.concatenate((left, right), axis=1), mix, out.reshape(steps.size, -1))
        return
    if side is None:
        np.take(lookup[0], steps, axis=0, out=out)
        return
    np.take(lookup[1], steps, axis=0, out=out)
    left = np.take(lookup[0], steps, axis=0)
    left -= out
    flat = left.reshape(-1, side.size)  # rows of 3 W floats: long inner loops
    flat *= side
    out += left


def _taps_at(elevation, base, side, index, weight) -> None:
    """Write the fill's taps and weights (see `fill_taps`) for (n,) float32 elevations in
    degrees into index (n, 2 or 4) int32 and weight (n, 2 or 4) float32."""
    e = np.clip(elevation + np.float32(90.0), 0, FILL_BINS - 1)
    b0 = np.minimum(np.floor(e), FILL_BINS - 2)
    frac = e - b0
    first = base + b0.astype(np.int32)
    index[:, 0], index[:, 1] = first, first + 1
    if side is None:
        weight[:, 0], weight[:, 1] = 1 - frac, frac
        return
    # Column by column: NumPy is slow on (n, 2) slices (its inner loop is 2 long).
    index[:, 2], index[:, 3] = first + FILL_BINS, first + (FILL_BINS + 1)
    side = np.asarray(side, np.float32)
    other = 1 - side
    low = 1 - frac
    np.multiply(low, side, out=weight[:, 0])
    np.multiply(frac, side, out=weight[:, 1])
    np.multiply(low, other, out=weight[:, 2])
    np.multiply(frac, other, out=weight[:, 3])
