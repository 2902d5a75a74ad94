"""The 3D scenes as plain descriptions, drawn from seeds (no bpy): camera, subject, ground,
neighbours, dome. `build.py` turns one into a Blender scene.

World frame: Blender's, +Z up, the ground is z = 0, the camera stands above the origin and looks
along +Y, tilted down by `pitch_deg`. Lengths in metres, angles in degrees.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..polyhaven import NAMES as POLYHAVEN
from ..polyhaven import PREFIX

# Six of Blender's eight bundled HDRIs make the scenes; two are held out for later checks.
HDRIS = ("city", "courtyard", "interior", "studio", "sunrise", "sunset")
HELD_OUT = ("forest", "night")
SHAPES = ("sphere", "torus", "suzanne", "car")
GROUNDS = ("checker", "brick", "noise")
SEEDS = tuple(range(101, 117))  # the full set: 16 scenes
QUICK_SEEDS = (101, 103)  # the quick subset (a sphere and Suzanne, two HDRIs)

SENSOR_MM = 36.0
ASPECT = 16 / 9  # render width / height


@dataclass
class Neighbour:
    """A box standing on the ground: where (centre of its base), how big, which way, colour."""

    role: str  # "beside", "behind" (the subject) or "behind camera"
    x: float
    y: float
    size: tuple  # (width, depth, height)
    yaw_deg: float
    colour: tuple


@dataclass
class Companion:
    """Another mirror object standing on the ground beside the subject (the inter-reflection
    cases): its shape, largest dimension, base centre and turn about the vertical."""

    shape: str
    size: float
    x: float
    y: float
    yaw_deg: float


@dataclass
class Scene3D:
    seed: int
    index: int
    hdri: str
    hdri_rotation_deg: float
    camera_height: float
    pitch_deg: float  # downward tilt
    lens_mm: float
    shape: str
    size: float  # the subject's largest dimension
    distance: float  # ground distance from the camera to the subject's centre
    azimuth_deg: float  # the subject's bearing from the view direction (+ to the right)
    subject_yaw_deg: float
    ground: str
    ground_scale: float  # texture repeats per metre
    ground_colours: tuple
    neighbours: list = field(default_factory=list)
    # the failure cases only (defaults leave the ordinary scenes, and their JSON, unchanged)
    lift: float = 0.0  # the subject's lowest point above the ground (floating, or on a pedestal)
    case: str = ""  # the failure case's name
    # the inter-reflection cases only: more mirror objects beside the subject
    companions: list = field(default_factory=list)

    @property
    def name(self) -> str:
        if self.case:
            return f"{self.case}_{self.shape}_{self.hdri}"
        return f"s{self.seed}_{self.shape}_{self.hdri}"

    @property
    def subject_xy(self) -> tuple:
        a = math.radians(self.azimuth_deg)
        return (self.distance * math.sin(a), self.distance * math.cos(a))

    def hfov_deg(self) -> float:
        return math.degrees(2 * math.atan(SENSOR_MM / 2 / self.lens_mm))

    def to_json(self) -> dict:
        d = asdict(self)
        for key in ("lift", "case", "companions"):  # absent from the ordinary scenes' records
            if not d[key]:
                del d[key]
        d["name"] = self.name
        d["hfov_deg"] = round(self.hfov_deg(), 2)
        return d


def _colour(rng, saturation=(0.35, 0.9), value=(0.25, 0.85)) -> tuple:
    h = rng.uniform()
    s, v = rng.uniform(*saturation), rng.uniform(*value)
    i = int(h * 6) % 6
    f = h * 6 - int(h * 6)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    rgb = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i]
    return tuple(round(c**2.2, 4) for c in rgb)  # linear


def _project(cam_h, pitch, half_w, half_h, point):
    """(u, v, depth) of a world point on the frame, u, v in [-1, 1] inside it (v up)."""
    x, y, z = point
    c, s = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    depth = y * c - (z - cam_h) * s  # along the view direction (0, cos, -sin)
    up = y * s + (z - cam_h) * c  # along the camera's up (0, sin, cos)
    return x / depth / half_w, up / depth / half_h, depth


def _fits(cam_h, pitch, lens, size, distance, azimuth, centre_height) -> bool:
    """The subject's bounding sphere lies inside the frame (a margin kept) and spans 12-50 %
    of the frame's height."""
    half_w = SENSOR_MM / 2 / lens
    half_h = half_w / ASPECT
    a = math.radians(azimuth)
    centre = (distance * math.sin(a), distance * math.cos(a), centre_height)
    u, v, depth = _project(cam_h, pitch, half_w, half_h, centre)
    if depth <= 1.0:
        return False
    radius = size / 2 / depth  # angular radius, in tangent units
    span = 2 * radius / (2 * half_h)
    ru, rv = radius / half_w, radius / half_h
    return 0.12 <= span <= 0.5 and abs(u) + ru < 0.9 and abs(v) + rv < 0.9


