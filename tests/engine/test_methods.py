"""The choice lists, defined once (virtual_reflections/methods.py), and the command-line layer
both command lines share (virtual_reflections/cli_common.py): issue 43, items 1 and 5."""

import pytest

from virtual_reflections import cli, cli_common, methods
from virtual_reflections.params import MAX_TRIANGLES, METHODS, SKY_GAINS, Params


def test_the_panels_keys_and_order_are_kept():
    """A .blend stores an enum by its key and index: the keys stay upper case, in order."""
    assert [m.key for m in methods.METHODS] == ["GROUND", "CAMERA", "PAPER"]
    assert [s.key for s in methods.SURROUNDINGS] == ["AUTO", "OPEN", "ENCLOSED", "WORLD", "CUSTOM"]
    assert [c.key for c in methods.COMBINES] == ["REPLACE", "MODULATE", "MIX", "WORLD"]
    assert methods.METHOD_NAMES == ("ground", "camera", "paper") and METHODS == methods.METHOD_NAMES
    assert methods.SURROUNDINGS_NAMES == ("auto", "open", "enclosed", "world", "custom")


@pytest.mark.parametrize(
    "key, camera, ground, regions, distant",
    [
        ("GROUND", True, True, False, False),
        ("ground", True, True, False, False),
        ("CAMERA", True, False, False, True),
        ("frustum", True, False, False, True),
        ("PAPER", False, False, True, False),
    ],
)
def test_what_each_method_does_is_asked_not_re_decided(key, camera, ground, regions, distant):
    assert methods.uses_camera(key) is camera
    assert methods.reads_ground(key) is ground
    assert methods.cuts_regions(key) is regions
    assert methods.takes_all_distant(key) is distant


def test_a_view_takes_the_camera_method_only_under_a_perspective_camera():
    """GROUND's view is the engine's camera method (the ground is added per map)."""
    assert methods.view_method("GROUND", perspective=True) == "camera"
    assert methods.view_method("CAMERA", perspective=True) == "camera"
    assert methods.view_method("GROUND", perspective=False) == "paper"
    assert methods.view_method("PAPER", perspective=True) == "paper"


def test_the_world_hdri_is_read_only_with_the_ground_method():
    assert methods.takes_world_hdri("GROUND", "WORLD")
    assert not methods.takes_world_hdri("CAMERA", "WORLD")
    assert not methods.takes_world_hdri("GROUND", "AUTO")
    with pytest.raises(KeyError):
        methods.method("magic")


def test_params_and_the_engine_cli_take_the_definitions():
    assert SKY_GAINS is methods.SKY_GAINS and MAX_TRIANGLES == methods.MAX_TRIANGLES
    with pytest.raises(ValueError, match=f"from 4 to {MAX_TRIANGLES}"):
        Params(triangles=MAX_TRIANGLES + 4)
    sub = next(a for a in cli.build_parser()._actions if a.dest == "command")
    options = {a.dest: a for a in sub.choices["envmap"]._actions}
    assert tuple(options["method"].choices) == (*methods.PLATE_METHODS, *methods.METHOD_ALIASES)
    assert "ground" not in options["method"].choices  # the ground needs the scene's 3D
    assert str(MAX_TRIANGLES) in options["triangles"].help


def test_the_engine_cli_uses_the_shared_layer(capsys):
    """One Terminated, one set of exit codes, one one-line parser for both command lines."""
    assert cli.Terminated is cli_common.Terminated and cli.UsageError is cli_common.UsageError
    assert isinstance(cli.build_parser(), cli_common.Parser)
    assert cli.main(["envmap", "p.exr", "-o", "o.exr", "--bbox", "1", "2", "3", "4", "--wid", "8"])
    assert cli.main(["envmap"]) == cli_common.EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("virtual_reflections: error: ") for line in err)
    with pytest.raises(cli_common.UsageError):
        cli_common.Parser(prog="x").parse_args(["--unknown"])
    assert cli_common.Parser(prog="x").allow_abbrev is False


def test_what_each_look_does_is_defined_with_it():
    """The traced pass and Cycles' emission sampling take the looks whose map is the whole
    surface; the ground is read per point by the looks with a map per object."""
    assert methods.WHOLE_SURFACE_LOOKS == ("REPLACE", "MODULATE")
    assert methods.PER_OBJECT_LOOKS == ("REPLACE", "MODULATE", "MIX")
