"""The ground method's sky gain is the one the study derives from the training HDRIs."""

import pytest

pytest.importorskip("bpy", reason="the HDRIs ship with the bpy module")

from study import sky_prior  # noqa: E402
from virtual_reflections import Params  # noqa: E402


def test_the_default_sky_gain_is_the_studys(capsys):
    chosen = sky_prior.run()
    assert Params().sky_gain == pytest.approx(chosen)
    table = capsys.readouterr().out
    assert "held out" in table and table.count("| yes |") == len(sky_prior.TRAIN)
