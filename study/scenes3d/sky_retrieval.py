"""The unseen sky retrieved from the HDRIs every Blender ships (Karsch et al. 2014 style; issue
41): of `datafiles/studiolights/world/*.exr` (8 lat-long), the one (and its turn about +Z)
whose band the plate sees best matches the plate; its upper hemisphere, levelled to the sky
estimate, gives the mirror's unseen sky its structure (and optionally its colour).

Held out strictly: a scene under one of Blender's HDRIs never retrieves that HDRI; every
constant (gain, level cue, tint, structure share, colour from the retrieved HDRI or the
estimate) is fitted leave-one-HDRI-out (`heldout_sky.loho`). Scored from `heldout_sky render`'s
renders (the prior's part is linear in its colour, per pixel too) and
`sky_directions`' (the world direction each mirror and plate pixel looks along).

    python -m study.scenes3d.sky_directions OUT/dirs            # ~2 min, 4 tiny renders a scene
    python -m study.scenes3d.sky_retrieval OUT [--safe]           # ~2 min
"""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np

from virtual_reflections.colour import srgb_to_linear
from virtual_reflections.imagefiles import read_rgba

from ..evaluate.metrics import psnr, to_display
from . import heldout_sky as hs

TURNS = np.radians(np.arange(0, 360, 15))  # the retrieved HDRI's turns about +Z tried
SHARES = (0.25, 0.5, 1.0)  # the retrieved structure's share of the sky
MIN_SKY = 20  # plate pixels of seen sky below which the whole plate is matched


