"""The GGX lobe of a rough surface, as the pre-filtered map (prefilter.py) and the Mix look's
lookup direction need it: no scene, only the microfacet model (Blender's Principled BSDF:
GGX with alpha = roughness^2, Smith's masking-shadowing).

`lobe`: the reflected radiance of a GGX surface seen along its normal, as a function of the
angle from the mirror direction, fitted by Gaussians over the sphere whose widths are alpha
times powers of two. GGX has a heavy tail — the share of the lobe beyond an angle t falls
only as (2 alpha / t)^2 — and under a sun or a studio light, light tens of degrees off the
mirror direction is most of what a rough surface shows away from its highlight; two
Gaussians (the fit before) held a half to a quarter of the tail beyond 60 degrees at
roughness 0.35 (docs/ground.md, "Rough surfaces under a bright light").

`dominant_shift`: away from normal incidence the lobe's weight leans toward the normal (the
masking and the microfacets facing the viewer), so its centre is not the mirror direction but
part of the way from it to the normal, more with roughness and toward grazing views (the
"dominant direction" of real-time pre-filtered lookups, derived here from the model); the Mix
look reads its pre-filtered map there (operators/node_trees/reflection_nodes.py).
"""

from __future__ import annotations

import functools
import itertools

import numpy as np

MAX_SIGMA = 1.0  # radians: the widest Gaussian of the fit (a wider one is nearly flat)
_TAIL_BINS = 40  # bins from 6 alpha to 90 degrees (the core has 30 up to 6 alpha)


def smith_g1(cosine, alpha2):
    """Smith's masking term of GGX for directions at ``cosine`` to the normal."""
    c = np.clip(cosine, 1e-9, 1.0)
    tan2 = (1.0 - c * c) / (c * c)
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * tan2))


def ggx_annuli(roughness: float, edges: np.ndarray) -> np.ndarray:
    """(len(edges) - 1,) share of the reflected radiance of a GGX surface of ``roughness``,
    seen along its normal, in each annulus [edges[i], edges[i + 1]) of angle (radians) from
    the mirror direction; the shares sum to 1 (energy kept, as Blender's multiple-scattering
    GGX keeps it). At normal incidence a direction t off the normal reflects off the
    microfacet at t / 2: D(t / 2) G1(1) G1(cos t) / 4 per solid angle."""
    alpha2 = float(roughness) ** 4
    t = np.linspace(0.0, np.pi / 2, 8001)[1:]
    half = np.cos(t / 2)
    d = alpha2 / (np.pi * (half * half * (alpha2 - 1.0) + 1.0) ** 2)
    density = d * smith_g1(1.0, alpha2) * smith_g1(np.cos(t), alpha2) / 4 * 2 * np.pi * np.sin(t)
    cumulative = np.concatenate(([0.0], np.cumsum(density))) * (t[1] - t[0])
    at = np.interp(np.clip(edges, 0, np.pi / 2), np.concatenate(([0.0], t)), cumulative)
    return np.diff(at) / cumulative[-1]


def _gaussian_annuli(sigma: float, edges: np.ndarray) -> np.ndarray:
    """Share of a Gaussian of ``sigma`` radians over the sphere in each annulus (its small-angle
    form, the one prefilter.py applies)."""
    return np.diff(1.0 - np.exp(-(edges**2) / (2.0 * sigma * sigma)))


@functools.lru_cache(maxsize=64)
def lobe(roughness: float) -> tuple[tuple[float, float], ...]:
    """((weight, sigma in radians), ...): the Gaussians whose sum fits the GGX lobe of
    ``roughness`` (0..1) at normal incidence, widths alpha x 1, 2, 4, ... up to MAX_SIGMA,
    weights >= 0 summing to 1, fitted on the share per annulus with each annulus's error
    relative to its own share (so the tail counts as much as the core)."""
    alpha = max(float(roughness) ** 2, 1e-4)
    sigmas = [alpha]
    while sigmas[-1] * 2.0 <= MAX_SIGMA:
        sigmas.append(sigmas[-1] * 2.0)
    core = np.linspace(0.0, 6.0 * alpha, 31)
    tail = np.linspace(min(6.0 * alpha, np.pi / 2), np.pi / 2, _TAIL_BINS + 1)[1:]
    edges = np.unique(np.concatenate((core, tail)))
    edges = edges[edges <= np.pi / 2]
    target = ggx_annuli(roughness, edges)
    weight = 1.0 / np.sqrt(np.maximum(target, 1e-9))
    basis = np.stack([_gaussian_annuli(s, edges) for s in sigmas], 1)
    best, best_error = None, np.inf
    # Non-negative least squares by trying every subset: at most seven widths.
    for size in range(1, len(sigmas) + 1):
        for subset in itertools.combinations(range(len(sigmas)), size):
            a = basis[:, subset] * weight[:, None]
            w, *_ = np.linalg.lstsq(a, target * weight, rcond=None)
            if (w < 0).any():
                continue
            error = float(np.sum((a @ w - target * weight) ** 2))
            if error < best_error:
                best, best_error = dict(zip(subset, w)), error
    total = sum(best.values())
    return tuple((best[i] / total, sigmas[i]) for i in sorted(best))


@functools.lru_cache(maxsize=64)
def dominant_shift(roughness: float) -> tuple[float, float, float]:
    """The fit of the GGX lobe's centre toward the normal, for one roughness.

    The lobe's centre (the mean of its reflected directions, weighted by the radiance they carry)
    is normalize(R + t (N - R)), R the mirror direction, N the normal, t = x (a + x (b + x c))
    and x = 1 - cos(view angle).

    Parameters
    ----------
    roughness : float
        Blender's, 0..1 (alpha = roughness^2).

    Returns
    -------
    (a, b, c) : tuple of 3 floats
        Least squares on views 4-88 degrees off the normal (deterministic quadrature over the
        microfacet normals, sampled through the GGX distribution's inverse).
    """
    alpha2 = float(roughness) ** 4
    n = 96
    u = (np.arange(n) + 0.5) / n
    cos_h = np.sqrt((1.0 - u) / (1.0 + (alpha2 - 1.0) * u))
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    phi = 2.0 * np.pi * u
    h = np.stack(
        (np.outer(sin_h, np.cos(phi)), np.outer(sin_h, np.sin(phi)), np.outer(cos_h, np.ones(n))),
        -1,
    ).reshape(-1, 3)
    views = np.radians(np.arange(4.0, 89.0, 4.0))
    weights = []
    for theta in views:
        v = np.array((np.sin(theta), 0.0, np.cos(theta)))
        vh = h @ v
        r = 2.0 * vh[:, None] * h - v
        ok = (r[:, 2] > 0) & (vh > 0)
        # Per microfacet sample (drawn with pdf D cos_h): G (v.h) / (cos_v cos_h).
        w = np.where(ok, smith_g1(v[2], alpha2) * smith_g1(r[:, 2], alpha2) * vh, 0.0)
        w = w / (v[2] * h[:, 2])
        mean = (w[:, None] * r).sum(0)
        turn = np.arctan2(mean[0], mean[2]) + theta  # from the mirror direction (at -theta)
        # The lerp weight toward N that turns R by `turn`: R and N are theta apart.
        tan = np.tan(turn)
        weights.append(tan / (np.sin(theta) + tan * (1.0 - np.cos(theta))))
    x = 1.0 - np.cos(views)
    basis = np.stack((x, x * x, x**3), 1)
    a, b, c = np.linalg.lstsq(basis, np.array(weights), rcond=None)[0]
    return float(a), float(b), float(c)