def centre_height(shape: str, size: float) -> float:
    """Height of the subject's bounding-sphere centre above the ground (build.py's shapes)."""
    return {"sphere": 0.5, "torus": 0.5, "suzanne": 0.4, "car": 0.17}[shape] * size


def make_scene(seed: int, index: int, hdri: str | None = None, shape: str | None = None) -> Scene3D:
    """Scene `index` of a set, drawn from `seed`: its HDRI and subject cycle through HDRIS and
    SHAPES by `index` unless given."""
    rng = np.random.default_rng(seed)
    hdri = hdri or HDRIS[index % len(HDRIS)]
    shape = shape or SHAPES[index % len(SHAPES)]
    for _ in range(10000):
        cam_h = rng.uniform(1.4, 1.8)
        lens = float(np.exp(rng.uniform(math.log(24), math.log(85))))
        distance = rng.uniform(3.0, 10.0)
        size = rng.uniform(0.3, 1.5)
        half_w = math.degrees(math.atan(SENSOR_MM / 2 / lens))
        azimuth = rng.uniform(-0.45, 0.45) * half_w
        # tilt so the subject sits in the lower-middle part of the frame, within 2-15 degrees
        below = math.degrees(math.atan2(cam_h - centre_height(shape, size), distance))
        pitch = float(np.clip(below - rng.uniform(-0.1, 0.35) * half_w / ASPECT, 2.0, 15.0))
        if _fits(cam_h, pitch, lens, size, distance, azimuth, centre_height(shape, size)):
            break
    else:  # pragma: no cover - the ranges above always leave room
        raise RuntimeError(f"no camera fits seed {seed}")
    scene = Scene3D(
        seed=seed,
        index=index,
        hdri=hdri,
        hdri_rotation_deg=round(rng.uniform(0, 360), 1),
        camera_height=round(cam_h, 3),
        pitch_deg=round(pitch, 2),
        lens_mm=round(lens, 1),
        shape=shape,
        size=round(size, 3),
        distance=round(distance, 3),
        azimuth_deg=round(azimuth, 2),
        subject_yaw_deg=round(rng.uniform(-60, 60), 1),
        ground=GROUNDS[int(rng.integers(len(GROUNDS)))],
        ground_scale=round(rng.uniform(0.6, 2.0), 2),
        ground_colours=(_colour(rng, value=(0.35, 0.85)), _colour(rng, value=(0.1, 0.5))),
    )
    sx, sy = scene.subject_xy
    side = 1.0 if rng.uniform() < 0.5 else -1.0
    # beside the subject, never nearer the camera (so nothing hides it)
    w = rng.uniform(0.3, 1.0)
    scene.neighbours.append(
        Neighbour(
            "beside",
            round(sx + side * (size / 2 + w / 2 + rng.uniform(0.3, 1.2)), 3),
            round(sy + rng.uniform(0.2, 1.5), 3),
            (round(w, 3), round(rng.uniform(0.3, 1.0), 3), round(rng.uniform(0.4, 1.6), 3)),
            round(rng.uniform(0, 90), 1),
            _colour(rng),
        )
    )
    scene.neighbours.append(
        Neighbour(
            "behind",
            round(sx - side * rng.uniform(0.0, 1.5), 3),
            round(sy + size / 2 + rng.uniform(1.5, 4.0), 3),
            (
                round(rng.uniform(1.0, 3.0), 3),
                round(rng.uniform(0.3, 1.0), 3),
                round(rng.uniform(1.2, 2.8), 3),
            ),
            round(rng.uniform(-30, 30), 1),
            _colour(rng),
        )
    )
    scene.neighbours.append(  # a wall behind the camera: only a reflection shows it
        Neighbour(
            "behind camera",
            round(rng.uniform(-1.5, 1.5), 3),
            round(-rng.uniform(2.0, 5.0), 3),
            (round(rng.uniform(2.0, 4.0), 3), 0.3, round(rng.uniform(1.8, 3.0), 3)),
            round(rng.uniform(-20, 20), 1),
            _colour(rng),
        )
    )
    return scene


