"""The headless batch's options (operators/batch/options.py): render_shot's defaults, one-line
checks, immutability, and render_sample building them. render_shot.parse needs no bpy."""

import dataclasses
import importlib.util
import pathlib
import subprocess
import sys
import textwrap
from types import SimpleNamespace

import pytest
from shots import addon_part

ROOT = pathlib.Path(__file__).resolve().parents[2]
BASE = ["--plate", "plate.exr", "--out", "out"]


def _load(name, path):
    """A file of the repository as a module of its own (a script, not part of the add-on)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="module")
def batch_options():
    return addon_part("operators.batch.options")


@pytest.fixture(scope="module")
def render_shot():
    return _load("vr_test_render_shot", "render_shot.py")


def test_parse_needs_no_bpy():
    """render_shot.parse works where importing bpy fails (one-line errors before Blender)."""
    code = textwrap.dedent(
        f"""
        import importlib.util, sys
        sys.modules["bpy"] = None  # import bpy raises ImportError
        path = {str(ROOT / "render_shot.py")!r}
        spec = importlib.util.spec_from_file_location("render_shot", path)
        render_shot = sys.modules["render_shot"] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(render_shot)
        print(render_shot.parse({BASE!r} + ["--frames", "1-3"]).frames)
        """
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == "1-3", r.stderr


@pytest.mark.parametrize(
    "abbreviation", [["--ou", "elsewhere"], ["--pla=p2.exr"], ["--rep", "r.json"], ["--fra", "2"]]
)
def test_abbreviated_options_are_refused(render_shot, capsys, abbreviation):
    """issue 40, row 30: argparse took `--ou` for `--out` (the last one won), so a farm's
    refusal of `--out` after `--` was bypassed; render_shot knows only whole option names."""
    with pytest.raises(SystemExit) as exit:
        render_shot.parse([*BASE, *abbreviation])
    assert exit.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith("render_shot: error: unrecognized arguments: " + abbreviation[0])


def test_every_option_says_what_it_does(render_shot):
    """render_shot --help: a TD reads what each option does, and its default where the shot's
    own setting is kept."""
    actions = [a for a in render_shot.parser()._actions if a.dest != "help"]
    assert len(actions) > 20
    silent = [a.dest for a in actions if not (a.help or "").strip()]
    assert not silent, silent
    text = render_shot.parser().format_help()
    assert "--combine {REPLACE,MODULATE,MIX,WORLD}" in text and "the shot's setting" in text


def test_defaults_are_render_shots(batch_options, render_shot):
    BatchOptions = batch_options.BatchOptions
    namespace = render_shot.parse(BASE)
    # Every option render_shot parses is a field, and the other way round.
    assert set(vars(namespace)) == set(batch_options.FIELDS)
    options = BatchOptions.from_namespace(namespace)
    assert options == BatchOptions(plate="plate.exr", out="out")
    for field in dataclasses.fields(BatchOptions):
        assert getattr(options, field.name) == getattr(namespace, field.name), field.name
        if field.default is not dataclasses.MISSING:
            assert field.default == getattr(namespace, field.name), field.name
    assert options.passes == 1 and options.format == "exr" and options.objects is None
    assert options.no_reflections is False and options.overwrite is False


def test_from_namespace_keeps_every_value(batch_options, render_shot):
    argv = [
        *BASE,
        "shot.blend",
        *("--objects", "A", "B", "--combine", "MIX", "--resolution", "512"),
        *("--triangles", "0", "--method", "paper", "--engine", "EEVEE", "--samples", "8"),
        *("--scale", "25", "--passes", "auto", "--tolerance", "0.01", "--max-passes", "4"),
        *("--name", "n", "--frames", "1-10x2", "--format", "png"),
        *("--overwrite", "--report", "r.json", "--smoothing", "0.9"),
    ]
    options = batch_options.BatchOptions.from_namespace(render_shot.parse(argv))
    assert options.blend == "shot.blend" and options.objects == ("A", "B")
    assert (options.combine, options.resolution, options.triangles) == ("MIX", 512, 0)
    assert (options.method, options.engine, options.samples, options.scale) == (
        "paper",
        "EEVEE",
        8,
        25,
    )
    assert (options.passes, options.tolerance, options.max_passes) == ("auto", 0.01, 4)
    assert not options.no_reflections and options.overwrite and options.name == "n"
    assert (options.frames, options.format, options.report) == ("1-10x2", "png", "r.json")
    assert options.smoothing == 0.9 and options.frame is None
    plain = render_shot.parse([*BASE, "--no-reflections"])  # (not with --passes: refused)
    assert batch_options.BatchOptions.from_namespace(plain).no_reflections


def test_frozen(batch_options):
    options = batch_options.BatchOptions(plate="p", out="o", objects=["A"])
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.plate = "other"
    assert options.objects == ("A",)  # a tuple: nothing inside changes either
    assert hash(options) == hash(batch_options.BatchOptions(plate="p", out="o", objects=("A",)))
    changed = dataclasses.replace(options, frame=3)
    assert changed.frame == 3 and options.frame is None


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"frame": 1, "frames": "1-3"}, "give --frame or --frames, not both"),
        ({"format": "tif"}, "--format must be exr or png, not 'tif'"),
        ({"frames": "3-1"}, "bad frame range '3-1'"),
        ({"frames": "1-"}, "bad frame range '1-'"),
        ({"passes": 0}, "expected a number of passes >= 1 or auto, not 0"),
        ({"passes": "some"}, "expected a number of passes >= 1 or auto"),
        ({"smoothing": 0.99}, "expected a number from 0 to 0.95, not 0.99"),
        ({"contact_shadow": 1.5}, "--contact-shadow: expected a number from 0 to 1, not 1.5"),
        ({"contact_shadow": "half"}, "--contact-shadow: expected a number from 0 to 1"),
        ({"sky_brightness": -2}, "--sky-brightness: expected a number from 0 to 100, not -2"),
        ({"sky_texture": 2}, "--sky-texture: expected a number from 0 to 1, not 2"),
        ({"sky_texture": -0.5}, "--sky-texture: expected a number from 0 to 1, not -0.5"),
        ({"combine": "ADD"}, "--combine must be REPLACE, MODULATE, MIX or WORLD, not 'ADD'"),
        ({"method": "CAMERA"}, "--method must be ground, camera or paper"),
        ({"engine": "WORKBENCH"}, "--engine must be CYCLES or EEVEE"),
        ({"resolution": 300}, "--resolution must be 256, 512, 1024, 2048, 4096 or AUTO, not 300"),
        ({"samples": -1}, "--samples must be a number >= 0"),
        ({"scale": 12.5}, "--scale must be a number >= 0"),
        ({"max_passes": -2}, "--max-passes must be a number >= 0"),
        ({"tolerance": -0.1}, "--tolerance must be a number >= 0"),
        ({"frame": "7"}, "--frame must be a frame number"),
        ({"objects": "Sphere"}, "--objects must be a list of object names"),
        ({"overwrite": "yes"}, "--overwrite is on or off"),
        ({"plate": None}, "--plate must be text"),
    ],
)
def test_bad_values_are_one_line(batch_options, changes, message):
    values = {"plate": "p", "out": "o", **changes}
    with pytest.raises(ValueError) as bad:
        batch_options.BatchOptions(**values)
    text = str(bad.value)
    assert message in text and "\n" not in text


def test_paths_become_text(batch_options, tmp_path):
    options = batch_options.BatchOptions(plate=tmp_path / "p.exr", out=tmp_path, report=tmp_path)
    assert options.plate == str(tmp_path / "p.exr") and options.out == str(tmp_path)
    assert isinstance(options.report, str)


def test_render_samples_options_are_batch_options(batch_options):
    render_sample = _load("vr_test_render_sample_options", "sample_scenes/render_sample.py")
    built = SimpleNamespace(
        plate_path="/plates/courtyard.exr",
        objects=[SimpleNamespace(name="Sphere"), SimpleNamespace(name="Cube")],
        combine="MIX",
    )
    BatchOptions = batch_options.BatchOptions
    made = [
        render_sample.batch_options(BatchOptions, "spheres", built, "/w", r, scale=10, samples=4)
        for r in (False, True)
    ]
    assert all(isinstance(o, BatchOptions) for o in made)
    without, with_ = made
    assert (without.name, with_.name) == ("spheres_without", "spheres_with")
    assert without.no_reflections and not with_.no_reflections
    assert with_ == dataclasses.replace(without, no_reflections=False, name="spheres_with")
    assert with_.objects == ("Sphere", "Cube") and with_.combine == "MIX"
    assert (with_.plate, with_.out, with_.scale, with_.samples) == (
        "/plates/courtyard.exr",
        "/w",
        10,
        4,
    )
    # The rest as render_shot leaves it by default.
    assert (with_.passes, with_.frames, with_.frame, with_.resolution) == (1, None, None, None)


# Issue 14, case 11: every option checked up front, one line (docs/failures.md).
@pytest.mark.parametrize(
    "fields,message",
    [
        ({"resolution": 0}, "--resolution must be"),
        ({"resolution": 3}, "--resolution must be"),
        ({"triangles": 7}, "--triangles must be 0 or a multiple of 4"),
        ({"samples": -5}, "--samples must be a number >= 0"),
        ({"scale": -50}, "--scale must be a number >= 0"),
        ({"scale": 20000}, "--scale must be from 1 to 10000"),
        ({"max_passes": 0}, "--max-passes must be at least 1"),
        ({"tolerance": -1}, "--tolerance must be a number >= 0"),
        ({"name": "../x"}, "--name must be a file name"),
        ({"name": ".hidden"}, "--name must be a file name"),
        # Issue 40, 27: another name's outputs (run a's CG elements are a_render.####.exr).
        ({"name": "a_render"}, "--name must not end in _render or _composite"),
        ({"name": "a_COMPOSITE"}, "--name must not end in _render or _composite"),
        # Issue 40, 40: control characters; --passes with nothing to reflect.
        ({"name": "a\nb"}, "--name must be a file name without control characters"),
        ({"name": "a\x7fb"}, "--name must be a file name without control characters"),
        ({"no_reflections": True, "passes": 3}, "--passes 3 with --no-reflections"),
        ({"no_reflections": True, "passes": "auto"}, "--passes auto with --no-reflections"),
        # Issue 42, 5: --scale 0 rendered at the shot's 100 %.
        ({"scale": 0}, "--scale must be from 1 to 10000, not 0"),
    ],
)
def test_bad_values_are_refused_up_front(batch_options, fields, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        batch_options.BatchOptions(plate="p.png", out="out", **fields)


def test_resolution_auto_can_be_passed(batch_options):
    assert batch_options.BatchOptions(plate="p", out="o", resolution="AUTO").resolution == "AUTO"


def test_the_sky_tint_is_three_numbers(render_shot, capsys):
    """--sky-tint R,G,B: three numbers, else one line and exit code 2 before Blender."""
    assert render_shot.parse([*BASE, "--sky-tint", "0.5,0.7,1"]).sky_tint == (0.5, 0.7, 1.0)
    for bad in ("blue", "0.5,0.7"):
        with pytest.raises(SystemExit) as stop:
            render_shot.parse([*BASE, "--sky-tint", bad])
        assert stop.value.code == 2
        err = capsys.readouterr().err.strip()
        assert "expected R,G,B (three numbers)" in err and "\n" not in err


def test_the_sky_texture_is_a_number_from_0_to_1(batch_options, render_shot, capsys):
    """--sky-texture K: parsed as a number; out of 0..1, one line on stderr and exit code 2
    before the shot is opened."""
    namespace = render_shot.parse([*BASE, "--sky-texture", "0.5"])
    assert batch_options.BatchOptions.from_namespace(namespace).sky_texture == 0.5
    assert render_shot.parse(BASE).sky_texture is None  # not given: the shot's own
    capsys.readouterr()
    assert render_shot.main([*BASE, "--sky-texture", "2"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "render_shot: error: --sky-texture: expected a number from 0 to 1, not 2.0"
    ]


def test_the_parser_is_built_from_the_options_definitions(batch_options, render_shot):
    """Issue 43, item 5: render_shot's options are BatchOptions' fields, their choices the
    engine's lists (virtual_reflections/methods.py), its exit codes and parser the engine
    CLI's (virtual_reflections/cli_common.py)."""
    methods = addon_part("virtual_reflections.methods")
    common = addon_part("virtual_reflections.cli_common")
    actions = {a.dest: a for a in render_shot.parser()._actions if a.dest != "help"}
    assert tuple(actions) == batch_options.FIELDS
    assert tuple(actions["method"].choices) == methods.METHOD_NAMES
    assert tuple(actions["surroundings"].choices) == methods.SURROUNDINGS_NAMES
    assert tuple(actions["combine"].choices) == methods.COMBINE_NAMES
    for field in dataclasses.fields(batch_options.BatchOptions):
        assert actions[field.name].help == field.metadata["help"], field.name
    # The extension's package render_shot finds (pytest may have imported the repository
    # under another name): its parser class and Terminated are the engine CLI's.
    shared = render_shot._common()
    assert shared.__file__ == common.__file__ and shared.__name__.endswith(".cli_common")
    assert type(render_shot.parser()) is shared.Parser
    assert shared.EXIT_BAD_INPUT == common.EXIT_BAD_INPUT == 2


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--smoothing", "0.99"], "--smoothing: expected a number from 0 to 0.95, not 0.99"),
        (["--passes", "0"], "--passes: expected a number of passes >= 1 or auto, not 0"),
        (["--passes", "some"], "--passes: expected a number of passes >= 1 or auto, not 'some'"),
        (["--resolution", "wide"], "--resolution must be 256, 512, 1024, 2048, 4096 or AUTO"),
        (["--sky-tint", "2,0,0"], "--sky-tint: expected R,G,B from 0 to 1"),
        (["--triangles", "2000"], "--triangles must be 0 or a multiple of 4 from 4 to 1024"),
    ],
)
def test_each_value_is_checked_once_by_the_options(batch_options, render_shot, argv, message):
    """The parser's types only turn text into values; BatchOptions checks them (one line)."""
    namespace = render_shot.parse([*BASE, *argv])
    with pytest.raises(ValueError) as bad:
        batch_options.BatchOptions.from_namespace(namespace)
    assert message in str(bad.value) and "\n" not in str(bad.value)
