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
frame: the plate file, the settings, the extension's version; operators/batch/record.py), are
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

The options are `BatchOptions`' fields (operators/batch/options.py): the parser is built from
them, and what it parses goes to the batch (operators/batch/shot.py) as one `BatchOptions`, checked
once when it is made, right after parsing. Exit codes, `Terminated` and the one-line parser
are the engine's command line's too (virtual_reflections/cli_common.py).

Exit codes (docs/pipeline.md): 0 done; 2 bad input (one line, nothing written); 1 a failure
once the run began (a full disk, a damaged plate frame, out of memory, or anything the tool
did not expect: one line, "internal error: ..."); 130 Ctrl-C, 143 SIGTERM. Under a Blender
binary the entry exits Blender with that code itself; also pass `--python-exit-code 1`, so
that an error before the entry runs (a script Blender cannot read) is not exit code 0.
Set VR_TRACEBACK=1 to see the traceback of an internal error.
"""

import importlib.util
import os
import signal
import sys
import time
import traceback
from importlib import import_module

NAME = "render_shot"  # how its messages start
_NOT_RUN = "_vr_init_not_run"  # on a package module made here whose __init__ has not run yet


def _package():
    """This extension's package: the one Blender (or a test) imported, else made here from
    this file's folder under a private name, its __init__ not run yet (that needs bpy;
    reading the command line does not: `_addon` runs it). Looked up at each call: a package
    imported since takes the place of one made here."""
    if __package__:
        return sys.modules[__package__]
    here = os.path.dirname(os.path.abspath(__file__))
    init = os.path.join(here, "__init__.py")
    found = [m for m in list(sys.modules.values()) if getattr(m, "__file__", None) == init]
    found.sort(key=lambda m: getattr(m, _NOT_RUN, False))  # one whose __init__ ran first
    if found:
        return found[0]
    spec = importlib.util.spec_from_file_location(
        "vr_render_shot_addon", init, submodule_search_locations=[here]
    )
    module = importlib.util.module_from_spec(spec)
    setattr(module, _NOT_RUN, True)
    sys.modules[spec.name] = module
    return module


def _addon():
    """(this extension's package, whether this file imported it): the enabled extension if
    Blender loaded it, else imported from this file's folder (a checkout)."""
    module = _package()
    if not getattr(module, _NOT_RUN, False):
        return module, False
    delattr(module, _NOT_RUN)
    module.__spec__.loader.exec_module(module)
    return module, True


def _part(name):
    """The add-on's module ``name`` (``operators.batch.shot``,
    ``virtual_reflections.cli_common``)."""
    return import_module(f"{_package().__name__}.{name}")


def _common():
    """The engine's virtual_reflections/cli_common.py: exit codes, Terminated, the parser."""
    return _part("virtual_reflections.cli_common")


def _raising(exception):
    """A signal handler that raises ``exception`` where the process is."""

    def handler(signum, frame):
        raise exception()

    return handler


def _silent(info):
    """An unraisablehook that prints nothing."""


def parse(argv):
    """The command line -> an argparse namespace whose attributes are BatchOptions' fields
    (`batch_options` makes it one). Needs no bpy. A bad command line: one line on stderr,
    SystemExit(2)."""
    common = _common()
    try:
        return parser().parse_args(argv)
    except common.UsageError as exc:
        common.error_line(NAME, exc)
        raise SystemExit(common.EXIT_BAD_INPUT) from None


def parser():
    """The command line's options, each with its help: BatchOptions' fields
    (operators/batch/options.py)."""
    p = _common().Parser(prog=NAME, description=__doc__.splitlines()[0], allow_abbrev=False)
    _part("operators.batch.options").add_arguments(p)
    return p


def main(argv=None):
    import bpy

    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    try:
        args = parse(argv)
    except SystemExit as exc:
        return 2 if exc.code else 0  # cli_common.EXIT_BAD_INPUT
    except ImportError as exc:  # the batch's options need NumPy: the dependency check says so
        return _missing_dependency(exc)
    common = _common()
    try:
        previous = signal.signal(signal.SIGTERM, _raising(common.Terminated))
    except ValueError:  # not the main thread
        previous = None
    try:
        addon, own = _addon()
        if _missing(addon):
            return common.EXIT_BAD_INPUT
        options = batch_options(addon, args)
        with _module(addon, "operators.batch.signals").stop_on_signals():
            return run(bpy, addon, own, options)
    except (ValueError, OSError, RuntimeError) as exc:
        common.error_line(NAME, exc)
        return getattr(exc, "exit_code", common.EXIT_BAD_INPUT)  # 1: a frame failed mid-run
    except MemoryError as exc:
        message = str(exc) or "out of memory (a smaller --scale or plate, or a bigger machine)"
        common.error_line(NAME, message)
        return common.EXIT_FAILED
    except KeyboardInterrupt as exc:  # Ctrl-C; SIGTERM (Terminated, signals.Interrupted)
        code = common.stopped(NAME, exc)
        # The run ends where it stopped: what it left half made (a kernel the optional
        # compiled back end was compiling) may fail in its destructor on the way out; print
        # nothing of that, this line said why the run ended.
        sys.unraisablehook = _silent
        return code
    except Exception as exc:  # a bug: still one line and a failure, never exit code 0
        if os.environ.get("VR_TRACEBACK"):
            traceback.print_exc()
        common.error_line(NAME, f"internal error: {type(exc).__name__}: {exc}")
        return common.EXIT_FAILED
    finally:
        if previous is not None:  # None: a handler set outside Python (Blender's)
            signal.signal(signal.SIGTERM, previous)


def _missing(addon) -> bool:
    """Whether NumPy or OpenImageIO is missing (distributions' Blender may have neither);
    if so, one line saying what to install."""
    for module in ("numpy", "OpenImageIO"):
        if not addon.dependencies.available(module):
            text = addon.dependencies.needs(module, "render_shot.py")
            line = next((line for line in text.splitlines() if line.strip()), module)
            print(f"{NAME}: error: {line}", file=sys.stderr, flush=True)
            return True
    return False


def _missing_dependency(exc):
    """The exit code when the command line could not be read for ``exc``, an ImportError:
    2 and one line naming what to install when NumPy or OpenImageIO is missing, else 1 and
    one line (an internal error)."""
    addon, _ = _addon()
    if _missing(addon):
        return 2  # cli_common.EXIT_BAD_INPUT (the engine, which defines it, did not load)
    print(f"{NAME}: error: internal error: ImportError: {exc}", file=sys.stderr, flush=True)
    return 1


def _module(addon, name):
    """The add-on's module ``name`` (``operators.batch.shot``)."""
    return import_module(f"{addon.__name__}.{name}")


def batch_options(addon, args):
    """The parsed command line as the add-on's BatchOptions; ValueError (one line) if an
    option is bad, before the shot is opened."""
    return _module(addon, "operators.batch.options").BatchOptions.from_namespace(args)


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
        return _module(addon, "operators.batch.shot").render_shot(options, started)
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
