"""The ground method's sky prior (Params.sky_gain, docs/ground.md): how many times brighter
than what a plate shows below the horizon the unseen sky should be taken to be.

For each of Blender's bundled HDRIs: the fill's brightness of its lower hemisphere (-5 to -40
degrees: the geometric mean of the log-average and the mean luminance, as the fill measures a
plate), and the error, in sRGB display values clipped at white and weighted by the cosine of
the elevation, of predicting its upper hemisphere (above 5 degrees) as a neutral grey `gain`
times that brightness. Prints each HDRI's own best gain, the gain that minimises the summed
error over the training HDRIs, and the error of that gain and of a neutral 1.0 on every HDRI;
then the gain of each kind of surroundings the artist can name in the panel (`KINDS`: open sky,
enclosed), derived the same way from the training HDRIs of that kind, and its error on the
held-out HDRIs of that kind (`SKY_GAINS` in virtual_reflections/params.py holds all three).

    python -m study sky-prior
"""

from __future__ import annotations

import numpy as np

from virtual_reflections.colour import linear_to_srgb
from virtual_reflections.fill import GROUND_BAND_DEG

from .evaluate import hdri_dir
from .panorama import load_equirect

TRAIN = ("city", "courtyard", "interior", "studio", "sunrise", "sunset")
# The kinds of surroundings (Params / SKY_GAINS): what an artist says of a shot. Open sky:
# outdoors, the sky over most of what stands around (streets, fields, a sunset); enclosed: a
# room, a studio, a yard walled in by buildings. Forest and night are held out (both open).
KINDS = {
    "open": ("city", "sunrise", "sunset", "forest", "night"),
    "enclosed": ("courtyard", "interior", "studio"),
}
GAINS = np.round(np.arange(0.1, 5.01, 0.1), 2)
LUMA = np.array([0.2126, 0.7152, 0.0722])


def errors(image) -> np.ndarray:
    """(len(GAINS),) display-value error of each gain for one equirectangular image."""
    rgb = image[..., :3]
    h, w = rgb.shape[:2]
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    weight = np.broadcast_to(np.cos(lat)[:, None], (h, w))
    lum = rgb @ LUMA
    up = lat > np.radians(5)
    near, far = GROUND_BAND_DEG  # the band the fill measures a plate's level on
    down = (lat < -np.radians(near)) & (lat > -np.radians(far))
    below, wd = lum[down], weight[down]
    log_average = np.exp((np.log(below + 1e-4) * wd).sum() / wd.sum())
    mean = (below * wd).sum() / wd.sum()
    level = log_average * (mean / log_average) ** 0.5
    target = linear_to_srgb(np.clip(rgb[up], 0, 1))
    wu = weight[up]
    out = []
    for gain in GAINS:
        grey = linear_to_srgb(np.clip(np.full(3, gain * level), 0, 1))
        out.append((((grey - target) ** 2).sum(-1) * wu).sum() / wu.sum())
    return np.array(out)


def best_index(per: dict, names) -> int:
    """The index in GAINS of the gain minimising the summed error over the HDRIs ``names``."""
    return int(np.argmin(sum(per[name] for name in names if name in per)))


def run() -> dict:
    """Print the tables; returns the gains: {"auto": the one chosen on the training HDRIs,
    "open": .., "enclosed": ..: each kind's from its training HDRIs}."""
    per = {p.stem: errors(load_equirect(str(p))) for p in sorted(hdri_dir().glob("*.exr"))}
    at = best_index(per, TRAIN)
    one = int(np.argmin(np.abs(GAINS - 1.0)))
    out = {"auto": float(GAINS[at])}
    print(f"gain minimising the summed error over {', '.join(TRAIN)}: {out['auto']:.1f}")
    print("| HDRI | used | own best gain | error at the chosen gain | error at 1.0 |")
    print("|---|---|---|---|---|")
    for name, e in per.items():
        used = "yes" if name in TRAIN else "held out"
        best = float(GAINS[int(np.argmin(e))])
        print(f"| {name} | {used} | {best:.1f} | {e[at]:.3f} | {e[one]:.3f} |")
    print()
    print("| surroundings | trained on | gain | held out: error at it / at the all-HDRI gain |")
    print("|---|---|---|---|")
    for kind, names in KINDS.items():
        train = [n for n in names if n in TRAIN]
        k = best_index(per, train)
        out[kind] = float(GAINS[k])
        held = [n for n in names if n not in TRAIN and n in per]
        checks = ", ".join(f"{n} {per[n][k]:.3f} / {per[n][at]:.3f}" for n in held) or "none"
        print(f"| {kind} | {', '.join(train)} | {out[kind]:.1f} | {checks} |")
    return out
