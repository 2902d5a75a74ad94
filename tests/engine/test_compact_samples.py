"""The compact samples (trilinear.py, supersample.py) and the optional back ends (backends.py):
the NumPy path reads what a plain trilinear lookup reads; OpenCV, when installed, gives the
same map to within its 1/32-pixel weights, Numba to float32 rounding (test_kernels.py has
whole maps); VR_GATHER=numpy forces NumPy."""

import numpy as np
import pytest

from virtual_reflections import backends
from virtual_reflections.mipmap import build_pyramid, level_offsets, level_shapes, level_view
from virtual_reflections.trilinear import ROW, gather, trilinear_samples

H, W = 45, 70
needs_cv2 = pytest.mark.skipif(backends.cv2() is None, reason="OpenCV not installed (optional)")
needs_numba = pytest.mark.skipif(
    backends.kernels() is None, reason="Numba not installed (optional)"
)


def _plate(seed=3, smooth=False):
    rng = np.random.default_rng(seed)
    if smooth:
        y, x = np.mgrid[0:H, 0:W].astype(np.float32)
        return np.stack([np.sin(x / 7) * np.cos(y / 5), x / W, y / H], -1).astype(np.float32)
    return rng.random((H, W, 3), dtype=np.float32)


def _samples(n=3000, seed=5):
    rng = np.random.default_rng(seed)
    px = (rng.random(n) * W).astype(np.float32)
    py = (rng.random(n) * H).astype(np.float32)
    top = len(level_shapes(H, W)) - 1
    lod = (rng.random(n) * top).astype(np.float32)
    lod[:50] = 0.0  # exact levels and the top
    lod[50:100] = np.float32(top)
    return px, py, lod


def _reference(flat, shapes, px, py, lod):
    """A plain trilinear lookup: bilinear on floor(lod) and the next level, edges repeated."""
    top = len(shapes) - 1
    out = np.zeros((px.size, 3), np.float64)
    for t in range(px.size):
        lo = min(int(lod[t]), max(top - 1, 0))
        up = min(max(float(lod[t]) - lo, 0.0), 1.0)
        for level, share in ((lo, 1 - up), (min(lo + 1, top), up)):
            img = level_view(flat, shapes, level).astype(np.float64)
            h, w = shapes[level]
            u, v = px[t] / 2**level - 0.5, py[t] / 2**level - 0.5
            i, j = int(np.floor(u)), int(np.floor(v))
            a, b = u - i, v - j
            for di, dj, wt in ((0, 0, (1 - a) * (1 - b)), (1, 0, a * (1 - b)),
                               (0, 1, (1 - a) * b), (1, 1, a * b)):  # fmt: skip
                x = min(max(i + di, 0), w - 1)
                y = min(max(j + dj, 0), h - 1)
                out[t] += share * wt * img[y, x]
    return out


def _read(plate, px, py, lod, use):
    shapes = level_shapes(H, W)
    flat = build_pyramid(plate)
    samples = trilinear_samples(px, py, lod, len(shapes) - 1, (px.size, 1))
    out = np.empty((px.size, 3), np.float32)
    gather(samples, flat, shapes, level_offsets(shapes), out, use=use)
    return out, flat, shapes, samples


def test_compact_samples_are_10_bytes_a_row_and_grouped_by_level():
    px, py, lod = _samples()
    _, _, _, s = _read(_plate(), px, py, lod, "numpy")
    nbytes = s.x.nbytes + s.y.nbytes + s.upper.nbytes + s.rank.nbytes
    # 10 bytes a row of the runs (padded to whole rows of ROW), 4 a texel for the way back:
    # 14 bytes a texel once the padding is small beside the map (benchmarks: 14.1 at 1024).
    assert nbytes == 10 * s.starts[-1] + 4 * px.size
    assert s.starts[-1] <= px.size + len(s.levels) * ROW
    assert list(s.levels) == sorted(s.levels) and all(b % ROW == 0 for b in s.starts)
    # Texels with no share on the next level (lod 0 here) are runs of one sample each.
    assert any(s.singles) and all(
        not s.upper[a:b].any() for a, b, one in zip(s.starts, s.starts[1:], s.singles) if one
    )
    rows = s.rank[..., 1].astype(np.int64) * ROW + s.rank[..., 0]
    assert np.unique(rows).size == px.size  # every texel has its own row


