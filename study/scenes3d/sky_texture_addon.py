"""Sky Texture as the add-on renders it (`Params.sky_texture`, the panel's Sky Texture; issue
41, item 3): the 50 scenes of `heldout_sky.specs` rendered by Generate at every share of
`sky_texture.CONTRASTS`, each scored against the truth over the plate-mean world, and the
share chosen leave-one-HDRI-out under `heldout_sky.SAFE_FLOOR` by PSNR and by FLIP.

    python -m study.scenes3d.sky_texture_addon render OUT   # 5 shares x 50 scenes (bpy 4.5);
                                                            # the truths once into OUT/cache
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
from .sky_texture import CONTRASTS, held_out_picks


def folder(out, k) -> pathlib.Path:
    return pathlib.Path(out) / f"k{k:g}"


def render(out, log=print) -> None:
    """Every scene at every share into OUT/k<share>/ (records.jsonl, work/), the truths and
    plate-mean mirrors cached in OUT/cache; a scene already recorded is skipped."""
    from . import mirror, run

    out = pathlib.Path(out)
    addon = run.Addon()
    generate, label = addon.generate.generate, run.default_method_label
    share = [0.0]

    def textured(scene, *args, **kwargs):
        scene.virtual_reflections.sky_texture = share[0]
        return generate(scene, *args, **kwargs)

    addon.generate.generate = textured
    run.default_method_label = lambda _addon: hs.LABEL
    try:
        for k in CONTRASTS:
            share[0] = k
            here = folder(out, k)
            here.mkdir(parents=True, exist_ok=True)
            done = {r["scene"]["name"] for r in hs.read_records(here)}
            with open(here / "records.jsonl", "a") as records:
                for spec in hs.specs():
                    if spec.name in done:
                        continue
                    record, _ = mirror.run_scene(
                        spec, addon, out / "cache", here / "work", hs.WIDTH, hs.SAMPLES, log
                    )
                    record["sky_texture"] = k
                    records.write(json.dumps(record) + "\n")
                    records.flush()
    finally:
        addon.generate.generate, run.default_method_label = generate, label
        run.new_file()
        addon.close()


def scene_scores(out, name, k) -> tuple:
    """One scene at share k: (PSNR over the plate-mean world, SSIM over it, FLIP, the upper
    half's detail ratio), display-space composites over the plate on the subject's pixels."""
    cache = pathlib.Path(out) / "cache"
    where = next(p for p in cache.glob(f"{name}-*") if (p / "truth mirror.exr").is_file())
    plate = read_rgba(str(where / "plate.exr"))[..., :3].astype(np.float64)
    truth = to_display(read_rgba(str(where / "truth mirror.exr"))[..., :3].astype(np.float64))
    mean = read_rgba(str(where / "Plate mean mirror.exr")).astype(np.float64)
    image = read_rgba(str(folder(out, k) / "work" / f"{name} {hs.LABEL}.exr")).astype(np.float64)
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
    """Print one row per share and the held-out picks; returns (scenes, shares, 4) scores."""
    records = hs.read_records(folder(out, CONTRASTS[0]))
    names = [r["scene"]["name"] for r in records]
    hdris = np.array([r["scene"]["hdri"] for r in records])
    scores = np.array([[scene_scores(out, name, k) for k in CONTRASTS] for name in names])
    log(f"{len(names)} scenes, {len(set(hdris))} HDRIs; the add-on's mirror at each Sky Texture, "
        "over the plate-mean world")  # fmt: skip
    log("| Sky Texture | PSNR: mean, ahead, worst | SSIM | FLIP | upper-half detail |")
    log("|---|---|---|---|---|")
    for j, k in enumerate(CONTRASTS):
        v, s, f, u = (scores[:, j, i] for i in range(4))
        log(f"| {k:g} | {v.mean():+.2f} dB, {(v > 0).sum()}/{len(v)}, worst {v.min():+.2f} | "
            f"{s.mean():+.3f} | {f.mean():.3f} | {np.nanmedian(u):.2f} |")  # fmt: skip
    psnrs, flips = scores[..., 0], scores[..., 2]
    rows = np.arange(len(names))
    for name, objective in (("PSNR", psnrs), ("FLIP", -flips)):
        chosen = held_out_picks(psnrs, objective, hdris)
        v, f = psnrs[rows, chosen], flips[rows, chosen]
        log(f"held out by {name} under the floor: picks {sorted({CONTRASTS[c] for c in chosen})}; "
            f"{v.mean():+.2f} dB, {(v > 0).sum()}/{len(v)}, worst {v.min():+.2f}, "
            f"FLIP {f.mean():.3f}")  # fmt: skip
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
