"""The accuracy study: ground truth from Blender's HDRIs, every method on every case, numbers.

Ground truth. Blender ships eight CC0 Poly Haven HDRIs (`<bpy>/<version>/datafiles/
studiolights/world/*.exr`, 1024 x 512); their whole surroundings are known. A *view* is a
pinhole camera at the HDRI's centre (heading, pitch, horizontal field of view); from it come

- the plate `(H, W, 3)`: `panorama.perspective_plate` (3 x 3 supersampled, scene-linear), as an
  EXR-like float plate and as an LDR plate (sRGB-encoded, clipped, quantised to 8 bits and
  decoded: the best an 8-bit photograph can give);
- the truth: the whole surroundings in the camera frame, every texel the mean radiance over its
  footprint (`truth_latlong`, from `panorama.ground_truth_latlong`), and the LDR-clipped truth:
  the truth of the world clipped at 1.0 (what an LDR plate can at best recover; clipped before
  any filtering, as a camera clips each pixel).

Each view is exposed like a photograph: plate and truth are scaled so that the plate's
log-average luminance is 0.18 (Reinhard's key), so scenes average fairly. A *placement* puts the
object (a square bbox, in plate pixels) somewhere on the plate.

A *case* is a view and a placement. Every method builds a map from the plate and bbox; the map and
the truth are rendered as mirror, matte-silver and diffuse spheres (`spheres.py`) seen from the
camera along the object's direction (the bbox centre's ray), and compared (`metrics.py`). The
map itself is also compared over the directions the plate sees.

Comparisons: "exr/hdr" (float plate against the HDR truth), "ldr/ldr" (LDR plate against the
LDR-clipped truth) and "ldr/hdr" (LDR plate against the HDR truth).
"""

from __future__ import annotations

import functools
import importlib.util
import itertools
import math
import os
import pathlib
import platform
import sys
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from virtual_reflections.colour import decode_uint, linear_to_srgb
from virtual_reflections.mapsize import auto_map_width

from .. import panorama
from ..bench import median_ms
from ..methods import PITCH_DEG
from . import metrics as M
from . import spheres as S
from .baselines import Method, all_methods

HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")
KEY = 0.18  # log-average luminance of every plate after exposure
LUMA = np.array([0.2126, 0.7152, 0.0722])
COMPARISONS = (("exr", "hdr"), ("ldr", "ldr"), ("ldr", "hdr"))
PSNR_CAP = 100.0  # identical images: reported as 100 dB (JSON has no infinity)


@dataclass(frozen=True)
class Placement:
    """An object on the plate: a square of side `size` (fraction of the plate's height) centred
    at (`cx`, `cy`) (fractions of the plate's width and height; origin top-left, y down)."""

    name: str
    cx: float
    cy: float
    size: float

    def bbox(self, width: int, height: int):
        """(x0, y0, x1, y1) in plate pixels; may reach outside the plate (docs/conventions.md)."""
        half = 0.5 * self.size * height
        x, y = self.cx * width, self.cy * height
        return (x - half, y - half, x + half, y + half)


PLACEMENTS = (
    Placement("centred", 0.50, 0.55, 0.30),
    Placement("off-centre", 0.30, 0.65, 0.30),
    Placement("left border", 0.05, 0.55, 0.30),
    Placement("right border", 0.95, 0.55, 0.30),
    Placement("top border", 0.50, 0.08, 0.30),
    Placement("bottom border", 0.50, 0.92, 0.30),
    Placement("large", 0.50, 0.50, 0.80),
    Placement("tiny", 0.62, 0.60, 0.05),
)
PLACEMENT_NAMES = tuple(p.name for p in PLACEMENTS)


@dataclass(frozen=True)
class Config:
    """What the study covers. The defaults are the full run; `QUICK` is the one-minute subset."""

    hdris: tuple = HDRIS
    headings: tuple = (0.0, 135.0)  # degrees, added to each HDRI's own offset (HEADING_OFFSET)
    # -8 degrees: looking slightly down, as a camera over the ground an object stands on; the
    # horizon "engine camera + horizon" is given (`run_study` refuses another pitch)
    pitch: float = PITCH_DEG
    hfovs: tuple = (40.0, 60.0, 90.0)
    placements: tuple = PLACEMENT_NAMES
    plate_size: tuple = (640, 360)
    map_width: int = 512
    sphere_size: int = 128
    comparisons: tuple = COMPARISONS
    timing_repeat: int = 5
    auto: bool = True  # item 6: resolution and rough/diffuse studies


QUICK = Config(
    hdris=("courtyard", "city", "forest"),
    headings=(0.0,),
    hfovs=(60.0,),
    placements=("centred", "left border", "large", "tiny"),
    plate_size=(320, 180),
    map_width=256,
    sphere_size=64,
    comparisons=(("exr", "hdr"), ("ldr", "ldr")),
    timing_repeat=3,
    auto=False,
)