@pytest.mark.parametrize("smooth", [False, True])
def test_each_run_holds_the_texels_of_its_level(smooth):
    """The runs' sizes (their texels counted per block by runs of equal keys) against the
    levels worked out directly: noisy levels (a new key at every texel) and smooth ones."""
    n = 300_000  # more than one block of the classification
    rng = np.random.default_rng(11)
    top = len(level_shapes(H, W)) - 1
    lod = np.linspace(0, top, n, dtype=np.float32) if smooth else rng.random(n) * top
    lod = lod.astype(np.float32)
    lod[::7] = np.floor(lod[::7])  # exact levels: single samples
    px = (rng.random(n) * W).astype(np.float32)
    py = (rng.random(n) * H).astype(np.float32)
    s = trilinear_samples(px, py, lod, top, (n, 1))
    level = np.minimum(np.floor(lod), top - 1)
    single = lod - level <= 2.0**-25
    rows = np.sort(s.rank[..., 1].astype(np.int64).ravel() * ROW + s.rank[..., 0].ravel())
    for r, (lv, one) in enumerate(zip(s.levels, s.singles, strict=True)):
        held = np.searchsorted(rows, s.starts[r + 1]) - np.searchsorted(rows, s.starts[r])
        assert held == np.count_nonzero((level == lv) & (single == one))


def test_numpy_path_is_a_trilinear_lookup():
    px, py, lod = _samples(1500)
    got, flat, shapes, _ = _read(_plate(), px, py, lod, "numpy")
    expected = _reference(flat, shapes, px, py, lod)
    # The next level's share is stored as float16: up to 2^-11 of the levels' difference.
    assert np.abs(got - expected).max() < 1e-3
    assert np.abs(got - expected).mean() < 1e-4


@needs_cv2
@pytest.mark.parametrize("smooth", [False, True])
def test_opencv_path_matches_numpy_within_its_weight_rounding(smooth):
    px, py, lod = _samples()
    plate = _plate(smooth=smooth)
    fast, *_ = _read(plate, px, py, lod, "opencv")
    ref, *_ = _read(plate, px, py, lod, "numpy")
    diff = np.abs(fast - ref)
    # OpenCV rounds bilinear weights to 1/32: at most 1/64 of the largest step between
    # neighbours per axis (here <= 1: values in [0, 1]), 1/32 for the two axes.
    assert diff.max() <= 1 / 32 + 1e-6
    psnr = 10 * np.log10(1.0 / np.mean(diff.astype(np.float64) ** 2))
    print(f"opencv vs numpy: max {diff.max():.2e}, PSNR {psnr:.1f} dB")
    assert psnr > 45, psnr


@needs_numba
@pytest.mark.parametrize("direct", [False, True])
def test_numba_path_matches_numpy_to_float32_rounding(direct):
    """The compiled trilinear gather (kernels.py) reads NumPy's taps with NumPy's weights,
    level 0 from the pyramid or from the plate itself (as envmap reads the paper's)."""
    px, py, lod = _samples()
    px[:20], py[:20] = 0.0, np.float32(H)  # on the plate's edges
    plate = _plate(smooth=True)
    ref, flat, shapes, samples = _read(plate, px, py, lod, "numpy")
    fast = np.empty_like(ref)
    if direct:
        part = build_pyramid(plate, first=1)
        gather(samples, part, shapes, level_offsets(shapes, 1), fast, use="numba", plate=plate)
    else:
        gather(samples, flat, shapes, level_offsets(shapes), fast, use="numba")
    assert np.abs(fast - ref).max() < 1e-6


def test_vr_gather_numpy_forces_the_numpy_path(monkeypatch):
    monkeypatch.setenv("VR_GATHER", "numpy")
    assert backends.backend() == "numpy"
    monkeypatch.setenv("VR_GATHER", "")
    assert backends.backend() == backends.available_backends()[0]


@pytest.mark.parametrize("use", ["numpy", pytest.param("numba", marks=needs_numba)])
def test_compact_supersamples_read_what_their_taps_read(monkeypatch, use):
    """supersample.py: the same means as seen_texels.mean_taps' rows and weights (positions
    beyond a level's edge included), at 8 bytes a sample instead of 32; NumPy or compiled."""
    monkeypatch.setenv("VR_GATHER", use)
    from virtual_reflections.seen_texels import mean_taps
    from virtual_reflections.supersample import gather as gather_supersample
    from virtual_reflections.supersample import supersamples

    rng = np.random.default_rng(9)
    shapes = level_shapes(H, W)
    offsets = level_offsets(shapes)
    flat = build_pyramid(_plate())
    count, k = 700, 16
    level = rng.integers(0, 4, count)
    positions = [
        (rng.random(count) * (W + 12) - 6, rng.random(count) * (H + 12) - 6) for _ in range(k)
    ]
    texels = rng.permutation(5000)[:count]
    index, weight = mean_taps(positions, level, shapes, offsets)
    expected = np.einsum("tkc,tk->tc", flat[index].astype(np.float64), weight)
    samples = supersamples(texels, positions, level, shapes, offsets)
    assert samples.on_plate[0] and not any(samples.on_plate[1:])  # level 0: the plate's rows
    plate = _plate().reshape(-1, 3)
    out = np.zeros((5000, 3), np.float32)
    # Level 0 from the plate itself: a pyramid without level 0 serves the other runs.
    part = build_pyramid(_plate(), first=1)
    part_samples = supersamples(texels, positions, level, shapes, level_offsets(shapes, 1))
    gather_supersample(part_samples, part, out, plate=plate)
    assert np.abs(out[texels] - expected).max() < 2e-5
    with pytest.raises(ValueError, match="plate"):
        gather_supersample(samples, flat, out)
    with pytest.raises(ValueError, match="pyramid"):
        gather_supersample(samples, None, out, plate=plate)
    gather_supersample(samples, flat, out, plate=plate)
    assert np.abs(out[texels] - expected).max() < 2e-5
    assert (samples.base.nbytes + samples.fx.nbytes + samples.fy.nbytes) / (count * k) == 8
    drop = np.zeros(5000, bool)
    drop[texels[:100]] = True
    out2 = np.zeros((5000, 3), np.float32)
    gather_supersample(samples.without(drop), flat, out2, plate=plate)
    assert not out2[texels[:100]].any() and np.array_equal(out2[texels[100:]], out[texels[100:]])


