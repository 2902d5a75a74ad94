"""Sky Texture as the add-on renders it (`Params.sky_texture`, the panel's Sky Texture; issue
41, item 3): the 50 scenes of `heldout_sky.specs` rendered by Generate at every share of
`sky_texture.CONTRASTS` and every fade of FADES (the engine's SKY_TEXTURE_FADE_DEG, set in the
engine and in the add-on's copy of it, the tables' cache emptied between fades), each scored
against the truth over the plate-mean world, and the setting chosen leave-one-HDRI-out
(`pick_by_bars`): on the other HDRIs' scenes, of the settings that meet issue 41's bars
(BARS: the worst scene within 1 dB of the plate-mean world, mean +1.0 dB, 75 % ahead, SSIM
+0.10, FLIP at most 0.48), the one with the most upper-half detail (the bar none met); none
meeting them, the flat sky. Also the held-out picks of the share alone by PSNR and by FLIP.

    python -m study.scenes3d.sky_texture_addon render OUT   # 17 settings x 50 scenes: ~17 min
                                                            # (bpy 4.5), the truths into OUT/cache
    python -m study.scenes3d.sky_texture_addon score OUT    # the table and the held-out picks
"""

from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

from virtual_reflections.imagefiles import read_rgba

from ..evaluate.metrics import psnr, ssim, to_display
from ..evaluate.perceptual import detail_ratio, flip_ldr, upper_half
from . import heldout_sky as hs
from .sky_texture import CONTRASTS

FADES = (10.0, 20.0, 30.0, 45.0)  # degrees: SKY_TEXTURE_FADE_DEG tried
BARS = {"worst": -1.0, "mean": 1.0, "ahead": 0.75, "ssim": 0.10, "flip": 0.48}


def settings() -> list:
    """[(fade, share)]: the flat sky (None, 0) and every fade with every share above 0."""
    return [(None, 0.0)] + [(f, k) for f in FADES for k in CONTRASTS if k > 0]


def folder(out, fade, k) -> pathlib.Path:
    return pathlib.Path(out) / ("k0" if not k else f"f{fade:g}_k{k:g}")


def set_fade(addon, fade) -> None:
    """SKY_TEXTURE_FADE_DEG = ``fade`` in the engine and the add-on's copy; every cached table
    dropped (a table does not hold the fade in its key)."""
    import importlib

    for package in ("virtual_reflections", f"{addon.module.__name__}.virtual_reflections"):
        importlib.import_module(f"{package}.sky_texture").SKY_TEXTURE_FADE_DEG = fade
        cache = importlib.import_module(f"{package}.cache")
        budget = cache.limit()
        cache.set_limit(0)
        cache.set_limit(budget)


def render(out, log=print) -> None:
    """Every scene at every setting into OUT/<setting>/ (records.jsonl, work/), the truths and
    plate-mean mirrors cached in OUT/cache; a scene already recorded is skipped."""
    import importlib

    from . import mirror, run

    out = pathlib.Path(out)
    addon = run.Addon()
    generate, label = addon.generate.generate, run.default_method_label
    share = [0.0]
    engine = importlib.import_module(f"{addon.module.__name__}.virtual_reflections.sky_texture")
    default_fade = engine.SKY_TEXTURE_FADE_DEG

    def textured(scene, *args, **kwargs):
        scene.virtual_reflections.sky_texture = share[0]
        return generate(scene, *args, **kwargs)

    addon.generate.generate = textured
    run.default_method_label = lambda _addon: hs.LABEL
    try:
        for fade, k in settings():
            set_fade(addon, default_fade if fade is None else fade)
            share[0] = k
            here = folder(out, fade, k)
            here.mkdir(parents=True, exist_ok=True)
            done = {r["scene"]["name"] for r in hs.read_records(here)}
            with open(here / "records.jsonl", "a") as records:
                for spec in hs.specs():
                    if spec.name in done:
                        continue
                    record, _ = mirror.run_scene(
                        spec, addon, out / "cache", here / "work", hs.WIDTH, hs.SAMPLES, log
                    )
                    record["sky_texture"] = [fade, k]
                    records.write(json.dumps(record) + "\n")
                    records.flush()
    finally:
        set_fade(addon, default_fade)
        addon.generate.generate, run.default_method_label = generate, label
        run.new_file()
        addon.close()