# Each HDRI's headings are offset so the first view looks at something (not at a blank wall).
HEADING_OFFSET = {
    "city": -150.0,
    "courtyard": -120.0,
    "forest": 0.0,
    "interior": 60.0,
    "night": 0.0,
    "studio": 0.0,
    "sunrise": 0.0,
    "sunset": -10.0,
}


# --- ground truth ------------------------------------------------------------------------------


_hdri_dir_override = None  # set in worker processes to the folder their parent found


def hdri_dir() -> pathlib.Path:
    """`<bpy>/<version>/datafiles/studiolights/world` of the installed bpy, found (never imported)
    as `sample_scenes/make_plates.py` does; `$VR_HDRI_DIR` overrides."""
    env = os.environ.get("VR_HDRI_DIR") or _hdri_dir_override
    if env:
        return pathlib.Path(env)
    spec = importlib.util.find_spec("bpy")
    if spec is not None and spec.submodule_search_locations:
        for location in spec.submodule_search_locations:
            # the wheel's package, or (once bpy has been imported in this process, which puts
            # Blender's scripts/modules on sys.path) <bpy>/<version>/scripts/modules/bpy
            for root in (pathlib.Path(location), *pathlib.Path(location).parents[:3]):
                found = sorted(root.glob("*/datafiles/studiolights/world")) or sorted(
                    root.glob("datafiles/studiolights/world")
                )
                if found:
                    return found[-1]
    raise FileNotFoundError(
        "Blender's studio-light HDRIs were not found: install the bpy wheel or set VR_HDRI_DIR"
    )


@functools.lru_cache(maxsize=2)
def load_hdri(name: str) -> np.ndarray:
    """Blender-convention lat-long `(512, 1024, 3)` float32 scene-linear of a bundled HDRI."""
    path = hdri_dir() / f"{name}.exr"
    if not path.is_file():
        raise FileNotFoundError(f"no HDRI {name!r} in {path.parent}")
    return panorama.load_equirect(path)


def ldr_plate(linear: np.ndarray) -> np.ndarray:
    """What an 8-bit sRGB photograph keeps of a linear plate: encode (clipping to [0, 1]),
    quantise to 8 bits, decode. `(H, W, 3)` float32 scene-linear."""
    code = np.round(linear_to_srgb(linear) * 255.0).astype(np.uint8)
    return decode_uint(code)


@dataclass
class View:
    """One camera in one HDRI, exposed; every image scene-linear Rec.709 float32."""

    hdri: str
    heading: float
    pitch: float
    hfov: float
    exposure: float  # the scale applied to the HDRI
    plates: dict  # "exr" / "ldr" -> (H, W, 3)
    truths: dict  # "hdr" / "ldr" -> (map_width/2, map_width, 3) camera-frame lat-long


def make_view(hdri, heading, pitch, hfov, plate_size, map_width) -> View:
    """Render a view's plates and truths (see the module docstring)."""
    equirect = load_hdri(hdri)
    w, h = plate_size
    plate = panorama.perspective_plate(equirect, w, h, hfov, heading, pitch, supersample=3)
    lum = plate.astype(np.float64) @ LUMA
    exposure = KEY / math.exp(float(np.mean(np.log(np.maximum(lum, 0.0) + 1e-4))))
    plate = (plate * exposure).astype(np.float32)
    rotation = panorama.camera_rotation(heading, pitch)
    truth = (truth_latlong(equirect, rotation, map_width) * exposure).astype(np.float32)
    # An LDR camera clips every pixel before anything averages it: the LDR truth is the truth of
    # the clipped world (clip, then filter), not the clipped truth map (filter, then clip).
    clipped_world = np.minimum(equirect * np.float32(exposure), 1.0)
    truth_ldr = truth_latlong(clipped_world, rotation, map_width)
    return View(
        hdri,
        heading,
        pitch,
        hfov,
        exposure,
        {"exr": plate, "ldr": ldr_plate(plate)},
        {"hdr": truth, "ldr": truth_ldr},
    )


TRUTH_RENDER_WIDTH = 1024  # the HDRIs' own width


def truth_latlong(equirect, rotation, width: int) -> np.ndarray:
    """The true map `(width/2, width, 3)`: every texel the mean radiance over its footprint.

    Rendered at the HDRI's resolution or above with 2 x 2 samples per texel
    (`panorama.ground_truth_latlong`), then averaged down by solid angle: at least 4 x 4 samples
    per texel of a 512-wide map. (Sampling at the map's own resolution would alias: a texel is
    several HDRI pixels wide.) `width` must divide 1024 or be at least 1024.
    """
    render_width = max(width, TRUTH_RENDER_WIDTH)
    if render_width % width:
        raise ValueError(f"truth width must divide {TRUTH_RENDER_WIDTH}, got {width}")
    full = panorama.ground_truth_latlong(equirect, rotation, render_width, supersample=2)
    return S.resample_latlong(full, width)


def object_direction(bbox, plate_size, hfov) -> np.ndarray:
    """Camera-frame unit direction of the bbox centre (the ray the object is seen along)."""
    w, h = plate_size
    f = panorama.focal_length_pixels(w, hfov)
    cx, cy = 0.5 * (bbox[0] + bbox[2]), 0.5 * (bbox[1] + bbox[3])
    d = np.array([-(cx - 0.5 * w) / f, -(cy - 0.5 * h) / f, 1.0])
    return d / np.linalg.norm(d)