@needs_cv2
def test_opencv_reads_level_0_from_the_plate_as_from_the_pyramid():
    """envmap reads the paper's level 0 from the plate itself with OpenCV (no copy into the
    pyramid): its remaps repeat the edge as the pyramid's border does."""
    px, py, lod = _samples()
    px[:20], py[:20] = 0.0, np.float32(H)  # on the plate's edges
    plate = _plate()
    shapes = level_shapes(H, W)
    samples = trilinear_samples(px, py, lod, len(shapes) - 1, (px.size, 1))
    full = np.empty((px.size, 3), np.float32)
    gather(samples, build_pyramid(plate), shapes, level_offsets(shapes), full, use="opencv")
    direct = np.empty_like(full)
    part = build_pyramid(plate, first=1)
    gather(samples, part, shapes, level_offsets(shapes, 1), direct, use="opencv", plate=plate)
    assert np.abs(direct - full).max() < 1e-6


@pytest.mark.parametrize(
    "use",
    ["numpy", pytest.param("opencv", marks=needs_cv2), pytest.param("numba", marks=needs_numba)],
)
def test_the_edge_extension_fades_a_trilinear_sample_into_the_fill(monkeypatch, use):
    """extension.py: the texels near the plate's view read one trilinear sample (as the plain
    lookup) faded into the fill already in the map by their weight; without a weight, the
    sample alone; `without` drops texels and keeps the others' values."""
    from virtual_reflections import extension as ext_module

    monkeypatch.setenv("VR_GATHER", use)
    px, py, lod = _samples(n=2500)
    shapes = level_shapes(H, W)
    flat = build_pyramid(_plate(smooth=True))
    expected = _reference(flat, shapes, px, py, lod)
    rng = np.random.default_rng(4)
    texels = np.sort(rng.permutation(9000)[: px.size])
    weight = rng.random(px.size).astype(np.float32)
    fill = rng.random((9000, 3)).astype(np.float32)
    tolerance = 1 / 32 if use == "opencv" else 2e-3  # float16 shares; OpenCV's 1/32 pixel
    for share in (weight, None):
        ext = ext_module.extension(texels, px, py, lod, len(shapes) - 1, share)
        out = fill.copy()
        ext_module.apply(ext, flat, shapes, level_offsets(shapes), out)
        want = (
            expected if share is None else fill[texels] + share[:, None] * (expected - fill[texels])
        )
        assert np.abs(out[texels] - want).max() < tolerance
        others = np.setdiff1d(np.arange(9000), texels)
        assert np.array_equal(out[others], fill[others])  # only its texels are written
        # 10 bytes a row of the runs, 4 + 4 a texel (its map index, its weight): no rank
        per_texel = 8 if share is not None else 4
        assert ext.samples.rank is None
        assert ext.samples.x.nbytes * 2.5 + per_texel * px.size == (
            ext.samples.x.nbytes + ext.samples.y.nbytes + ext.samples.upper.nbytes
            + ext.texels.nbytes + (0 if ext.weight is None else ext.weight.nbytes)
        )  # fmt: skip
        drop = np.zeros(9000, bool)
        drop[texels[::3]] = True
        less = ext.without(drop)
        again = fill.copy()
        ext_module.apply(less, flat, shapes, level_offsets(shapes), again)
        assert np.array_equal(again[texels[::3]], fill[texels[::3]])
        kept = np.setdiff1d(texels, texels[::3])
        assert np.abs(again[kept] - out[kept]).max() < 1e-6
        assert ext.without(np.ones(9000, bool)) is None
