"""Headless batch entry: render a shot with virtual reflections and composite it over the plate.

    blender -c virtual_reflections shot.blend --plate PLATE --out DIR   (Blender 4.2+, enabled)
    blender -b shot.blend --python <extension>/render_shot.py -- --plate PLATE --out DIR
    python -m render_shot shot.blend --plate PLATE --out DIR        (bpy module, repo root)

The first form is the extension's command (`register`, bpy.utils.register_cli_command): no
need to know where the extension is installed; Blender exits with the run's exit code.

One frame (a still plate, no --frames): writes DIR/<shot>_render.exr (RGBA, linear),
DIR/<shot>_composite.png (sRGB) and .exr (linear), one line per stage with its time, and the
report DIR/<shot>.report.json (--report PATH) of that one frame.

A frame range (--frames 1-240, 1..240 as Blender's -f, 1-10x2, 5, 1,3,7-9; or a plate that is
a sequence plate.####.exr / plate.%04d.jpg, unless a file of that very name exists, or a movie,
then the scene's range by default): per frame the maps from that frame's plate, the composite
DIR/<shot>.<frame:04d>.exr|png (--format; PNG through the scene's view transform, named in the
report), the CG element DIR/<shot>_render.<frame:04d>.exr (the render alone, RGBA
scene-linear), a progress line, and the report DIR/<shot>.report.json (--report PATH)
rewritten after each frame. Frames already complete, and made by the same inputs (a record per
frame: the plate file, the settings, the extension's version; operators/batch_record.py), are
skipped unless --overwrite; a complete frame made by other inputs is rendered again and the
report says why. Every file is written under a temporary name and renamed, so a killed run
leaves no half-written frame and resumes where it stopped.

Options: --objects NAME [NAME ...] (default: marked objects, else every visible mesh-like
object), --combine REPLACE|MODULATE|MIX|WORLD, --resolution W, --triangles N, --frame F,
--engine CYCLES|EEVEE, --samples N, --scale PERCENT, --smoothing S (bounds over frames, 0..1),
--passes N|auto (inter-reflections between the objects, paper §3.3: N render passes, or until
the image settles; --tolerance T, --max-passes N), --no-reflections (the plain render, for
comparisons), --name STEM (not ending in _render or _composite: those are the batch's own
files). Bad input (a bad range, a missing plate frame, an unwritable folder, a --report that
is an input, an output or a file other than a report): one line on stderr, exit code 2,
nothing written.

The options go to the batch (operators/batch.py) as one `BatchOptions`
(operators/batch_options.py), checked when it is made, right after parsing.

Exit codes (docs/pipeline.md): 0 done; 2 bad input (one line, nothing written); 1 a failure
once the run began (a full disk, a damaged plate frame, out of memory, or anything the tool
did not expect: one line, "internal error: ..."); 130 Ctrl-C, 143 SIGTERM. Under a Blender
binary the entry exits Blender with that code itself; also pass `--python-exit-code 1`, so
that an error before the entry runs (a script Blender cannot read) is not exit code 0.
Set VR_TRACEBACK=1 to see the traceback of an internal error.
"""

import argparse
import importlib.util
import os
import signal
import sys
import time
import traceback

