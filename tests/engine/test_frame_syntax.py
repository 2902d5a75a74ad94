"""--frames accepts Blender's own frame syntax (``blender -f 1..10``, ``1,3,5..7``) beside
the batch's (``1-10``, ``1-10x2``); both name the same frames (issue 12)."""

import pytest

from virtual_reflections.frames import parse_frames


@pytest.mark.parametrize(
    "blender, ours",
    [("1..10", "1-10"), ("1,3,5..7", "1,3,5-7"), ("-3..-1", "-3--1"), ("1..9x4", "1-9x4")],
)
def test_blender_ranges_equal_ours(blender, ours):
    assert parse_frames(blender) == parse_frames(ours)


@pytest.mark.parametrize("bad", ["1...3", "3..1", "..3", "1..", "1..2..3", "1.-3"])
def test_bad_blender_ranges_are_one_line(bad):
    with pytest.raises(ValueError, match="bad frame range") as err:
        parse_frames(bad)
    assert "\n" not in str(err.value) and "1..240" in str(err.value)