def pick_by_bars(scores) -> int:
    """The column of ``scores`` (scenes, settings, 4: PSNR over the plate mean, SSIM over it,
    FLIP, upper-half detail) meeting every bar of BARS with the most median upper-half detail
    (then the most mean PSNR); none meeting them: column 0, the flat sky."""
    v = scores[..., 0]
    meets = (
        (v.min(0) >= BARS["worst"])
        & (v.mean(0) >= BARS["mean"])
        & ((v > 0).mean(0) >= BARS["ahead"])
        & (scores[..., 1].mean(0) >= BARS["ssim"])
        & (scores[..., 2].mean(0) <= BARS["flip"])
    )
    if not meets.any():
        return 0
    detail = np.round(np.nanmedian(scores[..., 3], 0), 2)
    return int(np.lexsort((v.mean(0), np.where(meets, detail, -np.inf)))[-1])


def scene_scores(out, name, fade, k) -> tuple:
    """One scene at a setting: (PSNR over the plate-mean world, SSIM over it, FLIP, the upper
    half's detail ratio), display-space composites over the plate on the subject's pixels."""
    cache = pathlib.Path(out) / "cache"
    where = next(p for p in cache.glob(f"{name}-*") if (p / "truth mirror.exr").is_file())
    plate = read_rgba(str(where / "plate.exr"))[..., :3].astype(np.float64)
    truth = to_display(read_rgba(str(where / "truth mirror.exr"))[..., :3].astype(np.float64))
    mean = read_rgba(str(where / "Plate mean mirror.exr")).astype(np.float64)
    image = folder(out, fade, k) / "work" / f"{name} {hs.LABEL}.exr"
    image = read_rgba(str(image)).astype(np.float64)
    mask = mean[..., 3] > 0.5

    def over(rgba):
        return to_display(rgba[..., :3] + (1.0 - rgba[..., 3:4]) * plate)

    x, m = over(image), over(mean)
    return (
        psnr(x, truth, mask) - psnr(m, truth, mask),
        ssim(x, truth, mask) - ssim(m, truth, mask),
        flip_ldr(x, truth, mask),
        detail_ratio(x, truth, mask, upper_half(mask)),
    )


def score(out, log=print) -> np.ndarray:
    """Print one row per setting and the held-out picks; returns (scenes, settings, 4) scores."""
    records = hs.read_records(folder(out, None, 0.0))
    names = [r["scene"]["name"] for r in records]
    hdris = np.array([r["scene"]["hdri"] for r in records])
    every = settings()
    scores = np.array([[scene_scores(out, name, *s) for s in every] for name in names])
    log(f"{len(names)} scenes, {len(set(hdris))} HDRIs; the add-on's mirror at each Sky Texture "
        "and fade, over the plate-mean world")  # fmt: skip
    log("| fade | Sky Texture | PSNR: mean, ahead, worst | SSIM | FLIP | upper-half detail |")
    log("|---|---|---|---|---|---|")
    for j, (fade, k) in enumerate(every):
        v, s, f, u = (scores[:, j, i] for i in range(4))
        log(f"| {'–' if fade is None else f'{fade:g}°'} | {k:g} | {v.mean():+.2f} dB, "
            f"{(v > 0).sum()}/{len(v)}, worst {v.min():+.2f} | {s.mean():+.3f} | "
            f"{f.mean():.3f} | {np.nanmedian(u):.2f} |")  # fmt: skip
    rows = np.arange(len(names))
    chosen = np.empty(len(names), int)
    for group in np.unique(hdris):
        chosen[hdris == group] = pick_by_bars(scores[hdris != group])
    held = scores[rows, chosen]
    picks = sorted({(every[c], int((chosen == c).sum())) for c in set(chosen)}, key=str)
    v = held[:, 0]
    log(
        f"held out by the bars (fade, share: scenes): {picks}; {v.mean():+.2f} dB, "
        f"{(v > 0).sum()}/{len(v)}, worst {v.min():+.2f}, SSIM {held[:, 1].mean():+.3f}, "
        f"FLIP {held[:, 2].mean():.3f}, upper-half detail {np.nanmedian(held[:, 3]):.2f}"
    )
    log(f"on every scene: {every[pick_by_bars(scores)]}")
    return scores


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 2 or args[0] not in ("render", "score"):
        print("usage: python -m study.scenes3d.sky_texture_addon render|score OUT", file=sys.stderr)
        return 2
    (render if args[0] == "render" else score)(args[1])
    return 0


if __name__ == "__main__":
    sys.exit(main())
