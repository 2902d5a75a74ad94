"""Tests that would catch a wrong engine: colours per face, seams, aliasing, stability."""

import numpy as np
import pytest

from virtual_reflections import Params, environment_map, lookup_table, segment
from virtual_reflections.layouts import texel_directions
from virtual_reflections.projection import plate_positions

W, H = 400, 300
BBOX = (170.0, 110.0, 230.0, 170.0)
FACES = {"+X": 0, "-X": 1, "+Y": 2, "-Y": 3, "+Z": 4, "-Z": 5}


def close(pixels, colour, tol):
    return np.abs(np.asarray(pixels) - colour).max() < tol


def face(cube, name, size):
    i = FACES[name]
    return cube[i * size : (i + 1) * size]


def region_plate(seg):
    """A plate painted by region, from the paper's geometry written out independently:
    X, then the side trapezoids (between X and inner, split by the corner diagonals), then
    the ring F's trapezoids. Each region gets a colour from COLOURS."""
    py, px = np.mgrid[0:H, 0:W] + 0.5
    X, inner = seg.x, seg.inner

    def side(a, b):  # which trapezoid of the ring between rect a (inside) and b (outside)
        d = np.stack(
            [
                (a.x0 - px) / (a.x0 - b[0]),
                (px - a.x1) / (b[2] - a.x1),
                (a.y0 - py) / (a.y0 - b[1]),
                (py - a.y1) / (b[3] - a.y1),
            ]
        )
        return np.argmax(d, 0)

    label = np.where(
        (px >= inner.x0) & (px < inner.x1) & (py >= inner.y0) & (py < inner.y1),
        1 + side(X, (inner.x0, inner.y0, inner.x1, inner.y1)),
        5 + side(inner, (0, 0, W, H)),
    )
    label[(px >= X.x0) & (px < X.x1) & (py >= X.y0) & (py < X.y1)] = 0
    return COLOURS[label]


# X, L, R, T, B, F_L, F_R, F_T, F_B
COLOURS = np.array(
    [
        [1, 1, 1],
        [1, 0, 0],
        [0, 0, 1],
        [0, 1, 0],
        [1, 1, 0],
        [1, 0, 1],
        [0, 1, 1],
        [0.5, 0, 0],
        [0, 0, 0.5],
    ],
    dtype=np.float32,
)


