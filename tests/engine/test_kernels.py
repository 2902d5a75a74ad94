"""The optional compiled back end (kernels.py, chosen by backends.py): every map it makes is
NumPy's to float32 rounding — both methods and the ground, lat-long and cube, the plate's
level 0 read in place, an odd-sized plate — and without Numba the engine falls back to the
other back ends, never to an error."""

import numpy as np
import pytest

from virtual_reflections import backends
from virtual_reflections.envmap import apply_table, environment_map
from virtual_reflections.mipmap import build_pyramid, level_shapes, level_view
from virtual_reflections.params import Params
from virtual_reflections.table import lookup_table

needs_numba = pytest.mark.skipif(
    backends.kernels() is None, reason="Numba not installed (optional; requirements/ has it)"
)

GROUND = Params(
    method="ground", hfov=55.0, ground=(0.3, -0.4, 4.0, 0.5), up=(0.0, 0.97, 0.24), sky_gain=1.6
)
CASES = {
    "paper latlong": (Params(), "latlong", 256),
    "paper cube": (Params(), "cube", 64),
    "camera latlong": (Params(method="camera", hfov=50.0), "latlong", 512),
    "camera cube": (Params(method="camera", hfov=50.0), "cube", 96),
    "ground latlong": (GROUND, "latlong", 256),
}


def _plate(h=181, w=322, seed=11):
    """Detail at every scale, a bright spot and an odd size (the pyramid's repeated edges)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    plate = np.stack([x / w, y / h, 0.5 + 0.5 * np.sin(x / 5) * np.cos(y / 3)], -1)
    plate = plate.astype(np.float32) + 0.2 * rng.random((h, w, 3), dtype=np.float32)
    plate[40:44, 200:204] = 30.0
    return plate


def _map(monkeypatch, use, params, layout, size, plate, bbox=(120.0, 60.0, 210.0, 150.0)):
    monkeypatch.setenv("VR_GATHER", use)
    assert backends.backend() == use
    h, w = plate.shape[:2]
    table = lookup_table(w, h, bbox, params, layout, size)
    return apply_table(table, plate)


@needs_numba
@pytest.mark.parametrize("case", list(CASES))
def test_compiled_maps_are_numpys_to_float32_rounding(monkeypatch, case):
    params, layout, size = CASES[case]
    plate = _plate()
    fast = _map(monkeypatch, "numba", params, layout, size, plate)
    ref = _map(monkeypatch, "numpy", params, layout, size, plate)
    assert fast.shape == ref.shape and np.isfinite(fast).all()
    scale = float(np.abs(ref).max())
    diff = np.abs(fast - ref)
    assert diff.max() <= 4e-6 * scale, (case, diff.max(), scale)
    assert diff.mean() <= 1e-7 * scale
    # and not trivially: the map varies as the plate does
    assert ref.std() > 0.05


@needs_numba
def test_compiled_maps_follow_a_changed_plate(monkeypatch):
    """Nothing of one plate stays in the compiled path's buffers: a second plate's map is
    its own (a map of it made fresh with NumPy)."""
    params, layout, size = CASES["camera latlong"]
    first, second = _plate(seed=1), _plate(seed=2)[::-1].copy()
    _map(monkeypatch, "numba", params, layout, size, first)
    fast = _map(monkeypatch, "numba", params, layout, size, second)
    ref = _map(monkeypatch, "numpy", params, layout, size, second)
    assert np.abs(fast - ref).max() <= 4e-6 * float(np.abs(ref).max())


PYRAMIDS = [  # (h, w, levels, first) with a level to store
    (h, w, levels, first)
    for h, w in [(8, 8), (7, 5), (1, 6), (5, 1), (37, 50), (64, 40), (36, 52)]
    for levels in (None, 2, 5)
    for first in (0, 1, 2, 3)
    if first < len(level_shapes(h, w, levels))
]


@needs_numba
@pytest.mark.parametrize("h, w, levels, first", PYRAMIDS)
def test_compiled_pyramid_is_numpys_to_the_bit(monkeypatch, h, w, levels, first):
    """The compiled pyramid (its levels made in stripes in one call, the plate's block means
    straight to the first stored level when its sides allow, the halving otherwise) does
    NumPy's float32 arithmetic in NumPy's order, borders included."""
    plate = np.random.default_rng(h * w).random((h, w, 3), dtype=np.float32)
    monkeypatch.setenv("VR_GATHER", "numba")
    fast = build_pyramid(plate, levels, first=first)
    monkeypatch.setenv("VR_GATHER", "numpy")
    ref = build_pyramid(plate, levels, first=first)
    assert fast.shape == ref.shape
    shapes = level_shapes(h, w, levels)
    for level in range(first, len(shapes)):
        got = level_view(fast, shapes, level, first)
        assert np.array_equal(got, level_view(ref, shapes, level, first)), level
    assert np.array_equal(fast, ref)  # the borders too


def test_without_numba_the_engine_falls_back(monkeypatch):
    """A Blender without Numba (every distribution build): the other back ends, the same map."""
    monkeypatch.setattr(backends, "_kernels", [None])
    monkeypatch.setenv("VR_GATHER", "")
    assert backends.backend() == ("opencv" if backends.cv2() is not None else "numpy")
    monkeypatch.setenv("VR_GATHER", "numba")  # asked for, not there: the next one
    assert backends.backend() in ("opencv", "numpy")
    assert "numba" not in backends.available_backends()
    plate = _plate()
    env = environment_map(plate, (120, 60, 210, 150), Params(method="camera", hfov=50.0))
    assert env.shape == (512, 1024, 3) and np.isfinite(env).all()


def test_vr_gather_picks_the_back_end(monkeypatch):
    monkeypatch.setenv("VR_GATHER", "numpy")
    assert backends.backend() == "numpy" and backends.pyramid_backend() == "numpy"
    monkeypatch.setenv("VR_GATHER", "opencv")
    has_cv2 = backends.cv2() is not None
    assert backends.backend() == ("opencv" if has_cv2 else "numpy")
    assert backends.pyramid_backend() == ("opencv" if has_cv2 else "numpy")
    monkeypatch.setenv("VR_GATHER", "")
    default = backends.backend()
    assert default == backends.available_backends()[0]
    assert backends.available_backends()[-1] == "numpy"


def _forked_map(seed):
    plate = _plate(seed=seed)
    return environment_map(plate, (120, 60, 210, 150), Params(method="camera", hfov=50.0))


# Python 3.12+ warns on any fork of a process with threads: forking one is what this checks.
@pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning")
@needs_numba
def test_a_process_that_used_the_kernels_can_fork_workers(monkeypatch):
    """The study's and the farm's worker pools fork: Numba's threads must survive it (GNU
    OpenMP, which Numba picks where installed, aborts the child; backends.py uses Numba's
    own scheduler)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    monkeypatch.setenv("VR_GATHER", "numba")
    here = _forked_map(1)  # the parent's threads started
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        there = list(pool.map(_forked_map, [1, 2], timeout=120))
    assert np.array_equal(there[0], here)
    assert not np.array_equal(there[1], here)


@needs_numba
def test_the_kernels_read_the_runs_as_trilinear_writes_them():
    from virtual_reflections import trilinear

    assert backends.kernels().ROW == trilinear.ROW
