"""The unseen sky given the plate's own texture (issue 41, item 3: "structure borrowed from the
plate itself, levelled to the estimate"), measured against the flat estimate Auto renders.

Per mirror pixel that sees the sky prior, its world direction (`sky_directions`) is folded into
the plate's view: its elevation clamped to the elevations the plate shows at or above the
horizon, its azimuth reflected back and forth across the plate's azimuths (so the skyline the
plate shows continues around the camera, mirrored at each edge, without a seam). The plate
pixel nearest that direction lends its log-luminance (display: each pixel clipped at 1); the
sky's pixels are Auto's colour (`heldout_sky.plate_sky`) times exp(k (t - mean t)), the
difference clipped at the engine's SKY_TEXTURE_CLIP and faded out over SKY_TEXTURE_FADE_DEG
above the plate's highest elevation (w): their log-average stays the estimate's, k sets the
contrast (0: Auto's flat sky; 1: the plate's own). The engine's `Params.sky_texture`
(virtual_reflections/sky_texture.py) does the same on the map.

Scored from `heldout_sky render`'s renders (the prior's part is linear in its colour, per
pixel too); k is chosen leave-one-HDRI-out under `heldout_sky.SAFE_FLOOR`, by PSNR and by FLIP.

    python -m study.scenes3d.sky_directions OUT/dirs     # ~2 min, 4 tiny renders a scene
    python -m study.scenes3d.sky_texture OUT             # ~2 min: the sweep and the held-out picks
"""

from __future__ import annotations

import pathlib
import sys

import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba
from virtual_reflections.sky_texture import SKY_TEXTURE_CLIP, SKY_TEXTURE_FADE_DEG, fold

from ..evaluate.metrics import psnr, ssim, to_display
from ..evaluate.perceptual import detail_ratio, flip_ldr, upper_half
from . import heldout_sky as hs
from .sky_retrieval import unit

CONTRASTS = (0.0, 0.25, 0.5, 0.75, 1.0)  # k: the share of the plate's log-contrast


def angles(dirs: np.ndarray) -> np.ndarray:
    """(..., 2) elevation and azimuth (radians) of unit world directions (+Z up)."""
    return np.stack(
        [np.arcsin(np.clip(dirs[..., 2], -1, 1)), np.arctan2(dirs[..., 1], dirs[..., 0])], -1
    )


def plate_texture(plate8, plate_dirs, sky_dirs) -> np.ndarray:
    """(n,) the plate's display log-luminance lent to ``sky_dirs`` (n, 3): from the plate's
    pixels at or above the horizon (all of them when it shows under 20 such), at the direction
    folded into the plate's view (module docstring)."""
    from scipy.spatial import cKDTree

    lum = np.log(np.maximum(np.minimum(plate8, 1.0) @ hs.LUMA, 1e-3))
    where = plate_dirs[..., 2] >= 0.0
    if where.sum() < 20:
        where = np.ones(where.shape, bool)
    seen = angles(plate_dirs[where])
    values = lum[where]
    centre = np.angle(np.exp(1j * seen[:, 1]).mean())  # the plate's azimuths about their middle
    seen[:, 1] = np.angle(np.exp(1j * (seen[:, 1] - centre)))
    wanted = angles(sky_dirs)
    az = np.angle(np.exp(1j * (wanted[:, 1] - centre)))
    az = fold(az, seen[:, 1].min(), seen[:, 1].max())
    el = np.clip(wanted[:, 0], seen[:, 0].min(), seen[:, 0].max())
    _, index = cKDTree(seen).query(np.stack([el, az], -1))
    return values[index]


def attach(out, d) -> None:
    """d["texture"]: `plate_texture` for the scene's sky pixels (OUT/dirs/<scene>)."""
    folder = pathlib.Path(out) / "dirs" / d["name"]
    cache = next((pathlib.Path(out) / "cache").glob(f"{d['name']}-*"))
    plate8 = srgb_to_linear(read_rgba(str(cache / "plate.png"))[..., :3]).astype(np.float64)
    plate_dirs = unit(read_rgba(str(folder / "dir plate.exr"))[..., :3].astype(np.float64))
    y0, y1, x0, x1 = d["crop"]
    coded = read_rgba(str(folder / "dir mirror.exr"))[y0:y1, x0:x1, :3].astype(np.float64)
    white = read_rgba(str(folder / "white mirror.exr"))[y0:y1, x0:x1, :3].astype(np.float64)
    mirror = unit(coded / np.maximum(white, 1e-4))
    mirror[..., 2] = np.abs(mirror[..., 2])  # the prior's blur below the horizon: its mirror
    sky = mirror[d["sky"]]
    d["texture"] = plate_texture(plate8, plate_dirs, sky)
    top = float(np.arcsin(np.clip(plate_dirs[..., 2], -1, 1)).max())  # the plate's highest
    above = np.arcsin(np.clip(sky[:, 2], -1, 1)) - top
    d["fade"] = np.clip(1.0 - above / np.radians(SKY_TEXTURE_FADE_DEG), 0.0, 1.0)