def test_regions_land_on_the_paper_faces():
    seg = segment(W, H, BBOX)
    S = 32
    cube = environment_map(region_plate(seg), BBOX, layout="cube", size=S)
    mid = slice(S // 2 - 3, S // 2 + 3)
    assert close(face(cube, "+Z", S)[mid, mid], COLOURS[0], 0.02)  # X: back
    assert close(face(cube, "+X", S)[mid, mid], COLOURS[1], 0.02)  # L: left
    assert close(face(cube, "-X", S)[mid, mid], COLOURS[2], 0.02)  # R: right
    assert close(face(cube, "+Y", S)[mid, mid], COLOURS[3], 0.02)  # T: top
    assert close(face(cube, "-Y", S)[mid, mid], COLOURS[4], 0.02)  # B: bottom
    # The front face: each quarter shows its part of the ring F. The ring is squeezed
    # there, so texels average over their footprint: check the nearest region colour.
    front = face(cube, "-Z", S)  # columns: x = -1..1 (x < 0 is the right); rows: y = +1..-1
    q = S // 4
    for (row, col), expected in {
        (S // 2, q): 6,
        (S // 2, S - 1 - q): 5,
        (q, S // 2): 7,
        (S - 1 - q, S // 2): 8,
    }.items():
        got = front[row, col]
        assert np.argmin(np.abs(COLOURS - got).sum(1)) == expected, (row, col, got)


def test_plate_left_is_the_maps_plus_x():
    plate = np.zeros((H, W, 3), np.float32)
    plate[:, : W // 2] = (1, 0, 0)
    plate[:, W // 2 :] = (0, 0, 1)
    S = 16
    cube = environment_map(plate, BBOX, layout="cube", size=S)
    assert (face(cube, "+X", S)[..., 0] > 0.99).all()  # red on the plate's left
    assert (face(cube, "-X", S)[..., 2] > 0.99).all()
    ll = environment_map(plate, BBOX, layout="latlong", size=64)
    band = slice(8, 24)  # away from the poles, where the top/bottom faces meet at cx
    assert (ll[band, 4:28, 0] > 0.99).all() and (ll[band, 36:60, 2] > 0.99).all()
    # The back face shows the plate unmirrored: its left columns red, right columns blue.
    back = face(cube, "+Z", S)
    assert (back[:, :7, 0] > 0.99).all() and (back[:, -7:, 2] > 0.99).all()


# The 12 cube edges: (face a, its edge) meets (face b, its edge), per ImfEnvmap.
def _edge(img, side):
    return {"top": img[0], "bottom": img[-1], "left": img[:, 0], "right": img[:, -1]}[side]


EDGES = [
    ("+Z", "left", "+X", "right"),
    ("+Z", "right", "-X", "left"),
    ("+Z", "top", "+Y", "top"),
    ("+Z", "bottom", "-Y", "bottom"),
    ("-Z", "left", "-X", "right"),
    ("-Z", "right", "+X", "left"),
    ("-Z", "top", "+Y", "bottom"),
    ("-Z", "bottom", "-Y", "top"),
    ("+X", "top", "+Y", "right"),
    ("-X", "top", "+Y", "left"),
    ("+X", "bottom", "-Y", "right"),
    ("-X", "bottom", "-Y", "left"),
]


def _matching(a, b):
    """Compare two edge arrays of shared directions in either order."""
    return min(np.abs(a - b).max(), np.abs(a - b[::-1]).max())


def test_cube_edge_directions_are_shared():
    S = 9
    d = texel_directions("cube", S)
    for fa, ea, fb, eb in EDGES:
        a, b = _edge(face(d, fa, S), ea), _edge(face(d, fb, S), eb)
        assert _matching(a, b) < 1e-12, (fa, ea, fb, eb)


@pytest.mark.parametrize("triangles", [0, 32])
def test_faces_meet_without_seams(triangles):
    S = 64
    seg = segment(W, H, BBOX, Params(triangles=triangles))
    pos = plate_positions(texel_directions("cube", S, dtype=np.float32), seg, triangles)
    for fa, ea, fb, eb in EDGES:
        a, b = _edge(face(pos, fa, S), ea), _edge(face(pos, fb, S), eb)
        assert _matching(a, b) < 1e-6, (fa, ea, fb, eb)
    # And the colours on a smooth plate agree along the edges.
    py, px = np.mgrid[0:H, 0:W] / np.float32(W)
    plate = np.stack([px, py, px * py], -1).astype(np.float32)
    cube = environment_map(plate, BBOX, Params(triangles=triangles), "cube", S)
    for fa, ea, fb, eb in EDGES:
        a, b = _edge(face(cube, fa, S), ea), _edge(face(cube, fb, S), eb)
        assert _matching(a, b) < 0.02, (fa, ea, fb, eb)


def _front_seam(triangles):
    """Largest jump on the plate between neighbouring texels of the front face, away from
    its singular centre (where every method jumps from one border to another)."""
    S = 128
    d = texel_directions("cube", S)[5 * S : 6 * S]
    p = plate_positions(d, segment(W, H, BBOX), triangles)
    ring = np.maximum(np.abs(d[..., 0]), np.abs(d[..., 1])) > 0.25
    jumps = []
    for ax in (0, 1):
        step = np.hypot(*np.diff(p, axis=ax).transpose(2, 0, 1))
        both = ring[1:] & ring[:-1] if ax == 0 else ring[:, 1:] & ring[:, :-1]
        jumps.append(step[both].max())
    return max(jumps)


def test_front_face_seams_shrink_as_n_grows():
    jumps = [_front_seam(n) for n in (4, 32, 256)]
    assert jumps[0] > jumps[1] > jumps[2]
    assert jumps[2] >= _front_seam(0) - 1e-9  # the continuous limit has no triangle seams


def test_one_pixel_checkerboard_does_not_alias():
    y, x = np.mgrid[0:600, 0:800]
    plate = np.repeat(((x + y) % 2).astype(np.float32)[..., None], 3, axis=2)
    for layout, size in (("latlong", 64), ("cube", 24)):
        env = environment_map(plate, (350, 250, 450, 350), layout=layout, size=size)
        assert np.abs(env - 0.5).max() < 0.1, layout


@pytest.mark.parametrize(
    "bbox",
    [
        (0, 100, 40, 200),
        (360, 100, 400, 200),
        (150, 0, 250, 20),
        (150, 280, 250, 300),
        (-100, -100, 500, 400),
        (-300, -300, -200, -200),
        (1000, 50, 1100, 80),
        (200, 150, 200, 150),
    ],
)
def test_any_bounds_give_a_valid_finite_map(bbox):
    py, px = np.mgrid[0:H, 0:W]
    plate = np.stack([px / W, py / H, np.full_like(px, 0.5, dtype=float)], -1).astype(np.float32)
    for layout, size in (("latlong", 64), ("cube", 16)):
        env = environment_map(plate, bbox, Params(triangles=8), layout, size)
        assert np.isfinite(env).all() and env.min() >= 0 and env.max() <= 1.0001


def test_one_pixel_plate():
    env = environment_map(np.full((1, 1, 3), 0.25, np.float32), (0, 0, 1, 1), size=16)
    assert env.shape == (8, 16, 3) and np.allclose(env, 0.25)


def test_moving_bounds_by_a_pixel_changes_the_map_a_little():
    rng = np.random.default_rng(1)
    # A smooth random plate (low frequencies), so changes measure geometry, not noise.
    coarse = rng.random((6, 8, 3)).astype(np.float32)
    plate = np.kron(coarse, np.ones((50, 50, 1), np.float32))
    a = environment_map(plate, BBOX, size=128)
    b = environment_map(plate, (BBOX[0] + 1, BBOX[1], BBOX[2] + 1, BBOX[3]), size=128)
    c = environment_map(plate, (BBOX[0], BBOX[1] + 1, BBOX[2], BBOX[3] + 1), size=128)
    far = environment_map(plate, (BBOX[0] + 100, BBOX[1], BBOX[2] + 100, BBOX[3]), size=128)
    small = max(np.abs(a - b).mean(), np.abs(a - c).mean())
    assert small < 0.01
    assert np.abs(a - far).mean() > 10 * small


def test_tables_are_cached_and_read_only():
    t1 = lookup_table(W, H, BBOX, Params(), "latlong", 64)
    t2 = lookup_table(W, H, BBOX, Params(), "latlong", 64)
    assert t1 is t2
    assert lookup_table(W, H, BBOX, Params(triangles=4), "latlong", 64) is not t1
    (layer,) = t1.layers  # the paper's table: every texel one trilinear sample
    tri = layer.samples
    assert not any(a.flags.writeable for a in (tri.x, tri.y, tri.upper, tri.rank))
    assert ((tri.upper >= 0) & (tri.upper <= 1)).all()


def test_nan_and_inf_pixels_are_replaced():
    plate = np.full((H, W, 3), 0.5, np.float32)
    plate[10, 10] = np.nan
    plate[20, 20, 1] = np.inf
    env = environment_map(plate, BBOX, size=64)
    assert np.isfinite(env).all()


def test_grey_and_rgba_plates():
    grey = np.full((H, W), 0.3, np.float32)
    rgba = np.concatenate([np.full((H, W, 3), 0.3, np.float32), np.zeros((H, W, 1))], -1)
    for plate in (grey, rgba):
        assert np.allclose(environment_map(plate, BBOX, size=32), 0.3, atol=1e-5)


def test_maps_of_one_plate_share_its_pyramid(monkeypatch):
    """With a dict kept for the plate, several maps (objects, methods) build its pyramid once
    per set of levels, and the maps are those built without it."""
    from virtual_reflections import envmap

    rng = np.random.default_rng(3)
    plate = rng.random((H, W, 3), dtype=np.float32)
    params = (Params(), Params(method="camera", hfov=50.0))
    boxes = (BBOX, (100.0, 80.0, 160.0, 150.0))
    tables = [lookup_table(W, H, b, p, "latlong", 128) for p in params for b in boxes]
    alone = [envmap.apply_table(t, plate) for t in tables]
    built = []
    original = envmap.build_pyramid
    monkeypatch.setattr(
        envmap, "build_pyramid", lambda *a, **k: built.append(a[1:3]) or original(*a, **k)
    )
    pyramids = {}
    shared = [envmap.apply_table(t, plate, pyramids) for t in tables]
    for a, b in zip(alone, shared):
        np.testing.assert_array_equal(a, b)
    assert len(built) == len(set(built)) == len(pyramids) < len(tables)
