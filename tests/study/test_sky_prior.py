"""The ground method's sky gains are the ones the study derives from the training HDRIs."""

import pytest

pytest.importorskip("bpy", reason="the HDRIs ship with the bpy module")

from study import sky_prior  # noqa: E402
from virtual_reflections import Params  # noqa: E402
from virtual_reflections.params import ROUGH_SKY_RATIOS, SKY_GAINS, sky_gain_for  # noqa: E402


def test_the_sky_gains_are_the_studys(capsys):
    chosen = sky_prior.run()
    # the ground band's gain for an average place (Custom's default; Auto now takes the
    # plate's mean colour: study.scenes3d.heldout_sky fit --auto)
    assert sky_gain_for("auto") == pytest.approx(chosen["auto"])
    rough = chosen.pop("rough")
    # the log-error variant (docs/scenes3d.md, "32 scenes more"): printed, not used
    assert chosen.pop("auto_log") == pytest.approx(1.7)
    assert chosen.keys() == SKY_GAINS.keys()
    # the rough surfaces' ratios are the study's, and grow with roughness from 1
    assert rough == ROUGH_SKY_RATIOS
    for kind, knots in rough.items():
        ratios = [1.0] + [ratio for _, ratio in knots]
        assert all(b >= a for a, b in zip(ratios, ratios[1:])), kind
    for kind, gain in SKY_GAINS.items():
        assert gain == pytest.approx(chosen[kind]), kind
    # the kinds order as their names say: open sky brighter than knowing nothing, enclosed darker
    assert SKY_GAINS["enclosed"] < SKY_GAINS["auto"] < SKY_GAINS["open"]
    table = capsys.readouterr().out
    assert "held out" in table and table.count("| yes |") == len(sky_prior.TRAIN)
    assert "(summing the log errors instead, as a mean PSNR does: 1.7)" in table
    # the held-out HDRIs are all open skies: the open gain predicts them better than auto's
    assert "| open | city, sunrise, sunset |" in table
    for line in table.splitlines():
        if line.startswith("| open |"):
            for check in line.split("|")[4].split(","):
                ours, auto = (float(v) for v in check.split()[-3::2])
                assert ours < auto, check


def test_the_level_statistics_gain_is_the_add_ons_at_its_exponent():
    """`gain_for_exponent` derives the gain as `run` does for any brightening of the band's
    level; at the add-on's own (Params.fill_energy) it is the add-on's gain, and a level
    brightened further toward the band's mean wants a smaller gain."""
    images = sky_prior.load_images()
    assert sky_prior.gain_for_exponent(images, Params().fill_energy) == pytest.approx(
        SKY_GAINS["auto"]
    )
    assert sky_prior.gain_for_exponent(images, 1.0) < SKY_GAINS["auto"]
    assert sky_prior.gain_for_exponent(images, 0.0) > SKY_GAINS["auto"]
