"""Benchmark: pre-filtering a map for a rough material (virtual_reflections/prefilter.py).

    .venv/bin/python benchmarks/prefilter_bench.py [--repeat 5]

On one of Blender's bundled HDRIs (sunrise: a sun in the map) resampled to lat-long maps 256
to 2048 wide, for roughness 0.15, 0.35 and 0.6: the median time of `prefilter_latlong` and,
as its peer in the same run, of the filter it replaced (two Gaussians, 60 % of 1.2 alpha and
40 % of 3.2 alpha, both at full resolution, through the same `_gaussian`); and the accuracy of
running the wide Gaussians on reduced maps — the mean difference, relative to the map's mean,
from the same Gaussians all run at full resolution.
"""

import argparse
import pathlib
import statistics
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from study.evaluate import hdri_dir  # noqa: E402
from study.panorama import load_equirect  # noqa: E402
from virtual_reflections import prefilter  # noqa: E402


def resized(image, width):
    """``image`` (H, W, 3) box-filtered or repeated to a ``width``-wide lat-long."""
    h, w = image.shape[:2]
    if width <= w:
        f = w // width
        return image.reshape(h // f, f, w // f, f, 3).mean((1, 3)).astype(np.float32)
    f = width // w
    return np.repeat(np.repeat(image, f, 0), f, 1).astype(np.float32)


def median_ms(call, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        call()
        times.append(time.perf_counter() - t)
    return 1000 * statistics.median(times)


def full_resolution(env, roughness):
    """The same Gaussians as `prefilter_latlong`, every one at full resolution."""
    h = env.shape[0]
    spectrum = np.fft.rfft(env, axis=1)
    out = np.zeros_like(env)
    for weight, sigma in prefilter.lobe_sigmas(roughness):
        if sigma / (np.pi / h) < prefilter.IDENTITY_TEXELS:
            out += weight * env
        else:
            out += weight * prefilter._gaussian(spectrum, env.shape, sigma)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    source = load_equirect(str(hdri_dir() / "sunrise.exr"))[..., :3].astype(np.float32)
    print(f"sunrise HDRI {source.shape[1]}x{source.shape[0]}; medians of {args.repeat}")
    print("| map width | roughness | Gaussians | pre-filter (ms) | two Gaussians before (ms) "
          "| ratio | reduced maps' difference |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for width in (256, 512, 1024, 2048):
        env = resized(source, width)
        for roughness in (0.15, 0.35, 0.6):
            row(env, roughness, args.repeat)


def before(env, roughness):
    """The filter replaced: 60 % of 1.2 alpha and 40 % of 3.2 alpha, both at full resolution."""
    alpha = roughness**2
    return sum(
        w * prefilter._gaussian(np.fft.rfft(env, axis=1), env.shape, k * alpha)
        for w, k in ((0.6, 1.2), (0.4, 3.2))
    )


def row(env, roughness, repeat):
    """One line of the table: ``env`` pre-filtered for ``roughness``."""
    spent = median_ms(lambda: prefilter.prefilter_latlong(env, roughness), repeat)
    peer = median_ms(lambda: before(env, roughness), repeat)
    fast = prefilter.prefilter_latlong(env, roughness)
    difference = np.abs(fast - full_resolution(env, roughness)).mean() / env.mean()
    print(
        f"| {env.shape[1]} | {roughness} | {len(prefilter.lobe_sigmas(roughness))} "
        f"| {spent:.1f} | {peer:.1f} | {spent / peer:.2f}x | {100 * difference:.2f} % |"
    )


if __name__ == "__main__":
    main()
