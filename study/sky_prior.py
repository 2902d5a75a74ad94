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

Then **rough surfaces**: a rough object reflects the sky blurred by its lobe, which carries a
sun's or a light's energy into the directions around it, so the grey that predicts what it
reflects is brighter than a mirror's. How much brighter is taken from a model in which the
ground is lit by the sky it stands under (its level albedo x irradiance / pi, albedos 0.1-0.4
pooled; an HDRI's own floor is not that ground: a studio's is seven times darker than its
lights would make a grey floor, and blurred lights make that the whole answer): per roughness
in `ROUGHNESS` and kind, the gain fitted against the upper hemisphere pre-filtered for it (the
add-on's own GGX pre-filter) over the gain fitted against the sharp one (`ROUGH_SKY_RATIOS`;
`params.sky_gain_for` multiplies the mirror's gain by it).

    python -m study sky-prior [--polyhaven]

`--polyhaven` then derives the mirror's gain the same way on the 15 Poly Haven HDRIs of
study/polyhaven.py (fetched once with npm), which none of this chose: how far the gain the
add-on uses is a property of Blender's six.
"""

from __future__ import annotations

import numpy as np

from virtual_reflections.colour import linear_to_srgb
from virtual_reflections.fill import GROUND_BAND_DEG
from virtual_reflections.params import Params
from virtual_reflections.prefilter import prefilter_latlong

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
ROUGHNESS = (0.15, 0.35, 0.5, 1.0)  # the rough surfaces' knots (params.ROUGH_SKY_RATIOS)
LIT_GAINS = np.round(np.arange(0.1, 40.01, 0.1), 2)  # the lit-ground model's (rough: larger)
ALBEDOS = (0.1, 0.2, 0.3, 0.4)  # the lit ground's, pooled
LUMA = np.array([0.2126, 0.7152, 0.0722])
FILL_ENERGY = Params().fill_energy  # the level's brightening toward the band's mean (0.5)


def errors(image, exponent: float = FILL_ENERGY) -> np.ndarray:
    """(len(GAINS),) display-value error of each gain for one equirectangular image, its
    level the band's log-average luminance brightened toward the mean by ``exponent`` (the
    fill's `energy`: `fill.prior_level`)."""
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
    level = log_average * (mean / log_average) ** exponent
    target = linear_to_srgb(np.clip(rgb[up], 0, 1))
    wu = weight[up]
    out = []
    for gain in GAINS:
        grey = linear_to_srgb(np.clip(np.full(3, gain * level), 0, 1))
        out.append((((grey - target) ** 2).sum(-1) * wu).sum() / wu.sum())
    return np.array(out)


def lit_errors(image, seen) -> np.ndarray:
    """(len(LIT_GAINS),) display-value error of each gain, summed over ALBEDOS, of predicting
    the upper hemisphere (above 5 degrees) ``seen`` — the image, or it pre-filtered — as a grey
    at the gain times the level of a ground lit by the image's sky (albedo x irradiance / pi,
    the irradiance from the image's upper hemisphere)."""
    rgb, seen = image[..., :3], seen[..., :3]
    h, w = rgb.shape[:2]
    lat = np.pi * (0.5 - (np.arange(h) + 0.5) / h)
    sky = lat > 0
    solid = np.cos(lat) * (np.pi / h) * (2 * np.pi / w)
    irradiance = float(((rgb[sky] @ LUMA) * (np.sin(lat[sky]) * solid[sky])[:, None]).sum())
    up = lat > np.radians(5)
    target = linear_to_srgb(np.clip(seen[up], 0, 1)).reshape(-1, 3).astype(np.float64)
    weight = np.repeat(np.cos(lat[up]), w)[:, None]
    # sum w (grey - t)^2 = grey^2 S0 - 2 grey S1 + S2 per channel: every gain from three sums.
    s0, s1, s2 = weight.sum(), (weight * target).sum(0), (weight * target**2).sum(0)
    out = np.zeros(len(LIT_GAINS))
    for albedo in ALBEDOS:
        level = albedo * irradiance / np.pi
        grey = linear_to_srgb(np.clip(LIT_GAINS * level, 0, 1)).astype(np.float64)[:, None]
        out += (grey * grey * s0 - 2 * grey * s1 + s2).sum(1) / s0
    return out


def rough_ratios(images) -> dict:
    """Print the rough surfaces' table; returns {kind: ((roughness, ratio), ...)}: for "auto"
    (the training HDRIs) and each kind of KINDS (its training HDRIs), the lit-ground model's
    gain at each roughness of ROUGHNESS over its gain for a mirror."""
    kinds = {"auto": TRAIN, **{k: [n for n in names if n in TRAIN] for k, names in KINDS.items()}}
    sharp = {n: lit_errors(image, image) for n, image in images.items()}
    base = {kind: LIT_GAINS[best_index(sharp, names)] for kind, names in kinds.items()}
    print()
    print("Rough surfaces, a ground lit by the sky (albedo 0.1-0.4): the gain fitted against the")
    print("upper hemisphere pre-filtered for the roughness over the gain for a mirror")
    print("| roughness | " + " | ".join(kinds) + " |")
    print("|---|" + "---|" * len(kinds))
    print("| 0 (mirror) | " + " | ".join(f"{base[k]:.1f}" for k in kinds) + " |")
    out = {kind: [] for kind in kinds}
    for roughness in ROUGHNESS:
        per = {n: lit_errors(im, prefilter_latlong(im, roughness)) for n, im in images.items()}
        cells = []
        for kind, names in kinds.items():
            gain = LIT_GAINS[best_index(per, names)]
            out[kind].append((roughness, round(float(gain / base[kind]), 2)))
            cells.append(f"{gain:.1f} (x {out[kind][-1][1]:.2f})")
        print(f"| {roughness} | " + " | ".join(cells) + " |")
    return {kind: tuple(knots) for kind, knots in out.items()}


def best_index(per: dict, names) -> int:
    """The index in GAINS of the gain minimising the summed error over the HDRIs ``names``."""
    return int(np.argmin(sum(per[name] for name in names if name in per)))


def load_images() -> dict:
    """Blender's bundled HDRIs: {name: (H, W, 3) float32 equirectangular, scene-linear}."""
    return {p.stem: load_equirect(str(p))[..., :3] for p in sorted(hdri_dir().glob("*.exr"))}


def gain_for_exponent(images, exponent: float) -> float:
    """The gain of `run`'s derivation (the summed error over TRAIN) with the level brightened
    by ``exponent`` (docs/scenes3d.md, "The level's statistic")."""
    per = {name: errors(image, exponent) for name, image in images.items()}
    return float(GAINS[best_index(per, TRAIN)])


def load_polyhaven(log=print) -> dict:
    """The Poly Haven HDRIs of study/polyhaven.py: {name: (H, W, 3) float32, scene-linear}.
    Their lossy compression leaves a few pixels slightly negative (under 2 %): set to 0."""
    from . import polyhaven

    folder = polyhaven.ensure(log)
    return {
        name: np.clip(np.nan_to_num(load_equirect(str(folder / f"{name}.exr"))[..., :3]), 0, None)
        for name in polyhaven.NAMES
    }


def polyhaven_gains(images: dict, others: dict) -> dict:
    """The mirror's gain by `run`'s derivation (the summed error; and the summed log error) on
    ``images`` alone, and on them with TRAIN's of ``others`` (Blender's), each HDRI's own best
    gain: {"alone", "alone_log", "with_train", "own": {name: gain}}."""
    per = {name: errors(image) for name, image in images.items()}
    both = {**per, **{f"blender {n}": errors(others[n]) for n in TRAIN if n in others}}
    return {
        "alone": float(GAINS[best_index(per, list(per))]),
        "alone_log": float(GAINS[int(np.argmin(sum(np.log(e + 1e-12) for e in per.values())))]),
        "with_train": float(GAINS[best_index(both, list(both))]),
        "own": {name: float(GAINS[int(np.argmin(e))]) for name, e in per.items()},
    }


def print_polyhaven(gains: dict) -> None:
    print()
    print("The same derivation on the 15 Poly Haven HDRIs (none of Blender's; nothing chose them):")
    print("| HDRI | own best gain |")
    print("|---|---|")
    for name, gain in gains["own"].items():
        print(f"| {name} | {gain:.1f} |")
    print(
        f"gain minimising the summed error over them: {gains['alone']:.1f} (summing the log "
        f"errors: {gains['alone_log']:.1f}); over them and {', '.join(TRAIN)}: "
        f"{gains['with_train']:.1f} (the add-on's: {Params().sky_gain:.1f}, from the six alone)"
    )


def run(polyhaven: bool = False) -> dict:
    """Print the tables; returns the gains: {"auto": the one chosen on the training HDRIs,
    "auto_log": the same fit summing log errors (a variant the add-on does not use), "open":
    .., "enclosed": ..: each kind's from its training HDRIs, "rough": `rough_ratios`}."""
    images = load_images()
    per = {name: errors(image) for name, image in images.items()}
    at = best_index(per, TRAIN)
    one = int(np.argmin(np.abs(GAINS - 1.0)))
    out = {"auto": float(GAINS[at])}
    print(f"gain minimising the summed error over {', '.join(TRAIN)}: {out['auto']:.1f}")
    logs = int(np.argmin(sum(np.log(per[name]) for name in TRAIN)))
    out["auto_log"] = float(GAINS[logs])  # a variant, not used (docs/scenes3d.md)
    print(f"(summing the log errors instead, as a mean PSNR does: {out['auto_log']:.1f})")
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
    out["rough"] = rough_ratios(images)
    if polyhaven:
        out["polyhaven"] = polyhaven_gains(load_polyhaven(), images)
        print_polyhaven(out["polyhaven"])
    return out