# --- renders and metrics -------------------------------------------------------------------


@dataclass
class Renders:
    """The three spheres `(S, S, 3)` linear of one map, seen along one object's direction."""

    mirror: np.ndarray
    glossy: np.ndarray
    diffuse: np.ndarray


def render(latlong, probe: S.Probe) -> Renders:
    return Renders(*probe.render(latlong))


class Truth:
    """One truth map and its spheres for one case, with what every score reuses precomputed."""

    def __init__(self, latlong, probe: S.Probe, view_mask):
        self.renders = render(latlong, probe)
        self.mask = probe.mask
        self.display = {n: M.to_display(getattr(self.renders, n)) for n in _SPHERES}
        self.map_display = M.to_display(latlong[view_mask])
        self.view_mask = view_mask


_SPHERES = ("mirror", "glossy", "diffuse")


def score(pred: Renders, pred_map, truth: Truth) -> dict:
    """Every metric of one map and its spheres against one truth (definitions: metrics.py)."""
    out = {}
    mask = truth.mask
    for name in _SPHERES:
        p, t = getattr(pred, name)[mask], getattr(truth.renders, name)[mask]
        dp = M.to_display(p)
        out[f"{name}_psnr"] = min(M.psnr(dp, truth.display[name][mask]), PSNR_CAP)
        out[f"{name}_si_rmse"] = M.si_rmse(p, t)
        out[f"{name}_angular"] = M.angular_error(p, t)
    out["mirror_ssim"] = M.ssim(M.to_display(pred.mirror), truth.display["mirror"], mask)
    out["plate_psnr"] = min(
        M.psnr(M.to_display(pred_map[truth.view_mask]), truth.map_display), PSNR_CAP
    )
    return out


METRICS = (
    "mirror_psnr",
    "mirror_ssim",
    "mirror_si_rmse",
    "mirror_angular",
    "glossy_psnr",
    "glossy_si_rmse",
    "glossy_angular",
    "diffuse_psnr",
    "diffuse_si_rmse",
    "diffuse_angular",
    "plate_psnr",
)
HIGHER_IS_BETTER = {m: m.endswith(("psnr", "ssim")) for m in METRICS}


# --- timing --------------------------------------------------------------------------------


_NUDGE = itertools.count(1)  # every cold run in a process gets bounds never used before


def time_method(method: Method, plate, bbox, hfov, width, repeat) -> dict:
    """Median wall-clock milliseconds of one map: "cold" (bounds never seen before, so any
    lookup table is built: a new object or a moved one) and "warm" (same plate size and bounds
    again, a new frame: only the per-frame work). The bbox is moved by a hundredth of a pixel
    per cold run so no cache can answer."""
    cold = []
    for _ in range(repeat):
        moved = tuple(v + 0.01 * next(_NUDGE) for v in bbox)
        t = time.perf_counter()
        method.fn(plate, moved, hfov, width)
        cold.append(time.perf_counter() - t)
    method.fn(plate, bbox, hfov, width)
    warm = []
    for _ in range(repeat):
        t = time.perf_counter()
        method.fn(plate, bbox, hfov, width)
        warm.append(time.perf_counter() - t)
    return {"cold_ms": 1000.0 * float(np.median(cold)), "warm_ms": 1000.0 * float(np.median(warm))}


# --- the study -----------------------------------------------------------------------------


@dataclass
class Results:
    """Everything one run measured (written as JSON by the full run)."""

    config: dict
    default: str | None
    methods: list  # [{"name", "family"}]
    records: list = field(default_factory=list)  # one per case, method and comparison
    timing: dict = field(default_factory=dict)  # method -> {"cold_ms", "warm_ms"}
    auto: dict = field(default_factory=dict)  # item 6
    machine: dict = field(default_factory=dict)
    seconds: float = 0.0


def views_of(config: Config):
    """(hdri, heading, pitch, hfov) of every view of the study."""
    for hdri in config.hdris:
        for heading in config.headings:
            for hfov in config.hfovs:
                yield hdri, HEADING_OFFSET.get(hdri, 0.0) + heading, config.pitch, hfov


def _placements(config: Config):
    by_name = {p.name: p for p in PLACEMENTS}
    return [by_name[n] for n in config.placements]


def machine_info() -> dict:
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count() or 1
    return {
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cores": cores,
    }