def blender_hdris() -> dict:
    """{name: (h, w, 3) float32} Blender's studio-light worlds, halved to 256 x 512."""
    import bpy  # only for its datafiles folder

    root = pathlib.Path(bpy.utils.system_resource("DATAFILES")) / "studiolights" / "world"
    out = {}
    for path in sorted(root.glob("*.exr")):
        image = read_rgba(str(path))[..., :3].astype(np.float32)
        h, w = image.shape[:2]
        image = image[: h // 2 * 2, : w // 2 * 2]
        out[path.stem] = image.reshape(h // 2, 2, w // 2, 2, 3).mean((1, 3))
    return out


def sample(image, d, turn=0.0):
    """``image`` (lat-long as Cycles' Environment Texture reads it) along directions ``d``
    (..., 3), the world turned by ``turn`` about +Z first (build.dome_world's Mapping)."""
    c, s = math.cos(turn), math.sin(turn)
    x, y = c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]
    u = (math.pi - np.arctan2(y, x)) / (2 * math.pi)
    v = 0.5 - np.arcsin(np.clip(d[..., 2], -1, 1)) / math.pi
    h, w = image.shape[:2]
    return image[np.clip((v * h).astype(int), 0, h - 1), (u * w).astype(int) % w]


def upper_level(image) -> float:
    """The upper hemisphere's mean luminance per solid angle."""
    h = image.shape[0]
    rows = image[: h // 2] @ hs.LUMA  # (h/2, w)
    weight = np.cos((np.arange(h // 2) + 0.5 - h / 2) / h * math.pi)
    return float((rows.mean(1) * weight).sum() / weight.sum())


def unit(rgb):
    d = 2.0 * rgb - 1.0
    return d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-6)


def retrieve(plate8, dirs, alpha, hdris, exclude):
    """(name, turn, distance): the HDRI (not ``exclude``) and turn whose view along the plate's
    directions best matches the plate's seen sky (its whole plate when under MIN_SKY pixels
    show sky): the mean squared log difference per channel, after the best common scale,
    the candidate clipped at 1 as the 8-bit plate is."""
    sky = (alpha < 0.5) & (dirs[..., 2] > 0.02)
    where = sky if sky.sum() >= MIN_SKY else np.ones(sky.shape, bool)
    seen = np.log(np.maximum(plate8[where], 1e-3))
    best = (None, 0.0, np.inf)
    for name, image in hdris.items():
        if name == exclude:
            continue
        for turn in TURNS:
            c = np.maximum(sample(image, dirs[where], turn), 1e-6)
            scale = np.exp(np.median((seen - np.log(c)).mean(-1)))
            view = np.log(np.maximum(np.minimum(c * scale, 1.0), 1e-3))
            distance = float(np.mean((view - seen) ** 2))
            if distance < best[2]:
                best = (name, float(turn), distance)
    return best


def attach(out, d, hdris) -> None:
    """d["retrieved"] (name, turn, distance) and d["structure"] (the sky pixels' retrieved
    radiance, its upper hemisphere's mean luminance 1)."""
    folder = pathlib.Path(out) / "dirs" / d["name"]
    cache = next((pathlib.Path(out) / "cache").glob(f"{d['name']}-*"))
    plate8 = srgb_to_linear(read_rgba(str(cache / "plate.png"))[..., :3]).astype(np.float64)
    dirs = unit(read_rgba(str(folder / "dir plate.exr"))[..., :3].astype(np.float64))
    alpha = read_rgba(str(folder / "alpha plate.exr"))[..., 3]
    exclude = d["hdri"] if d["hdri"] in hdris else None
    d["retrieved"] = name, turn, _ = retrieve(plate8, dirs, alpha, hdris, exclude)
    y0, y1, x0, x1 = d["crop"]
    coded = read_rgba(str(folder / "dir mirror.exr"))[y0:y1, x0:x1, :3].astype(np.float64)
    white = read_rgba(str(folder / "white mirror.exr"))[y0:y1, x0:x1, :3].astype(np.float64)
    mirror = unit(coded / np.maximum(white, 1e-4))
    mirror[..., 2] = np.abs(mirror[..., 2])  # the prior's blur below the horizon: its mirror
    image = hdris[name]
    d["structure"] = sample(image, mirror[d["sky"]], turn) / max(upper_level(image), 1e-9)


MODES = ("its colour", "the estimate's colour")


def composite(d, gain, level, tau, share, mode):
    """The scene's mirror with the flat estimate's sky (`heldout_sky.composite`'s level and
    tint) given the retrieved structure by ``share``: its colour ("its colour") or only its
    luminance in the estimate's colour."""
    target = gain * hs.LEVELS[level](d) * hs.chroma(d, d["plate_mean"], tau)
    structure = d["structure"]
    if mode == MODES[0]:
        lit = hs.lum(target) * structure
    else:
        lit = target * (structure @ hs.LUMA)[:, None]
    colour = np.broadcast_to(target, d["part"].shape).copy()
    colour[d["sky"]] = (1 - share) * target + share * lit
    return d["dark"] + colour / d["today"] * d["part"]


def grid():
    return [
        (g, lv, t, s, m) for g in hs.GAINS for lv in ("today's level", "plate mean's level")
        for t in (0.0, 0.25, 0.5) for s in SHARES for m in MODES
    ]  # fmt: skip


def fit(out, safe=False, log=print):
    hdris = blender_hdris()
    data = [hs.load(out, r) for r in hs.read_records(out)]
    for d in data:
        attach(out, d, hdris)
    params = grid()
    scores = np.array(
        [
            [psnr(to_display(composite(d, *p)), to_display(d["truth"]), d["mask"]) - d["base"]
             for p in params]
            for d in data
        ]
    )  # fmt: skip
    groups = np.array([d["hdri"] for d in data])
    log(f"{len(data)} scenes; retrieved (scene: HDRI, turn deg, distance):")
    log(", ".join(
        f"{d['name']}: {d['retrieved'][0]} {math.degrees(d['retrieved'][1]):.0f}"
        for d in data
    ))  # fmt: skip
    log("| the unseen sky | mean, ahead, worst |")
    log("|---|---|")
    results = {}
    families = {
        "retrieved structure (any share, colour from it or the estimate)": list(range(len(params))),
        "retrieved structure, its colour": [i for i, p in enumerate(params) if p[4] == MODES[0]],
        "retrieved structure, the estimate's colour": [
            i for i, p in enumerate(params) if p[4] == MODES[1]
        ],
        "retrieved structure alone (share 1)": [i for i, p in enumerate(params) if p[3] == 1.0],
    }
    for name, columns in families.items():
        held, chosen = hs.loho(scores, groups, columns, safe)
        results[name] = held
        log(hs.table_line(name, held))
        picked = sorted({(round(params[c][0], 2), *params[c][1:]) for c in chosen}, key=str)
        log(f"|   fitted per held-out HDRI: {picked} | |")
        log("|   worst held out: " + ", ".join(
            f"{data[i]['name']} {held[i]:+.2f}" for i in np.argsort(held)[:4]) + " |"
        )  # fmt: skip
    for name, held in results.items():
        sets = {
            "Blender's HDRIs (20)": np.isin(groups, list(hdris)),
            "Poly Haven (30)": ~np.isin(groups, list(hdris)),
        }
        log(
            f"{name}: "
            + ", ".join(f"{s} {hs.table_line('', held[m])[5:-2]}" for s, m in sets.items())
        )
    return results


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        print("usage: python -m study.scenes3d.sky_retrieval OUT [--safe]", file=sys.stderr)
        return 2
    fit(args[0], "--safe" in args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
