"""The paper's regions (§3.2): enlargement, border distance, bisection, centre lines."""

import pytest

from virtual_reflections import Params, segment


def test_region_x_is_the_enlarged_box_away_from_borders():
    seg = segment(1000, 500, (400, 200, 600, 300))
    assert seg.x.x0 == pytest.approx(400 - 75) and seg.x.x1 == pytest.approx(600 + 75)
    assert seg.x.y0 == pytest.approx(200 - 37.5) and seg.x.y1 == pytest.approx(300 + 37.5)
    assert not seg.shrunk
    assert seg.centre == (500, 250)


def test_inner_boundary_of_f_bisects_x_and_the_border():
    seg = segment(1000, 500, (400, 200, 600, 300))
    assert seg.inner.x0 == pytest.approx(seg.x.x0 / 2)
    assert seg.inner.x1 == pytest.approx((seg.x.x1 + 1000) / 2)
    assert seg.inner.y0 == pytest.approx(seg.x.y0 / 2)
    assert seg.inner.y1 == pytest.approx((seg.x.y1 + 500) / 2)


def test_x_keeps_the_border_distance_and_can_be_smaller_than_the_box():
    seg = segment(1000, 500, (20, 400, 300, 495), Params(border=0.15))
    assert seg.x.x0 == pytest.approx(150) and seg.x.y1 == pytest.approx(425)
    assert seg.shrunk
    # The centre lines stay strictly inside X so every face has both halves.
    assert seg.x.x0 < seg.centre[0] < seg.x.x1 and seg.x.y0 < seg.centre[1] < seg.x.y1


@pytest.mark.parametrize(
    "bbox",
    [
        (-500, -500, -400, -400),
        (2000, 100, 2100, 200),
        (0, 0, 1000, 500),
        (-100, -100, 1100, 600),
        (500, 250, 500, 250),
        (0, 0, 1, 1),
    ],
)
def test_x_never_collapses(bbox):
    seg = segment(1000, 500, bbox)
    assert seg.x.width > 0 and seg.x.height > 0
    assert 150 <= seg.x.x0 < seg.x.x1 <= 850 and 75 <= seg.x.y0 < seg.x.y1 <= 425
    assert seg.inner.x0 < seg.x.x0 and seg.inner.x1 > seg.x.x1


def test_tiny_plate():
    seg = segment(1, 1, (0, 0, 1, 1))
    assert 0 < seg.x.x0 < seg.x.x1 < 1


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(triangles=6),
        dict(triangles=2048),
        dict(border=0.5),
        dict(enlarge=-0.1),
        dict(hfov=0),
        dict(triangles=True),
    ],
)
def test_bad_params_are_refused(kwargs):
    with pytest.raises(ValueError):
        Params(**kwargs)


def test_inverted_box_is_refused():
    with pytest.raises(ValueError, match="x0 <= x1"):
        segment(100, 100, (50, 10, 40, 20))