def textured(d, gain, tint, k):
    """The scene's mirror (linear crop) with Auto's sky from the plate (`plate_sky`'s gain and
    tint) given the plate's texture at contrast ``k``, its log-average kept (the difference
    clipped at SKY_TEXTURE_CLIP and weighted by d["fade"], w, when given)."""
    hue = d["plate_mean"] / max(hs.lum(d["plate_mean"]), 1e-6)
    target = gain * hs.lum(d["plate_mean"]) * ((1 - tint) + tint * hue)
    colour = np.broadcast_to(target, d["part"].shape).copy()
    t, w = d["texture"], d.get("fade", np.ones(d["texture"].shape))
    if k and t.size and w.sum() > 0:
        spread = w * (t - (w @ t) / w.sum())
        spread = np.clip(spread, -SKY_TEXTURE_CLIP, SKY_TEXTURE_CLIP)
        colour[d["sky"]] = target * np.exp(k * spread)[:, None]
    return d["dark"] + colour / d["today"] * d["part"]


def sweep(out, gain=hs.AUTO_SKY_GAIN, tint=hs.AUTO_SKY_TINT, log=print) -> dict:
    """Score every k of CONTRASTS on OUT's scenes (those with directions), print one row each
    and the held-out picks; returns {k: PSNR over the plate mean per scene}."""
    data = []
    for record in hs.read_records(out):
        if (pathlib.Path(out) / "dirs" / record["scene"]["name"] / "dir mirror.exr").is_file():
            d = hs.load(out, record)
            attach(out, d)
            data.append(d)
    if not data:
        raise SystemExit(f"no scene of {out} has directions: run study.scenes3d.sky_directions")
    truths = [to_display(d["truth"]) for d in data]
    hdris = np.array([d["hdri"] for d in data])
    log(f"{len(data)} scenes, {len(set(hdris))} HDRIs; Auto's sky (gain {gain:g}, tint {tint:g}) "
        "given the plate's texture at contrast k; mirror over the plate-mean world")  # fmt: skip
    log("| k | PSNR: mean, ahead, worst | SSIM | FLIP | upper-half detail |")
    log("|---|---|---|---|---|")
    scores, flips = [], []
    for k in CONTRASTS:
        images = [to_display(textured(d, gain, tint, k)) for d in data]
        v = np.array([psnr(x, t, d["mask"]) - d["base"] for x, t, d in zip(images, truths, data)])
        s = [ssim(x, t, d["mask"]) - ssim(to_display(d["mean"]), t, d["mask"])
             for x, t, d in zip(images, truths, data)]  # fmt: skip
        f = np.array([flip_ldr(x, t, d["mask"]) for x, t, d in zip(images, truths, data)])
        u = [detail_ratio(x, t, d["mask"], upper_half(d["mask"]))
             for x, t, d in zip(images, truths, data)]  # fmt: skip
        scores.append(v)
        flips.append(f)
        log(f"| {k:g} | {v.mean():+.2f} dB, {(v > 0).sum()}/{len(v)}, worst {v.min():+.2f} | "
            f"{np.mean(s):+.3f} | {f.mean():.3f} | {np.nanmedian(u):.2f} |")  # fmt: skip
    scores, flips = np.array(scores).T, np.array(flips).T
    for name, objective in (("PSNR", scores), ("FLIP", -flips)):
        chosen = held_out_picks(scores, objective, hdris)
        v, f = scores[np.arange(len(data)), chosen], flips[np.arange(len(data)), chosen]
        log(
            f"k held out by {name}: picks {sorted({CONTRASTS[c] for c in chosen})}; "
            f"{v.mean():+.2f} dB, {(v > 0).sum()}/{len(v)}, worst {v.min():+.2f}, "
            f"FLIP {f.mean():.3f}"
        )
    return dict(zip(CONTRASTS, scores.T))


def held_out_picks(scores, objective, groups) -> np.ndarray:
    """Per scene, the column chosen without its group (leave-one-group-out): of the columns
    whose worst PSNR ``scores`` over the other groups stays at or above SAFE_FLOOR, the best
    mean ``objective`` there (none: the best worst scene)."""
    chosen = np.empty(len(scores), int)
    for group in np.unique(groups):
        train = groups != group
        chosen[~train] = hs.pick_under_floor(scores[train], objective=objective[train])
    return chosen


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m study.scenes3d.sky_texture OUT", file=sys.stderr)
        return 2
    sweep(args[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
