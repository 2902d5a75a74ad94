"""The camera-view method (Camera View): exact placement by the camera's field of view, the
edges extended and faded into a fill outside it."""

import math

import numpy as np
import pytest

from virtual_reflections import Params, environment_map, fill, seen_texels
from virtual_reflections import camera_view as cv
from virtual_reflections.camera_view import plate_positions


def camera_frame_directions(width, height, hfov_deg):
    """Unit pinhole directions (H, W, 3) of the plate's pixel centres in the camera frame
    (docs/conventions.md: +Z the plate's centre, +Y up, +X the plate's left)."""
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
    py, px = np.mgrid[0:height, 0:width] + 0.5
    d = np.stack([-(px - 0.5 * width) / f, -(py - 0.5 * height) / f, np.ones(px.shape)], -1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_pixel_directions_land_on_their_pixels():
    w, h, hfov = 160, 90, 60.0
    d = camera_frame_directions(w, h, hfov)  # docs/conventions.md pinhole directions
    pos, lod = plate_positions(d, w, h, hfov)
    py, px = np.mgrid[0:h, 0:w] + 0.5
    assert np.abs(pos[..., 0] - px).max() < 1e-3 and np.abs(pos[..., 1] - py).max() < 1e-3
    assert lod.max() == 0.0


def test_outside_the_view_is_clamped_to_the_nearest_edge_and_blurred():
    w, h, hfov = 160, 90, 60.0
    left = np.array([[math.sin(1.0), 0.0, math.cos(1.0)]])  # 57 degrees to the left
    up = np.array([[0.0, math.sin(1.2), math.cos(1.2)]])
    behind = np.array([[0.0, 0.0, -1.0]])
    (pl,), (ll,) = plate_positions(left, w, h, hfov)
    (pu,), (lu,) = plate_positions(up, w, h, hfov)
    _, (lb,) = plate_positions(behind, w, h, hfov, max_blur=1.0)
    assert pl[0] == pytest.approx(0.0) and pl[1] == pytest.approx(45.0)  # the left edge
    assert pu[0] == pytest.approx(80.0) and pu[1] == pytest.approx(0.0)  # the top edge
    assert 0 < ll < lb and lu > 0  # more blur further out, capped
    _, (capped,) = plate_positions(behind, w, h, hfov, max_blur=0.125)
    assert capped == pytest.approx(math.log2(0.125 * h))


def test_camera_map_reproduces_a_plate_of_the_map():
    """A plate rendered from a known lat-long map comes back exactly where the plate sees."""
    from virtual_reflections.layouts import texel_directions

    w, h, hfov = 320, 180, 70.0
    d = camera_frame_directions(w, h, hfov)
    plate = np.stack([0.5 + 0.5 * d[..., 0], 0.5 + 0.5 * d[..., 1], d[..., 2]], -1)
    env = environment_map(
        plate.astype(np.float32), (0, 0, 1, 1), Params(method="camera", hfov=hfov), "latlong", 256
    )
    dirs = texel_directions("latlong", 256)
    inside = (
        (dirs[..., 2] > 0)
        & (np.abs(dirs[..., 0] / dirs[..., 2]) < 0.6)
        & (np.abs(dirs[..., 1] / dirs[..., 2]) < 0.3)
    )
    expected = np.stack([0.5 + 0.5 * dirs[..., 0], 0.5 + 0.5 * dirs[..., 1], dirs[..., 2]], -1)
    assert np.abs(env[inside] - expected[inside]).max() < 0.002


def test_camera_needs_the_field_of_view():
    with pytest.raises(ValueError, match="field of view"):
        Params(method="camera")
    with pytest.raises(ValueError, match="method"):
        Params(method="magic")


def test_frustum_is_an_alias_of_camera():
    from virtual_reflections.params import METHODS

    assert set(METHODS) == {"paper", "camera", "ground"}
    old, new = Params(method="frustum", hfov=50.0), Params(method="camera", hfov=50.0)
    assert old.method == "camera" and old == new and hash(old) == hash(new)
    with pytest.raises(ValueError, match="field of view"):
        Params(method="frustum")
    plate = np.random.default_rng(3).random((36, 64, 3), dtype=np.float32)
    np.testing.assert_array_equal(
        environment_map(plate, (20, 10, 40, 30), old, "latlong", 64),
        environment_map(plate, (20, 10, 40, 30), new, "latlong", 64),
    )


def test_shifted_lens_and_non_square_pixels():
    w, h = 200, 100
    fx, fy, cx, cy = 150.0, 120.0, 130.0, 40.0  # principal point off-centre
    py, px = np.mgrid[0:h, 0:w] + 0.5
    d = np.stack([-(px - cx) / fx, -(py - cy) / fy, np.ones_like(px)], -1)
    pos, lod = plate_positions(d, w, h, intrinsics=(fx, fy, cx, cy))
    assert np.abs(pos[..., 0] - px).max() < 1e-3 and np.abs(pos[..., 1] - py).max() < 1e-3
    assert lod.max() == 0.0


def _map(plate, hfov=60.0, width=256, **kw):
    return environment_map(
        plate.astype(np.float32),
        (0, 0, 1, 1),
        Params(method="camera", hfov=hfov, **kw),
        "latlong",
        width,
    )


def _texel(direction, width):
    """(row, column) of the lat-long texel holding camera-frame `direction`
    (docs/conventions.md)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    lat, lon = math.asin(d[1]), math.atan2(d[0], d[2])
    row = int((0.5 - lat / math.pi) * (width // 2))
    col = int((0.5 - lon / (2 * math.pi)) * width)
    return min(row, width // 2 - 1), col % width


def test_seen_texels_average_their_footprint():
    """A one-pixel checkerboard seen through texels many pixels wide averages to grey (one
    bilinear tap per texel would alias or need a blurring mip level); a smooth plate is placed
    exactly."""
    w, h = 640, 360
    py, px = np.mgrid[0:h, 0:w]
    checker = np.repeat(((px + py) % 2).astype(np.float32)[..., None], 3, -1)
    env = _map(checker, width=256)  # about 7 plate pixels per texel
    r, c = _texel([0, 0, 1], 256)
    assert np.abs(env[r - 5 : r + 5, c - 5 : c + 5] - 0.5).max() < 0.02


def test_unseen_directions_fade_into_a_robust_average_by_elevation():
    """Bright sky above, dark ground below: above the plate the map is bright, below dark;
    behind, at the horizon's elevation, near the plate's log-average and far below its mean (a
    small sun in view must not light half the sphere). `fill_energy` brightens the log-average
    toward the mean: 0 is the log-average, 1 the mean's luminance, the default between."""
    w, h = 320, 180
    plate = np.full((h, w, 3), 0.05, np.float32)
    plate[: h // 2] = 0.8
    plate[10:14, 150:154] = 5000.0  # a small, very bright sun
    half_v = math.atan(math.tan(math.radians(30)) * h / w)
    up, down = (
        _texel([0, math.tan(half_v + 0.35), 1], 256),
        _texel([0, -math.tan(half_v + 0.35), 1], 256),
    )
    behind = _texel([0, 0, -1], 256)
    env = _map(plate, width=256)
    assert env[up].mean() > 2.0 * env[down].mean()
    log_average = math.exp(0.5 * math.log(0.8) + 0.5 * math.log(0.05))
    assert 0.5 * log_average < env[behind].mean() < 2.0 * log_average
    assert plate.mean() > 5 * env[behind].mean()
    above = [_map(plate, width=256, fill_energy=e)[up].mean() for e in (0.0, 0.5, 1.0)]
    assert above[0] < above[1] < above[2]
    assert above[1] == pytest.approx(math.sqrt(above[0] * above[2]), rel=0.2)


def test_fill_and_fade_do_not_depend_on_the_map_width():
    """The same direction gets the same fill from a 128- and a 512-wide map (the fade and the
    fill are angles, not texels); the plate is smooth so the texels' own size does not count."""
    rng = np.random.default_rng(3)
    rows = np.linspace(2.0, 0.2, 180, dtype=np.float32)[:, None, None]
    plate = rows * (0.9 + 0.2 * rng.random((180, 320, 3))).astype(np.float32)
    small, large = _map(plate, width=128), _map(plate, width=512)
    near = [math.sin(math.radians(35)), 0.0, math.cos(math.radians(35))]  # 5 deg off the plate
    for direction in ([0.0, 0.0, -1.0], [1.0, 0.2, 0.3], [0.0, 1.0, 0.4], near):
        r, c = _texel(direction, 128)  # its 4 x 4 texels in the wider map share its centre
        block = large[4 * r : 4 * r + 4, 4 * c : 4 * c + 4].mean((0, 1))
        np.testing.assert_allclose(small[r, c], block, rtol=0.01)


def test_fill_colour_and_the_old_extension():
    plate = np.zeros((90, 160, 3), np.float32)
    plate[...] = [0.4, 0.2, 0.1]
    behind = _texel([0, 0, -1], 128)
    grey = _map(plate, width=128, fill_saturation=0.0)[behind]
    assert np.ptp(grey) < 1e-4 and grey[0] == pytest.approx(
        0.2126 * 0.4 + 0.7152 * 0.2 + 0.0722 * 0.1, rel=1e-3
    )
    coloured = _map(plate, width=128, fill_saturation=1.0)[behind]
    np.testing.assert_allclose(coloured, [0.4, 0.2, 0.1], rtol=1e-3)


def test_the_default_keeps_left_on_the_left():
    """A plate whose left half is red is red to the left, behind-left too, as the add-on
    promises: the default's fill depends on the side (the difference between the sides keeps
    its colour); straight behind, both halves blend. The previous default (no fill) is red
    everywhere to the left; the fill by elevation only mixes the two halves."""
    plate = np.zeros((90, 160, 3), np.float32)
    plate[:, :80] = [1.0, 0.0, 0.0]  # the plate's left half red: +X
    plate[:, 80:] = [0.0, 0.0, 1.0]
    default = environment_map(plate, (0, 0, 1, 1), Params(method="camera", hfov=60.0))
    for direction in ([1, 0, 0], [1, 0.5, -0.5], [1, -0.3, -1]):
        left = default[_texel(direction, 1024)]
        right = default[_texel([-direction[0], *direction[1:]], 1024)]
        assert left[0] > 0.6 and left[0] > 5 * left[2], direction
        assert right[2] > 0.6 and right[2] > 5 * right[0], direction
    back = default[_texel([0, 0, -1], 1024)]
    assert back[0] == pytest.approx(back[2], rel=0.05)
    edges = environment_map(
        plate, (0, 0, 1, 1), Params(method="camera", hfov=60.0, extend_fade=None)
    )
    for direction in ([1, 0, 0], [1, 0.5, -0.5], [1, -0.3, -1]):
        left = edges[_texel(direction, 1024)]
        assert left[0] > 0.9 and left[2] < 0.1, direction
    by_elevation = _map(plate, width=128, extend_fade=10.0, fill_sides=False)
    mixed = by_elevation[_texel([1, 0, 0], 128)]
    assert mixed[0] == pytest.approx(mixed[2], rel=0.05)  # the two halves mixed


def test_camera_cube_map_is_finite_and_places_the_plate():
    w, h, hfov = 160, 90, 70.0
    d = camera_frame_directions(w, h, hfov)
    plate = np.stack([0.5 + 0.5 * d[..., 0], 0.5 + 0.5 * d[..., 1], d[..., 2]], -1)
    cube = environment_map(
        plate.astype(np.float32), (0, 0, 1, 1), Params(method="camera", hfov=hfov), "cube", 64
    )
    assert cube.shape == (384, 64, 3) and np.isfinite(cube).all()
    front = cube[4 * 64 : 5 * 64]  # +Z: the plate's centre
    np.testing.assert_allclose(front[32, 32], [0.5, 0.5, 1.0], atol=0.02)


def test_new_params_are_validated():
    for bad in (
        {"extend_fade": -1.0},
        {"fill_width": 0.0},
        {"fill_saturation": 2.0},
        {"fill_spread": float("nan")},
        {"fill_energy": 1.5},
        {"fill_sides": 1},
    ):
        with pytest.raises(ValueError):
            Params(method="camera", hfov=60.0, **bad)


def test_one_camera_table_serves_every_object_position():
    """The camera-view table depends on the camera only: a moved object reuses its taps (no
    rebuild) but keeps its own segmentation for the advice the add-on gives."""
    from virtual_reflections.table import lookup_table

    params = Params(method="camera", hfov=55.0)
    a = lookup_table(320, 180, (100.0, 50.0, 140.0, 90.0), params, "latlong", 64)
    b = lookup_table(320, 180, (200.0, 60.0, 260.0, 120.0), params, "latlong", 64)
    assert a.layers is b.layers and a.fill is b.fill
    assert a.segmentation != b.segmentation
    paper = Params()
    c = lookup_table(320, 180, (100.0, 50.0, 140.0, 90.0), paper, "latlong", 64)
    d = lookup_table(320, 180, (200.0, 60.0, 260.0, 120.0), paper, "latlong", 64)
    assert c.layers[0].samples is not d.layers[0].samples


@pytest.mark.parametrize("shifted", [False, True])
def test_the_lat_long_clamp_per_row_and_column_is_the_general_one(shifted):
    """The lat-long's clamp (trigonometry per row and column) places every texel where the
    general clamp does, finds the same seen texels, and the same angles (but for round-off
    at the threshold of the plate's view)."""
    from virtual_reflections.layouts import texel_directions

    width, height, size = 640, 360, 256
    intrinsics = cv.intrinsics_from_hfov(width, height, 60.0)
    if shifted:  # a shifted lens, non-square pixels
        intrinsics = (intrinsics[0], 1.1 * intrinsics[1], intrinsics[2] + 40, intrinsics[3] - 20)
    d = texel_directions("latlong", size, dtype=np.float32).reshape(-1, 3)
    position, angle = cv.clamp_to_view(d, width, height, intrinsics)
    position2, angle2, inside = cv.clamp_to_view_latlong(size, width, height, intrinsics)
    assert np.abs(position - position2).max() < 1e-2
    off = np.abs(angle - angle2) > 1e-4
    assert off.mean() < 1e-3 and np.abs(angle - angle2)[off].max(initial=0.0) <= cv.ANGLE_EPS + 1e-4
    seen, _ = seen_texels.seen_footprints("latlong", size, d, width, height, intrinsics)
    np.testing.assert_array_equal(seen, np.flatnonzero(inside))


@pytest.mark.parametrize("up", [None, (0.0, 0.97, 0.24), (0.1, 0.96, 0.26)])  # rolled: no mirror
def test_the_compact_fill_reads_the_profile_as_its_taps_do(up):
    """The lat-long fill kept as one elevation step per texel (or per row) gives the values
    the fill's taps give, to the step's rounding."""
    from virtual_reflections.layouts import texel_directions

    size, width = 128, 640
    intrinsics = cv.intrinsics_from_hfov(width, 360, 60.0)
    rng = np.random.default_rng(5)
    profile = np.cumsum(rng.random((2, fill.FILL_BINS, 3), dtype=np.float32) * 0.05, axis=1)
    d = texel_directions("latlong", size, dtype=np.float32).reshape(-1, 3)
    side = fill.side_weight(d[:size], intrinsics, width)
    index, weight = fill.fill_taps(d, 0, np.tile(side, size // 2), up)
    expected = np.einsum("tkc,tk->tc", profile.reshape(-1, 3)[index], weight)
    steps = fill.fill_bins_latlong(size, up)
    assert steps.size == (size // 2 if up is None else d.shape[0])
    out = np.empty_like(expected)
    fill.fill_values(steps, np.repeat(side, 3), fill.fill_lookup(profile), out)
    step = np.abs(np.diff(profile, axis=1)).max()
    assert np.abs(out - expected).max() <= step / fill.FILL_STEPS + 1e-5


@pytest.mark.parametrize(
    "intrinsics, reach_deg",
    [
        ((300.0, 300.0, 160.0, 90.0), 20.0),
        ((150.0, 170.0, 40.0, 150.0), 10.0),
        ((900.0, 900.0, 160.0, 90.0), 0.0),
    ],
)
def test_the_rows_left_out_of_a_cold_table_are_beyond_the_edge_extension(intrinsics, reach_deg):
    """The camera view's table projects only `latlong_rows_near_view`'s rows: every texel of
    the other rows must be farther than the extension's reach from the plate's view (the fill
    alone there), and the kept rows must hold every texel the plate sees."""
    size, width, height = 256, 320, 180
    reach = math.radians(reach_deg)
    first, stop = cv.latlong_rows_near_view(size, width, height, intrinsics, reach)
    _, angle, inside = cv.clamp_to_view_latlong(size, width, height, intrinsics)
    angle, inside = angle.reshape(size // 2, size), inside.reshape(size // 2, size)
    outside = np.ones(size // 2, bool)
    outside[first:stop] = False
    assert 0 < stop - first < size // 2
    assert (angle[outside] >= reach - 1e-6).all()
    assert not inside[outside].any()
    assert inside[first:stop].any()


@pytest.mark.parametrize(
    "intrinsics, reach_deg",
    [
        ((277.0, 277.0, 160.0, 90.0), 20.0),  # 60 degrees across, centred
        ((150.0, 170.0, 40.0, 150.0), 10.0),  # a wide, off-centre lens
        ((900.0, 900.0, 160.0, 90.0), 0.0),  # a long lens, no extension
        ((277.0, 277.0, 160.0, 90.0), 60.0),  # a wide reach: most columns kept
    ],
)
def test_the_columns_left_out_of_a_cold_table_are_beyond_the_edge_extension(intrinsics, reach_deg):
    """Within the kept rows, the table projects only `latlong_cols_near_view`'s columns:
    every texel of the other columns must be farther than the extension's reach from the
    plate's view, and the kept columns must hold every texel the plate sees (the whole map
    projected, for comparison, and the columns' own projection the same values)."""
    size, width, height = 256, 320, 180
    reach = math.radians(reach_deg)
    rows = cv.latlong_rows_near_view(size, width, height, intrinsics, reach)
    first, stop = cv.latlong_cols_near_view(size, width, height, intrinsics, reach, rows)
    position, angle, inside = cv.clamp_to_view_latlong(size, width, height, intrinsics)
    angle, inside = angle.reshape(size // 2, size), inside.reshape(size // 2, size)
    band = slice(*rows)
    outside = np.ones(size, bool)
    outside[first:stop] = False
    assert 0 < stop - first <= size
    assert (angle[band][:, outside] >= reach - 1e-6).all()
    assert not inside[:, outside].any()
    assert inside[:, first:stop].any()
    if reach_deg == 60.0:
        assert stop - first > size // 2
    else:
        assert stop - first < size // 2  # the point: most columns are the fill alone
    part = cv.clamp_to_view_latlong(
        size, width, height, intrinsics, slice(*rows), slice(first, stop)
    )
    whole = position.reshape(size // 2, size, 2)[band, first:stop].reshape(-1, 2)
    assert np.array_equal(part[0], whole)
    assert np.array_equal(part[1], angle[band, first:stop].ravel())
    assert np.array_equal(part[2], inside[band, first:stop].ravel())
