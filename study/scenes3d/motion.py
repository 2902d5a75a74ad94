"""Motion (issue 11, item 5): does the map change smoothly with the motion? (no bpy)

Two sequences built on the failure cases' base scene (s105: a 0.64 m mirror sphere 7.3 m away
under the sunrise HDRI, 48 mm, 8.4 degrees down):

- `m1_sliding`: the sphere slides along the ground toward the camera and out past the frame's
  right border (the camera still), so the ground points it reflects cross the right border;
- `m2_dolly`: the camera dollies 2 m forward and pans left (the sphere still), so the plate
  itself moves and the sphere drifts toward the right border, growing.

Per frame (`motion_run.py`, bpy): the plate, the truth (mirror and rough 0.35) and each of the
add-on's Camera View + Ground and Camera View in the Replace look (mirror) and the World look
(rough 0.35), run as Update Every Frame runs them: Generate at the first frame, then
`sequence.update` per frame from the plate sequence. Here: the per-pair change measures, the
popping rule, the tables and the chart.

Change between frames k and k + 1 of a column (the truth or a method), on the subject's pixels
(display values, the mask eroded by a pixel so the rim's mix with the background stays out):

- `aligned`: the mean absolute difference of the subject's pixels after aligning frame k + 1 to
  frame k by the subject's screen motion (its projected centre moves and its radius scales:
  a similarity; bilinear);
- `mean`: the change of the subject's mean colour (mean over channels of the absolute change).

Ratio: a method's change over the truth's, per pair. A pair *pops* when a method's change is
above FLOOR and more than POP times the median of its neighbouring pairs' (up to two on each
side), and that jump is more than POP times the truth's own jump at the pair (`pops`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from .scenes import ASPECT, SENSOR_MM, Scene3D, make_scene

BASE = (105, 4)  # the failure cases' base scene, s105_sphere_sunrise
POP = 3.0  # a change this many times its neighbours' median pops ...
FLOOR = 0.003  # ... when it is also above this (display units; 0.77 of an 8-bit code value)
NEIGHBOURS = 2  # pairs on each side whose median a pair is compared with
MEASURES = ("aligned", "mean")
TRUTH = "Truth"
# (look, the truth's material, the add-on's combine mode)
LOOKS = (("mirror", 0.0, "REPLACE"), ("rough 0.35", 0.35, "WORLD"))
METHODS = ("GROUND", "CAMERA")  # the add-on's default and the method before it


@dataclass(frozen=True)
class Pose:
    """One frame: the subject's ground position, the camera's (at the spec's height) and its
    pan (degrees, + turns left; the tilt stays the spec's)."""

    subject_xy: tuple
    camera_xy: tuple = (0.0, 0.0)
    pan_deg: float = 0.0


@dataclass
class Motion:
    name: str
    what: str
    spec: Scene3D
    poses: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {
            "name": self.name,
            "what": self.what,
            "scene": self.spec.to_json(),
            "poses": [asdict(p) for p in self.poses],
        }


def _lerp(a, b, t):
    return tuple(round(x + (y - x) * t, 4) for x, y in zip(a, b))


def screen(spec: Scene3D, pose: Pose) -> tuple:
    """(u, v, ru, rv) of the subject's bounding sphere on the frame for ``pose``: centre in
    [-1, 1] (v up) and radius in frame half-widths / half-heights."""
    from .scenes import centre_height

    half_w = SENSOR_MM / 2 / spec.lens_mm
    half_h = half_w / ASPECT
    yaw, pitch = math.radians(pose.pan_deg), math.radians(spec.pitch_deg)
    x = pose.subject_xy[0] - pose.camera_xy[0]
    y = pose.subject_xy[1] - pose.camera_xy[1]
    z = spec.lift + centre_height(spec.shape, spec.size) - spec.camera_height
    # the camera's heading (0, 1) turned left by the pan; right = heading turned right
    fx, fy = -math.sin(yaw), math.cos(yaw)
    ahead = x * fx + y * fy
    right = x * fy - y * fx
    depth = ahead * math.cos(pitch) - z * math.sin(pitch)
    up = ahead * math.sin(pitch) + z * math.cos(pitch)
    radius = spec.size / 2 / depth
    return right / depth / half_w, up / depth / half_h, radius / half_w, radius / half_h


def motion_set(quick: bool = False, frames: int = 14) -> list:
    """The two sequences (``frames`` each); with ``quick`` the sliding sphere alone."""
    base = make_scene(*BASE)
    base.neighbours = [n for n in base.neighbours if n.role != "beside"]  # out of the path
    sliding = Motion(
        "m1_sliding",
        "the sphere slides toward the camera and out past the right border, camera still",
        base,
    )
    start, end = (0.0, 8.0), (2.25, 6.0)
    for k in range(frames):
        sliding.poses.append(Pose(_lerp(start, end, k / (frames - 1))))
    dolly = Motion(
        "m2_dolly",
        "the camera dollies 2 m forward and pans 15 degrees left, the sphere still",
        base,
    )
    for k in range(frames):
        t = k / (frames - 1)
        dolly.poses.append(
            Pose(base.subject_xy, _lerp((0.0, 0.0), (0.0, 2.0), t), round(15.0 * t, 3))
        )
    return [sliding] if quick else [sliding, dolly]


# --- the change measures (numpy) -----------------------------------------------------------------


def erode(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: ``mask`` shrunk by one pixel (4-neighbourhood)."""
    m = np.asarray(mask, bool)
    out = m.copy()
    out[1:, :] &= m[:-1, :]
    out[:-1, :] &= m[1:, :]
    out[:, 1:] &= m[:, :-1]
    out[:, :-1] &= m[:, 1:]
    return out


def _bilinear(image, x, y):
    """``image`` (H, W, C) at continuous pixel positions (pixel centres at i + 0.5)."""
    h, w = image.shape[:2]
    x = np.clip(x - 0.5, 0, w - 1)
    y = np.clip(y - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    ax, ay = (x - x0)[:, None], (y - y0)[:, None]
    top = image[y0, x0] * (1 - ax) + image[y0, x1] * ax
    bottom = image[y1, x0] * (1 - ax) + image[y1, x1] * ax
    return top * (1 - ay) + bottom * ay


def _matched(a, b, mask_a, mask_b, centre_a, centre_b, scale):
    """The subject's pixels seen in both frames: ((N, 3) of ``a``, (N, 3) of ``b``) for each
    pixel p of eroded ``mask_a`` and ``b`` at centre_b + scale (p - centre_a) (the subject's
    screen motion: pixel positions, x right, y down; bilinear), where that lands inside eroded
    ``mask_b``."""
    ma, mb = erode(mask_a), erode(mask_b)
    ys, xs = np.nonzero(ma)
    px = centre_b[0] + scale * (xs + 0.5 - centre_a[0])
    py = centre_b[1] + scale * (ys + 0.5 - centre_a[1])
    h, w = mb.shape
    ix, iy = np.floor(px).astype(int), np.floor(py).astype(int)
    inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    keep = inside.copy()
    keep[inside] = mb[iy[inside], ix[inside]]
    got = _bilinear(np.asarray(b, np.float64), px[keep], py[keep])
    return np.asarray(a, np.float64)[ys[keep], xs[keep]], got


def aligned_change(a, b, mask_a, mask_b, centre_a, centre_b, scale) -> float:
    """Mean absolute difference (over pixels and channels) of display images ``a`` and ``b``
    ((H, W, 3)) on the subject's pixels seen in both (`_matched`). NaN when none is."""
    pa, pb = _matched(a, b, mask_a, mask_b, centre_a, centre_b, scale)
    return float(np.mean(np.abs(pb - pa))) if len(pa) else float("nan")


def mean_change(a, b, mask_a, mask_b, centre_a, centre_b, scale) -> float:
    """The change of the subject's mean display colour over its pixels seen in both frames
    (`_matched`; a part leaving the frame does not count), mean over channels of |change|."""
    pa, pb = _matched(a, b, mask_a, mask_b, centre_a, centre_b, scale)
    return float(np.mean(np.abs(pb.mean(0) - pa.mean(0)))) if len(pa) else float("nan")


def changes(frames: list) -> dict:
    """{measure: [change per pair]} of a column; ``frames``: per frame (display (H, W, 3),
    mask (H, W) bool, centre (x, y) pixels, radius pixels)."""
    out = {m: [] for m in MEASURES}
    for (a, ma, ca, ra), (b, mb, cb, rb) in zip(frames, frames[1:]):
        out["aligned"].append(aligned_change(a, b, ma, mb, ca, cb, rb / ra))
        out["mean"].append(mean_change(a, b, ma, mb, ca, cb, rb / ra))
    return out


def _neighbour_median(values, k) -> float:
    around = [
        values[j]
        for j in range(max(0, k - NEIGHBOURS), min(len(values), k + NEIGHBOURS + 1))
        if j != k and math.isfinite(values[j])
    ]
    return float(np.median(around)) if around else float("nan")


def pops(method: list, truth: list, pop=POP, floor=FLOOR) -> list:
    """The pairs (indices) where ``method``'s change pops and ``truth``'s does not: the
    method's change is above ``floor`` and more than ``pop`` times its neighbours' median, and
    that jump factor is more than ``pop`` times the truth's own at the pair (where the truth
    changes more than usual too -- the subject enters a shadow -- the method may follow)."""
    out = []
    for k, (m, t) in enumerate(zip(method, truth)):
        if not (math.isfinite(m) and m > floor):
            continue
        jump = m / max(_neighbour_median(method, k), floor / pop)
        t_near = _neighbour_median(truth, k)
        t_jump = t / t_near if math.isfinite(t) and t_near > 0 else 1.0
        if jump > pop * max(1.0, t_jump):
            out.append(k)
    return out


def summarise(method: dict, truth: dict) -> dict:
    """Per measure: ratios per pair, their median and max, and the popping pairs."""
    out = {}
    for m in MEASURES:
        ratio = [
            a / b if b > 1e-9 and math.isfinite(a) and math.isfinite(b) else float("nan")
            for a, b in zip(method[m], truth[m])
        ]
        finite = [r for r in ratio if math.isfinite(r)]
        out[m] = {
            "ratio": ratio,
            "median_ratio": float(np.median(finite)) if finite else float("nan"),
            "max_ratio": float(max(finite)) if finite else float("nan"),
            "pops": pops(method[m], truth[m]),
        }
    return out


def column(method: str, look: str) -> str:
    return f"{method} {look}"