def scene_set(quick: bool = False) -> list:
    seeds = QUICK_SEEDS if quick else SEEDS
    return [make_scene(seed, SEEDS.index(seed)) for seed in seeds]


MORE_SEEDS = tuple(range(117, 149))  # the default set drawn further: 32 scenes more


def more_set(quick: bool = False) -> list:
    """32 scenes more, drawn by `scene_set`'s own rule as if its seeds ran on (117-148, set
    indices 16-47: the same six HDRIs and four shapes in turn; quick: the first two): how
    far the 16 scenes' mean is from what scenes drawn this way give (the sampling error)."""
    seeds = MORE_SEEDS[:2] if quick else MORE_SEEDS
    return [make_scene(seed, len(SEEDS) + i) for i, seed in enumerate(seeds)]


HELD_OUT_SEEDS = tuple(range(201, 209))  # eight scenes under the two held-out HDRIs


def held_out_set(quick: bool = False) -> list:
    """Scenes drawn as `scene_set`'s but under the HDRIs nothing was tuned on (HELD_OUT):
    every shape under each of them, from the seeds 201-208 (quick: the first two)."""
    seeds = HELD_OUT_SEEDS[:2] if quick else HELD_OUT_SEEDS
    return [
        make_scene(
            seed,
            i,
            hdri=HELD_OUT[i % len(HELD_OUT)],
            shape=SHAPES[(i // len(HELD_OUT)) % len(SHAPES)],
        )
        for i, seed in enumerate(seeds)
    ]


POLYHAVEN_SEEDS = tuple(range(301, 331))  # 30 scenes under the 15 Poly Haven HDRIs


def polyhaven_set(quick: bool = False) -> list:
    """Scenes drawn as `scene_set`'s but under the 15 Poly Haven HDRIs of study/polyhaven.py
    (none of Blender's; nothing in the add-on was chosen on them), two scenes each with two
    different shapes, from the seeds 301-330 (quick: the first two)."""
    seeds = POLYHAVEN_SEEDS[:2] if quick else POLYHAVEN_SEEDS
    n = len(POLYHAVEN)
    return [
        make_scene(
            seed,
            i,
            hdri=PREFIX + POLYHAVEN[i % n],
            shape=SHAPES[(i + 2 * (i // n)) % len(SHAPES)],  # the second turn: another shape
        )
        for i, seed in enumerate(seeds)
    ]


# --- failure cases (issue 11, item 5) -----------------------------------------------------------

FAILURE_BASE = (105, 4)  # s105_sphere_sunrise: 48 mm, 7.3 m, a 0.64 m sphere, 8.4 degrees down
QUICK_FAILURES = ("f1_floating",)


def frame_extent(spec: Scene3D) -> tuple:
    """(u, v, span, reach) of the subject's bounding sphere on the frame: centre (u, v in
    [-1, 1], v up), its diameter as a share of the frame's height, and max(|u| + ru, |v| + rv)
    (under 1: inside the frame)."""
    half_w = SENSOR_MM / 2 / spec.lens_mm
    half_h = half_w / ASPECT
    centre = (*spec.subject_xy, spec.lift + centre_height(spec.shape, spec.size))
    u, v, depth = _project(spec.camera_height, spec.pitch_deg, half_w, half_h, centre)
    radius = spec.size / 2 / depth
    ru, rv = radius / half_w, radius / half_h
    return u, v, radius / half_h, max(abs(u) + ru, abs(v) + rv)


def _pedestal(spec: Scene3D, width: float) -> Neighbour:
    sx, sy = spec.subject_xy
    return Neighbour(
        "pedestal", round(sx, 3), round(sy, 3), (width, width, spec.lift), 0.0, (0.35, 0.35, 0.33)
    )


def _variant(base: Scene3D, case: str, **changes) -> Scene3D:
    """``base`` with ``changes``; the neighbours near the subject (beside, behind) follow it:
    moved by the subject's displacement and pushed out by half its growth."""
    spec = replace(base, case=case, neighbours=[], **changes)
    (bx, by), (sx, sy) = base.subject_xy, spec.subject_xy
    grow = max(0.0, (spec.size - base.size) / 2)
    for n in base.neighbours:
        if n.role == "behind camera":
            spec.neighbours.append(n)
            continue
        x, y = n.x + sx - bx, n.y + sy - by
        if n.role == "beside":
            x += math.copysign(grow, n.x - bx)
        y += grow
        spec.neighbours.append(replace(n, x=round(x, 3), y=round(y, 3)))
    return spec


def _aim(spec: Scene3D) -> float:
    """The pitch (degrees down) that puts the subject's centre at the frame's middle row."""
    drop = spec.camera_height - spec.lift - centre_height(spec.shape, spec.size)
    return round(math.degrees(math.atan2(drop, spec.distance)), 2)


def failure_set(quick: bool = False) -> list:
    """Six variations of one ordinary scene (s105), each a way the add-on's model can fail:
    floating subject, camera looking up, a plate of only a wall, the subject at the frame's
    border, covering most of the plate, tiny."""
    base = make_scene(*FAILURE_BASE)
    cases = []
    # (1) floating 0.75 m above the ground: the add-on takes the subject's lowest point as
    # the ground unless a Ground object is chosen
    cases.append(_variant(base, "f1_floating", lift=0.75))
    # (2) looking up 15 degrees at a sphere on a 2.5 m column: no ground in the plate
    up = _variant(
        base,
        "f2_looking_up",
        lift=2.5,
        distance=5.0,
        size=0.6,
        lens_mm=50.0,
        pitch_deg=-15.0,
        azimuth_deg=0.0,
    )
    up.neighbours.append(_pedestal(up, 0.4))
    cases.append(up)
    # (3) a wall 2 m in front of the camera fills the plate; the sphere on a pedestal before it
    wall = _variant(
        base, "f3_wall", lift=1.2, distance=1.4, size=0.35, lens_mm=40.0, azimuth_deg=0.0
    )
    wall.pitch_deg = _aim(wall)
    wall.neighbours = [n for n in wall.neighbours if n.role == "behind camera"]
    wall.neighbours.append(
        Neighbour("wall ahead", 0.0, 2.15, (8.0, 0.3, 4.0), 0.0, (0.45, 0.32, 0.22))
    )
    wall.neighbours.append(_pedestal(wall, 0.3))
    cases.append(wall)
    # (4) at the frame's right border (its bounding sphere touching it)
    border = _variant(base, "f4_border", azimuth_deg=base.azimuth_deg)
    half_w = math.degrees(math.atan(SENSOR_MM / 2 / base.lens_mm))
    for k in range(200):
        border.azimuth_deg = round(half_w * k / 200, 2)
        if frame_extent(border)[3] > 0.97:
            break
    cases.append(_variant(base, "f4_border", azimuth_deg=border.azimuth_deg))
    # (5) a 2.2 m sphere 3.3 m away: most of the plate
    large = _variant(base, "f5_large", size=2.2, distance=3.3, lens_mm=35.0, azimuth_deg=0.0)
    large.pitch_deg = _aim(large)
    cases.append(large)
    # (6) a 0.15 m sphere 8 m away: a few percent of the frame's height
    cases.append(_variant(base, "f6_tiny", size=0.15, distance=8.0))
    if quick:
        cases = [c for c in cases if c.case in QUICK_FAILURES]
    return cases


# --- inter-reflection cases (issue 11, item 4) ---------------------------------------------------

QUICK_INTER = ("i1_two_spheres",)


def _row(base: Scene3D, case, hdri, lens, depth, objects) -> Scene3D:
    """Mirror objects in a row across the view, ``depth`` metres ahead of the camera, their
    surfaces ``gap`` apart: ``objects`` is [(shape, size, gap before the next, yaw)], the first
    the subject. The base scene gives the dome's turn, the ground, the wall behind the camera and
    the box behind (moved behind the row); its box beside the subject is left out (the other
    mirrors stand there). The camera looks at the row's middle."""
    width = sum(size for _, size, _, _ in objects) + sum(gap for _, _, gap, _ in objects[:-1])
    x = -width / 2
    placed = []
    for shape, size, gap, yaw in objects:
        placed.append((shape, size, round(x + size / 2, 3), yaw))
        x += size + gap
    shape, size, sx, yaw = placed[0]
    spec = replace(
        base,
        case=case,
        hdri=hdri,
        lens_mm=lens,
        shape=shape,
        size=size,
        distance=round(math.hypot(sx, depth), 3),
        azimuth_deg=round(math.degrees(math.atan2(sx, depth)), 2),
        subject_yaw_deg=yaw,
        neighbours=[],
        companions=[Companion(s, z, cx, depth, w) for s, z, cx, w in placed[1:]],
    )
    bx, by = base.subject_xy
    for n in base.neighbours:
        if n.role == "behind camera":
            spec.neighbours.append(n)
        elif n.role == "behind":
            y = n.y - by + depth + max(size for _, size, _, _ in objects) / 2
            spec.neighbours.append(replace(n, x=round(n.x - bx, 3), y=round(y, 3)))
    tallest = max(objects, key=lambda o: centre_height(o[0], o[1]))
    drop = spec.camera_height - centre_height(tallest[0], tallest[1])
    spec.pitch_deg = round(math.degrees(math.atan2(drop, depth)), 2)
    return spec


def mirrors(spec: Scene3D) -> list:
    """[(shape, size, x, y, yaw)] of every mirror object: the subject first."""
    return [(spec.shape, spec.size, *spec.subject_xy, spec.subject_yaw_deg)] + [
        (c.shape, c.size, c.x, c.y, c.yaw_deg) for c in spec.companions
    ]


def inter_set(quick: bool = False) -> list:
    """Two or three mirror objects side by side on the ground, a few tens of centimetres
    apart (issue 11, item 4): each sees the others large. Four HDRIs, lenses 28-50 mm; the
    rest (dome turn, ground, the walls) from ordinary scenes' seeds."""
    cases = [
        _row(
            make_scene(101, 0),
            "i1_two_spheres",
            "city",
            40.0,
            5.5,
            [("sphere", 0.8, 0.25, 0.0), ("sphere", 0.8, 0.0, 0.0)],
        ),
        _row(
            make_scene(105, 4),
            "i2_sphere_torus",
            "sunrise",
            50.0,
            6.5,
            [("sphere", 0.7, 0.2, 0.0), ("torus", 0.8, 0.0, 55.0)],
        ),
        _row(
            make_scene(102, 1),
            "i3_three",
            "courtyard",
            32.0,
            4.5,
            [("sphere", 0.6, 0.2, 0.0), ("suzanne", 0.6, 0.2, -20.0), ("torus", 0.7, 0.0, 40.0)],
        ),
        _row(
            make_scene(106, 5),
            "i4_big_small",
            "sunset",
            28.0,
            4.0,
            [("sphere", 1.0, 0.15, 0.0), ("sphere", 0.45, 0.0, 0.0)],
        ),
    ]
    if quick:
        cases = [c for c in cases if c.case in QUICK_INTER]
    return cases


def frame_reach(spec: Scene3D) -> float:
    """max(|u| + ru, |v| + rv) over every mirror's bounding sphere (under 1: all inside the
    frame)."""
    half_w = SENSOR_MM / 2 / spec.lens_mm
    half_h = half_w / ASPECT
    reach = 0.0
    for shape, size, x, y, _ in mirrors(spec):
        centre = (x, y, spec.lift + centre_height(shape, size))
        u, v, depth = _project(spec.camera_height, spec.pitch_deg, half_w, half_h, centre)
        radius = size / 2 / depth
        reach = max(reach, abs(u) + radius / half_w, abs(v) + radius / half_h)
    return reach