def _view_records(config: Config, spec, methods) -> list:
    """Every record of one view: each placement, method, plate kind and comparison."""
    hdri, heading, pitch, hfov = spec
    size = config.sphere_size
    plates_needed = sorted({p for p, _ in config.comparisons})
    view = make_view(hdri, heading, pitch, hfov, config.plate_size, config.map_width)
    view_mask = M.plate_view_mask(config.map_width, *config.plate_size, hfov)
    shape = (config.map_width // 2, config.map_width, 3)
    records = []
    for placement in _placements(config):
        bbox = placement.bbox(*config.plate_size)
        probe = S.Probe(size, S.object_view(object_direction(bbox, config.plate_size, hfov)))
        truths = {k: Truth(t, probe, view_mask) for k, t in view.truths.items()}
        case = {
            "hdri": hdri,
            "heading": heading,
            "pitch": pitch,
            "hfov": hfov,
            "placement": placement.name,
            "size_px": placement.size * config.plate_size[1],
        }
        for method in methods:
            for plate_kind in plates_needed:
                env = np.asarray(
                    method.fn(view.plates[plate_kind], bbox, hfov, config.map_width), np.float32
                )
                if env.shape != shape:
                    raise ValueError(f"method {method.name} returned {env.shape}, not {shape}")
                renders = render(env, probe)
                for p_kind, t_kind in config.comparisons:
                    if p_kind == plate_kind:
                        numbers = score(renders, env, truths[t_kind])
                        records.append(
                            {
                                **case,
                                "method": method.name,
                                "family": method.family,
                                "comparison": f"{p_kind}/{t_kind}",
                                **numbers,
                            }
                        )
    return records


def _worker_view_records(config: Config, spec, folder: str) -> list:
    """`_view_records` in a worker process, with the methods `all_methods()` registers there
    (closures do not pickle) and the HDRI folder the parent found."""
    global _hdri_dir_override
    _hdri_dir_override = folder
    methods, _ = all_methods()
    return _view_records(config, spec, methods)


def default_jobs() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return max(1, os.cpu_count() or 1)


def run_study(
    config: Config = Config(), methods=None, default=None, log=None, jobs: int | None = None
) -> Results:
    """Run every method on every case of `config`; returns the Results (no files written).

    methods: list of `Method` (default: `baselines.all_methods()`, which also picks `default`).
    log: a callable taking one line of progress, or None.
    jobs: worker processes for the cases (default: the cores; 1 runs here). Given `methods`
    always run here. Timings are taken afterwards, alone.
    """
    started = time.perf_counter()
    own_methods = methods is None
    if own_methods:
        methods, default = all_methods()
        if config.pitch != PITCH_DEG:  # "camera + horizon" is given this pitch's horizon
            raise ValueError(
                f"the study's methods know the horizon of a {PITCH_DEG:g} degree pitch only, "
                f"not {config.pitch:g}: pass methods without 'engine camera + horizon'"
            )
    say = log or (lambda line: None)
    results = Results(
        config=asdict(config),
        default=default,
        methods=[{"name": m.name, "family": m.family} for m in methods],
        machine=machine_info(),
    )
    views = list(views_of(config))
    jobs = default_jobs() if jobs is None else max(1, int(jobs))
    if own_methods and jobs > 1 and len(views) > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # "spawn", not fork: a forked child would inherit the engine's thread pool
        # (parallel.py) without its threads, and wait on it for ever.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(min(jobs, len(views)), mp_context=context) as pool:
            folder = str(hdri_dir())
            futures = [pool.submit(_worker_view_records, config, v, folder) for v in views]
            for i, (spec, future) in enumerate(zip(views, futures)):
                results.records.extend(future.result())
                say(f"[{i + 1}/{len(views)}] {spec[0]} heading {spec[1]:+.0f} hfov {spec[3]:.0f}")
    else:
        for i, spec in enumerate(views):
            results.records.extend(_view_records(config, spec, methods))
            say(f"[{i + 1}/{len(views)}] {spec[0]} heading {spec[1]:+.0f} hfov {spec[3]:.0f}")
    # Timing on one representative case: the first view, the centred object, the float plate.
    hdri, heading, pitch, hfov = views[0]
    view = make_view(hdri, heading, pitch, hfov, config.plate_size, config.map_width)
    bbox = PLACEMENTS[0].bbox(*config.plate_size)
    for method in methods:
        results.timing[method.name] = time_method(
            method, view.plates["exr"], bbox, hfov, config.map_width, config.timing_repeat
        )
    say("timed every method")
    if config.auto and default is not None:
        by_name = {m.name: m for m in methods}
        results.auto = run_auto_study(config, by_name[default], log=say)
    results.seconds = time.perf_counter() - started
    return results


# --- item 6: model no more than a scene needs ---------------------------------------------------

AUTO_WIDTHS = (64, 128, 256, 512, 1024, 2048)
TRUTH_WIDTH_AUTO = 2048  # the HDRIs are 1024 wide: 2048 holds all their detail


def run_auto_study(config: Config, method: Method, log=None) -> dict:
    """Item 6 of the issue, for the product's default `method`, float plates, HDR truth.

    resolution: the mirror sphere rendered at the object's own size on screen (its bbox height in
      plate pixels, 4 x 4 samples per pixel) from maps of every width in AUTO_WIDTHS: "psnr"
      against the truth (a 2048-wide truth map); "self_psnr" against the method's own 2048-wide
      map (the detail a narrower map loses); "truth_psnr" the truth map itself brought to each
      width, against the truth (what resolution costs a perfect method); and the width
      `auto_map_width` picks.
    rough: matte-silver and diffuse spheres (at the study's sphere size) from the full map
      (study width; exact lobe convolutions) against cheap light: a pre-filtered map built from a
      128-wide map (glossy) and 9 SH coefficients of a 32-wide map (diffuse). Truth: the exact
      convolutions of the HDR truth.
    Costs are median milliseconds of building the map ("cold": new bounds) plus the filtering.
    """
    say = log or (lambda line: None)
    w, h = config.plate_size
    views = [v for v in views_of(config) if v[3] == 60.0] or list(views_of(config))
    views = views[:: max(1, len(views) // 8)][:8]  # at most one view per HDRI
    resolution, rough = [], []
    for hdri, heading, pitch, hfov in views:
        view = make_view(hdri, heading, pitch, hfov, config.plate_size, TRUTH_WIDTH_AUTO)
        plate, truth = view.plates["exr"], view.truths["hdr"]
        truth_glossy = S.prefilter(truth, S.GLOSSY_EXPONENT)
        truth_diffuse = S.prefilter(truth, 1.0)
        for placement in _placements(config):
            bbox = placement.bbox(w, h)
            rot = S.object_view(object_direction(bbox, config.plate_size, hfov))
            row = _resolution_row(config, method, plate, truth, bbox, hfov, rot, placement)
            resolution.append({"hdri": hdri, **row})
            entry = _rough_entry(
                config, method, plate, bbox, hfov, rot, truth_glossy, truth_diffuse
            )
            rough.append({"hdri": hdri, "placement": placement.name, **entry})
        say(f"auto: {hdri}")
    width_cost, rough_cost = _auto_costs(config, method, views[0])
    return {
        "method": method.name,
        "widths": list(AUTO_WIDTHS),
        "resolution": resolution,
        "width_cost": {str(k): v for k, v in width_cost.items()},
        "rough": rough,
        "rough_cost_ms": rough_cost,
    }


def _resolution_row(config, method, plate, truth, bbox, hfov, rot, placement) -> dict:
    """`run_auto_study`'s resolution row for one object: the mirror sphere at its size on
    screen from maps of every width in AUTO_WIDTHS, against the truth, against the method's
    widest map and the truth map at each width, and the width `auto_map_width` picks."""
    d = max(8, int(round(placement.size * config.plate_size[1])))
    mask = S.sphere_mask(d)
    probe = S.Probe(d, rot, mirror_samples=4)
    t_mirror = M.to_display(probe.mirror(truth))
    row = {"placement": placement.name, "object_px": d}
    renders, truth_renders = {}, {}
    for width in AUTO_WIDTHS:
        env = method.fn(plate, bbox, hfov, width)
        renders[width] = M.to_display(probe.mirror(env))
        truth_renders[width] = M.to_display(probe.mirror(S.resample_latlong(truth, width)))
    top = AUTO_WIDTHS[-1]
    # against the truth; against the method's own widest map (what resolution loses of
    # the method's detail); the truth map itself at each width (what any method loses)
    for key, ref, got in (
        ("psnr", t_mirror, renders),
        ("self_psnr", renders[top], renders),
        ("truth_psnr", t_mirror, truth_renders),
    ):
        row[key] = {str(w): min(M.psnr(got[w], ref, mask), PSNR_CAP) for w in AUTO_WIDTHS}
    row["auto_width"] = auto_map_width(d)
    return row


def _rough_entry(config, method, plate, bbox, hfov, rot, truth_glossy, truth_diffuse) -> dict:
    """`run_auto_study`'s rough entry for one object: matte-silver and diffuse spheres from the
    full map and from cheap light (a pre-filtered 128-wide map, SH9 of 128- and 32-wide maps),
    PSNR and si-RMSE against the exact convolutions of the truth."""
    size = config.sphere_size
    smask = S.sphere_mask(size)
    truth_g = S.glossy_sphere(None, size, view=rot, prefiltered=truth_glossy)
    truth_d = S.diffuse_sphere_exact(None, size, view=rot, irradiance=truth_diffuse)
    full = method.fn(plate, bbox, hfov, config.map_width)
    small = method.fn(plate, bbox, hfov, 128)
    tiny = method.fn(plate, bbox, hfov, 32)
    candidates = {
        "glossy full map": S.glossy_sphere(full, size, view=rot),
        "glossy prefiltered 128": S.glossy_sphere(
            None, size, view=rot, prefiltered=S.prefilter(small, S.GLOSSY_EXPONENT, 128)
        ),
        "diffuse full map": S.diffuse_sphere_exact(full, size, view=rot),
        "diffuse SH9 full map": S.diffuse_sphere(full, size, view=rot),
        "diffuse SH9 128": S.diffuse_sphere(small, size, view=rot),
        "diffuse SH9 32": S.diffuse_sphere(tiny, size, view=rot),
    }
    entry = {}
    for name, img in candidates.items():
        t = truth_g if name.startswith("glossy") else truth_d
        entry[name] = {
            "psnr": min(M.psnr(M.to_display(img), M.to_display(t), smask), PSNR_CAP),
            "si_rmse": M.si_rmse(img, t, smask),
        }
    return entry


def _auto_costs(config, method, first_view):
    """`run_auto_study`'s costs on the first view's centred object: (each map width's build
    times, each rough candidate's median ms: its map cold plus its filtering)."""
    w, h = config.plate_size
    hdri, heading, pitch, hfov = first_view
    view = make_view(hdri, heading, pitch, hfov, config.plate_size, 256)
    plate = view.plates["exr"]
    bbox = PLACEMENTS[0].bbox(w, h)
    width_cost = {}
    for width in AUTO_WIDTHS:
        width_cost[width] = time_method(method, plate, bbox, hfov, width, 3)
    full = method.fn(plate, bbox, hfov, config.map_width)
    small = method.fn(plate, bbox, hfov, 128)
    tiny = method.fn(plate, bbox, hfov, 32)
    filter_cost = {
        "glossy full map": median_ms(lambda: S.prefilter(full, S.GLOSSY_EXPONENT)),
        "glossy prefiltered 128": median_ms(lambda: S.prefilter(small, S.GLOSSY_EXPONENT, 128)),
        "diffuse full map": median_ms(lambda: S.prefilter(full, 1.0)),
        "diffuse SH9 full map": median_ms(lambda: S.sh9_coefficients(full)),
        "diffuse SH9 128": median_ms(lambda: S.sh9_coefficients(small)),
        "diffuse SH9 32": median_ms(lambda: S.sh9_coefficients(tiny)),
    }
    map_width_of = {
        "glossy full map": config.map_width,
        "glossy prefiltered 128": 128,
        "diffuse full map": config.map_width,
        "diffuse SH9 full map": config.map_width,
        "diffuse SH9 128": 128,
        "diffuse SH9 32": 32,
    }
    for width in {config.map_width, 128, 32} - set(width_cost):
        width_cost[width] = time_method(method, plate, bbox, hfov, width, 3)
    rough_cost = {
        name: width_cost[map_width_of[name]]["cold_ms"] + filter_cost[name] for name in filter_cost
    }
    return width_cost, rough_cost


# --- summaries -----------------------------------------------------------------------------


def records_for(results: Results, comparison: str = "exr/hdr", **where) -> list:
    return [
        r
        for r in results.records
        if r["comparison"] == comparison and all(r[k] == v for k, v in where.items())
    ]


def summarise(results: Results, comparison: str = "exr/hdr", by=None) -> dict:
    """Mean of every metric per method (and per value of the field `by`, e.g. "placement").

    Returns {method: {metric: mean}} or, with `by`, {method: {group: {metric: mean}}}.
    """
    rows = records_for(results, comparison)
    out: dict = {}
    for m in [m["name"] for m in results.methods]:
        mine = [r for r in rows if r["method"] == m]
        if not mine:
            continue
        if by is None:
            out[m] = {k: float(np.mean([r[k] for r in mine])) for k in METRICS}
        else:
            groups = {}
            for r in mine:
                groups.setdefault(r[by], []).append(r)
            out[m] = {
                g: {k: float(np.mean([r[k] for r in rs])) for k in METRICS}
                for g, rs in groups.items()
            }
    return out


def win_rate(results: Results, a: str, b: str, metric="mirror_psnr", comparison="exr/hdr"):
    """Share of cases (0..1) in which method `a` scores better than method `b` on `metric`."""
    key = ("hdri", "heading", "hfov", "placement")
    rows = records_for(results, comparison)
    va = {tuple(r[k] for k in key): r[metric] for r in rows if r["method"] == a}
    vb = {tuple(r[k] for k in key): r[metric] for r in rows if r["method"] == b}
    sign = 1.0 if HIGHER_IS_BETTER[metric] else -1.0
    cases = [c for c in va if c in vb]
    return sum(sign * va[c] > sign * vb[c] for c in cases) / max(1, len(cases))


def ranking(results: Results, comparison: str = "exr/hdr", metric: str = "mirror_psnr"):
    """Method names, best first by the mean of `metric`."""
    summary = summarise(results, comparison)
    sign = -1.0 if HIGHER_IS_BETTER[metric] else 1.0
    return sorted(summary, key=lambda m: sign * summary[m][metric])


def ranking_table(results: Results, comparison: str = "exr/hdr") -> str:
    """A plain-text table of the mean metrics per method, best mirror PSNR first."""
    summary = summarise(results, comparison)
    cols = (
        ("mirror PSNR", "mirror_psnr", "{:7.2f}"),
        ("SSIM", "mirror_ssim", "{:6.3f}"),
        ("mirror siRMSE", "mirror_si_rmse", "{:6.3f}"),
        ("glossy siRMSE", "glossy_si_rmse", "{:6.3f}"),
        ("diffuse siRMSE", "diffuse_si_rmse", "{:6.3f}"),
        ("diffuse ang.", "diffuse_angular", "{:6.2f}"),
        ("plate PSNR", "plate_psnr", "{:6.2f}"),
        ("ms", None, "{:7.1f}"),
    )
    name_w = max(len(m) for m in summary) + 2
    head = "method".ljust(name_w) + "  ".join(c[0].rjust(max(len(c[0]), 7)) for c in cols)
    lines = [
        f"comparison {comparison} (means over {len(records_for(results, comparison))} "
        f"method-case pairs)",
        head,
    ]
    for m in ranking(results, comparison):
        cells = []
        for label, key, fmt in cols:
            value = summary[m][key] if key else results.timing.get(m, {}).get("cold_ms", math.nan)
            cells.append(fmt.format(value).rjust(max(len(label), 7)))
        star = " *" if m == results.default else ""
        lines.append((m + star).ljust(name_w) + "  ".join(cells))
    if results.default:
        lines.append("* the product's default; ms: median cold time (new bounds) per map")
    return "\n".join(lines)


def check_targets(results: Results, comparison: str = "exr/hdr") -> list:
    """The issue's targets for the default method: [(target, measured, holds)]."""
    d = results.default
    if d is None:
        return []
    summary = summarise(results, comparison)
    others = [m["name"] for m in results.methods if m["family"] in ("baseline", "paper")]
    out = []
    for metric, label in (
        ("mirror_psnr", "mirror-sphere PSNR"),
        ("mirror_ssim", "mirror-sphere SSIM"),
        ("diffuse_si_rmse", "diffuse-sphere si-RMSE"),
    ):
        sign = 1.0 if HIGHER_IS_BETTER[metric] else -1.0
        best_other = max(others, key=lambda m: sign * summary[m][metric])
        holds = sign * summary[d][metric] > sign * summary[best_other][metric]
        out.append(
            (
                f"beats every baseline and the paper on {label}",
                f"{summary[d][metric]:.3f} vs best other {best_other} "
                f"{summary[best_other][metric]:.3f}",
                bool(holds),
            )
        )
    plate = [r["plate_psnr"] for r in records_for(results, comparison, method=d)]
    out.append(
        (
            ">= 40 dB PSNR on the directions the plate sees, in every case",
            f"mean {np.mean(plate):.2f} dB, worst case {np.min(plate):.2f} dB",
            bool(np.min(plate) >= 40.0),
        )
    )
    by = summarise(results, comparison, by="placement")
    gaps = {g: by[d][g]["mirror_psnr"] - by["plate mean"][g]["mirror_psnr"] for g in by[d]}
    worst = min(gaps, key=gaps.get)
    out.append(
        (
            "no placement more than 1 dB worse than the plate's mean colour (mirror PSNR, "
            "mean over scenes)",
            f"worst placement {worst}: {gaps[worst]:+.2f} dB",
            bool(gaps[worst] >= -1.0),
        )
    )
    key = ("hdri", "heading", "hfov", "placement")
    rows = records_for(results, comparison)
    mean_of = {
        tuple(r[k] for k in key): r["mirror_psnr"] for r in rows if r["method"] == "plate mean"
    }
    case_gaps = [
        (r["mirror_psnr"] - mean_of[tuple(r[k] for k in key)], tuple(r[k] for k in key))
        for r in rows
        if r["method"] == d
    ]
    worst_gap, worst_case = min(case_gaps)
    share = np.mean([g < -1.0 for g, _ in case_gaps])
    out.append(
        (
            "not more than 1 dB worse than the plate's mean colour in any single case",
            f"{100 * share:.0f} % of cases are; worst {worst_gap:+.2f} dB "
            f"({worst_case[0]}, heading {worst_case[1]:g}, hfov {worst_case[2]:g}, "
            f"{worst_case[3]})",
            bool(worst_gap >= -1.0),
        )
    )
    return out


def _round(value):
    return round(value, 4) if isinstance(value, float) else value


def results_to_json(results: Results) -> dict:
    """Results as JSON-ready data; the records as a table (`columns` and `rows`, numbers rounded
    to 4 decimals), so 16,000 records stay a couple of megabytes."""
    data = asdict(results)
    records = data.pop("records")
    columns = list(records[0]) if records else []
    data["records"] = {
        "columns": columns,
        "rows": [[_round(r[c]) for c in columns] for r in records],
    }
    return data


def results_from_json(data: dict) -> Results:
    """Inverse of `results_to_json` (also accepts records as a list of dicts)."""
    data = dict(data)
    records = data.pop("records", [])
    if isinstance(records, dict):
        records = [dict(zip(records["columns"], row)) for row in records["rows"]]
    return Results(records=records, **data)


class StudyInputError(Exception):
    """Bad input to the study (an unknown HDRI, HDRIs not found); the message is one line."""


def with_hdris(config: Config, names) -> Config:
    """`config` restricted to the HDRIs `names` (checked against HDRIS)."""
    unknown = [n for n in names if n not in HDRIS]
    if unknown:
        raise StudyInputError(f"unknown HDRI {unknown[0]!r}; choose from {', '.join(HDRIS)}")
    return replace(config, hdris=tuple(names))


# --- the claims docs/accuracy.md makes (tests/study/test_evaluate.py checks them on --quick) ---


def _mean(results, comparison, method, metric):
    return summarise(results, comparison)[method][metric]


def _family(results, family):
    return [m["name"] for m in results.methods if m["family"] == family]


def _claim_default_beats_paper(results):
    """On the float plates, the default beats the paper's method at every n on mirror PSNR,
    mirror SSIM and diffuse si-RMSE."""
    s, d = summarise(results, "exr/hdr"), results.default
    return all(
        s[d]["mirror_psnr"] > s[p]["mirror_psnr"]
        and s[d]["mirror_ssim"] > s[p]["mirror_ssim"]
        and s[d]["diffuse_si_rmse"] < s[p]["diffuse_si_rmse"]
        for p in _family(results, "paper")
    )


def _claim_default_places_plate(results):
    """Where the plate sees, the default is closer to the truth than every baseline and the
    paper (plate PSNR), on float and LDR plates."""
    out = True
    for comparison in ("exr/hdr", "ldr/ldr"):
        s, d = summarise(results, comparison), results.default
        others = _family(results, "baseline") + _family(results, "paper")
        out &= all(s[d]["plate_psnr"] > s[o]["plate_psnr"] for o in others)
    return out


def _claim_paper_below_mean(results):
    """The paper's method, at every n, scores a lower mirror PSNR than the plate's mean colour:
    misplaced detail costs more than no detail."""
    s = summarise(results, "exr/hdr")
    return all(
        s[p]["mirror_psnr"] < s["plate mean"]["mirror_psnr"] for p in _family(results, "paper")
    )


def _claim_n_irrelevant(results):
    """The paper's n hardly matters: every n is within 0.2 dB mirror PSNR of the continuous
    limit."""
    s = summarise(results, "exr/hdr")
    ref = s["paper n=inf"]["mirror_psnr"]
    return all(abs(s[p]["mirror_psnr"] - ref) <= 0.2 for p in _family(results, "paper"))


def _claim_stretch_below_mean(results):
    """Stretching the plate over the sphere (what artists do today) scores below the plate's mean
    colour on mirror PSNR and SSIM."""
    s = summarise(results, "exr/hdr")
    return (
        s["stretched plate"]["mirror_psnr"] < s["plate mean"]["mirror_psnr"]
        and s["stretched plate"]["mirror_ssim"] < s["plate mean"]["mirror_ssim"]
    )


def _claim_default_beats_all(results):
    """On the float plates, the default beats every baseline and the paper's method on mean
    mirror-sphere PSNR, mirror-sphere SSIM and diffuse-sphere si-RMSE."""
    s, d = summarise(results, "exr/hdr"), results.default
    return all(
        s[d]["mirror_psnr"] > s[o]["mirror_psnr"]
        and s[d]["mirror_ssim"] > s[o]["mirror_ssim"]
        and s[d]["diffuse_si_rmse"] < s[o]["diffuse_si_rmse"]
        for o in _family(results, "baseline") + _family(results, "paper")
    )


def _claim_default_reaches_40db(results):
    """Where the plate sees, the default reaches 40 dB: its plate PSNR, averaged over the cases,
    is above 40 dB on float and LDR plates."""
    return all(
        float(np.mean([r["plate_psnr"] for r in records_for(results, c, method=results.default)]))
        > 40.0
        for c in ("exr/hdr", "ldr/ldr")
    )


def _claim_exact_placement_reachable(results):
    """Exact placement reaches the 40 dB target where the plate sees: on the float plates the
    reference (the plate box-filtered over each texel's footprint) scores more than 40 dB there,
    averaged over the cases."""
    rows = records_for(results, "exr/hdr", method=_family(results, "reference")[0])
    return bool(rows) and float(np.mean([r["plate_psnr"] for r in rows])) > 40.0


ADDON_DEFAULT_MAP = "engine camera + horizon"  # the add-on's default's map (study.methods)


def _claim_addon_default_keeps_up(results):
    """On the float plates, the add-on's default's map (engine camera + horizon: the camera
    view with the world's horizon and the sky prior above it) scores a mean mirror-sphere PSNR
    no more than 0.3 dB below the default's here (engine camera): against distant
    surroundings, the 3D default does not regress."""
    s = summarise(results, "exr/hdr")
    return s[ADDON_DEFAULT_MAP]["mirror_psnr"] >= s[results.default]["mirror_psnr"] - 0.3


CLAIMS = (
    _claim_default_beats_all,
    _claim_default_beats_paper,
    _claim_default_places_plate,
    _claim_default_reaches_40db,
    _claim_paper_below_mean,
    _claim_n_irrelevant,
    _claim_stretch_below_mean,
    _claim_exact_placement_reachable,
    _claim_addon_default_keeps_up,
)


def check_claims(results: Results) -> list:
    """[(claim, holds)] for every claim docs/accuracy.md makes (CLAIMS); none without a default."""
    if results.default is None:
        return []
    return [(" ".join(c.__doc__.split()), bool(c(results))) for c in CLAIMS]