EXIT_BAD_INPUT = 2
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM (a farm cancelling the task), raised where the run is, so that its temporary
    files are removed on the way out."""


def _terminate(signum, frame):
    raise Terminated()


def _silent(info):
    """An unraisablehook that prints nothing."""


def _error(message):
    lines = [line for line in str(message).splitlines() if line.strip()]
    print(f"render_shot: error: {lines[0] if lines else 'failed'}", file=sys.stderr, flush=True)


def _addon():
    """This extension's package: the enabled extension if Blender loaded it, else imported
    from this file's folder (a checkout) under a private name."""
    here = os.path.dirname(os.path.abspath(__file__))
    init = os.path.join(here, "__init__.py")
    for module in list(sys.modules.values()):
        if getattr(module, "__file__", None) == init:
            return module, False
    spec = importlib.util.spec_from_file_location(
        "vr_render_shot_addon", init, submodule_search_locations=[here]
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module, True


def _passes(text):
    if text == "auto":
        return text
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a number of passes >= 1 or auto, not {text!r}")
    return int(text)


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line on stderr, not the usage block
        print(f"render_shot: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


def _resolution(text):
    """A map width (checked by BatchOptions) or AUTO (from the object's size on screen)."""
    if text.upper() == "AUTO":
        return "AUTO"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a map width or AUTO, not {text!r}") from None


def _unit(text):
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 <= value <= 0.95:
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 0.95, not {text!r}")
    return value


def _colour(text):
    """R,G,B (three numbers, checked by BatchOptions)."""
    parts = text.split(",")
    try:
        if len(parts) != 3:
            raise ValueError
        return tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected R,G,B (three numbers), not {text!r}") from None


def parse(argv):
    """The command line -> an argparse namespace whose attributes are BatchOptions' fields
    (`batch_options` makes it one). Needs no bpy."""
    return parser().parse_args(argv)


def parser() -> argparse.ArgumentParser:
    """The command line's options, each with its help."""
    p = _Parser(prog="render_shot", description=__doc__.splitlines()[0], allow_abbrev=False)
    p.add_argument("blend", nargs="?", help="the shot (.blend); omit under blender -b shot.blend")
    p.add_argument("--plate", required=True, help="background plate image file")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument(
        "--objects",
        nargs="+",
        default=None,
        metavar="NAME",
        help="the reflective objects (default: those marked in the panel, else every visible "
        "object with a surface but the ground they stand on: a shadow catcher, the chosen "
        "ground, the floor under them)",
    )
    p.add_argument(
        "--combine",
        choices=("REPLACE", "MODULATE", "MIX", "WORLD"),
        default=None,
        help="the look: REPLACE (chrome: the object shows the map), MODULATE (the material's "
        "colour times the map), MIX (the map blended over the material's own shader by "
        "strength and Fresnel), WORLD (one shared map as world lighting for any material); "
        "default: the shot's setting",
    )
    p.add_argument(
        "--resolution", type=_resolution, default=None, help="lat-long map width, or AUTO"
    )
    p.add_argument("--triangles", type=int, default=None, help="0 = continuous")
    p.add_argument(
        "--method",
        choices=("ground", "camera", "paper"),
        default=None,
        help="ground: the camera view with the ground seen from the object; camera: the plate "
        "placed by the camera's field of view; paper: Ropinski et al. (default: the shot's "
        "setting)",
    )
    p.add_argument(
        "--ground-object",
        default=None,
        metavar="NAME",
        help="the object the reflective objects stand on, for --method ground (default: the "
        "shot's setting, else a shadow catcher, else a flat mesh under them, else their lowest "
        "point)",
    )
    p.add_argument(
        "--surroundings",
        choices=("auto", "open", "enclosed", "world", "custom"),
        default=None,
        help="for --method ground, how bright the sky the plate does not show is taken to be: "
        "open (outdoors under open sky), enclosed (a dim room, a studio, a walled yard), auto "
        "(nothing known, or a brightly lit interior), world (the shot's world holds the on-set "
        "HDRI: it is used there) or custom (the shot's Sky Brightness, or --sky-brightness); "
        "default: the shot's setting",
    )
    p.add_argument(
        "--contact-shadow",
        type=float,
        default=None,
        metavar="K",
        help="for --method ground, how much the objects darken the ground they reflect around "
        "them: 1 the share of the sky they hide, 0 none (a plate that already shows their "
        "shadow); default: the shot's setting",
    )
    p.add_argument(
        "--sky-brightness",
        type=float,
        default=None,
        metavar="G",
        help="Surroundings custom: the unseen sky is G times the ground's brightness in the "
        "plate (0..100; auto takes 1.6, open 3.6, enclosed 0.7); default: the shot's setting",
    )
    p.add_argument(
        "--sky-tint",
        type=_colour,
        default=None,
        metavar="R,G,B",
        help="Surroundings custom: the unseen sky's colour, its brightness taken out (linear, "
        "0..1 each, e.g. 0.6,0.75,1 for a blue sky); default: the shot's setting",
    )
    p.add_argument("--frame", type=int, default=None, help="the frame (default: the shot's)")
    p.add_argument(
        "--engine", choices=("CYCLES", "EEVEE"), default=None, help="default: the shot's"
    )
    p.add_argument("--samples", type=int, default=None, help="render samples (default: the shot's)")
    p.add_argument("--scale", type=int, default=None, help="resolution percentage, 1 to 10000")
    p.add_argument(
        "--passes", type=_passes, default=1, help="inter-reflection passes r, or auto (default 1)"
    )
    p.add_argument("--tolerance", type=float, default=None, help="--passes auto: stop below")
    p.add_argument("--max-passes", type=int, default=None, help="--passes auto: at most")
    p.add_argument(
        "--no-reflections",
        action="store_true",
        help="render the shot over the plate without virtual reflections (a reference)",
    )
    p.add_argument("--name", default=None, help="output file stem (default: the .blend's name)")
    p.add_argument("--frames", default=None, help="1-240, 1..240, 1-10x2, 5 or 1,3,7-9")
    p.add_argument("--format", choices=("exr", "png"), default="exr", help="frame range output")
    p.add_argument("--overwrite", action="store_true", help="render complete frames again")
    p.add_argument(
        "--report",
        default=None,
        help="report path (default DIR/<name>.report.json); never an input, an output of the "
        "run or a file other than an earlier report",
    )
    p.add_argument("--smoothing", type=_unit, default=None, help="bounds smoothing 0..0.95")
    return p


def main(argv=None):
    import bpy

    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    try:
        args = parse(argv)
    except SystemExit as exc:
        return EXIT_BAD_INPUT if exc.code else 0
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread
        previous = None
    try:
        addon, own = _addon()
        for module in ("numpy", "OpenImageIO"):  # distributions' Blender may have neither
            if not addon.dependencies.available(module):
                _error(addon.dependencies.needs(module, "render_shot.py"))
                return EXIT_BAD_INPUT
        options = batch_options(addon, args)
        with _part(addon, "batch_signals").stop_on_signals():
            return run(bpy, addon, own, options)
    except (ValueError, OSError, RuntimeError) as exc:
        _error(exc)
        return getattr(exc, "exit_code", EXIT_BAD_INPUT)  # 1: a frame failed mid-run
    except MemoryError as exc:
        _error(str(exc) or "out of memory (a smaller --scale or plate, or a bigger machine)")
        return EXIT_FAILED
    except KeyboardInterrupt as exc:  # Ctrl-C; SIGTERM (Terminated, batch_signals.Interrupted)
        code = EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED
        code = getattr(exc, "exit_code", code)
        word = "terminated" if code == EXIT_TERMINATED else "interrupted"
        print(f"render_shot: {word}", file=sys.stderr, flush=True)
        # The run ends where it stopped: what it left half made (a kernel the optional
        # compiled back end was compiling) may fail in its destructor on the way out; print
        # nothing of that, this line said why the run ended.
        sys.unraisablehook = _silent
        return code
    except Exception as exc:  # a bug: still one line and a failure, never exit code 0
        if os.environ.get("VR_TRACEBACK"):
            traceback.print_exc()
        _error(f"internal error: {type(exc).__name__}: {exc}")
        return EXIT_FAILED
    finally:
        if previous is not None:  # None: a handler set outside Python (Blender's)
            signal.signal(signal.SIGTERM, previous)


def _part(addon, name):
    """The add-on's module operators.<name> (the batch's modules)."""
    from importlib import import_module

    return import_module(f"{addon.__name__}.operators.{name}")


def batch_options(addon, args):
    """The parsed command line as the add-on's BatchOptions; ValueError (one line) if an
    option is bad, before the shot is opened."""
    return _part(addon, "batch_options").BatchOptions.from_namespace(args)


def run(bpy, addon, own, options):
    started = time.perf_counter()
    if options.blend:
        if not os.path.isfile(options.blend):
            raise ValueError(f"shot not found: {options.blend}")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(options.blend))
    registered = own and not hasattr(bpy.types.Scene, "virtual_reflections")
    if registered:
        addon.register()
    try:
        return _part(addon, "batch").render_shot(options, started)
    finally:
        if registered:  # the bpy 4.5 module hangs at exit while classes stay registered
            addon.unregister()


# --- `blender -c virtual_reflections ...` (Blender 4.2+) -----------------------------------------

CLI_COMMAND = "virtual_reflections"
_cli = []  # the handle of the registered command


def command(argv):
    """The extension's command line: ``blender -c virtual_reflections [shot.blend] --plate ...``
    (every option of this script); returns the exit code Blender leaves with."""
    code = main(list(argv))
    sys.stdout.flush()
    sys.stderr.flush()
    return code


def register():
    """Register `command` with Blender (4.2+; older Blenders have no command lines to add)."""
    import bpy

    add = getattr(bpy.utils, "register_cli_command", None)
    if add is not None and not _cli:
        _cli.append(add(CLI_COMMAND, command))


def unregister():
    import bpy

    while _cli:
        bpy.utils.unregister_cli_command(_cli.pop())


def _exit(code):
    """Leave with ``code``. Under a Blender binary, sys.exit from a --python script ends
    Blender with that code; flush first, Blender's own exit does not."""
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(code)


if __name__ == "__main__":
    _exit(main())
