"""Command line — a pipeline contract, keep it stable:

    python -m virtual_reflections envmap PLATE -o OUT --bbox X0 Y0 X1 Y1 [--layout latlong|cube]
        [--width W] [--method camera|paper] [--hfov DEG] [--triangles N] [--enlarge F]
        [--border F] [--float]
    python -m virtual_reflections segment PLATE -o OVERLAY.png --bbox X0 Y0 X1 Y1 [same options]

--method camera (the default, the add-on's Camera View and the accuracy study's best) places
the plate by the plate camera's horizontal field of view, --hfov DEG, which it needs; --method
paper is Ropinski et al. 2004 (--triangles, --enlarge, --border; --hfov ignored). `frustum` is
accepted as an older name of `camera`. segment draws the paper's regions whatever the method.

--bbox is in plate pixels, origin top-left, y down, X1/Y1 exclusive; it may reach outside the
plate. OUT's extension picks the format (.exr with the standard envmap attribute, .hdr, or
sRGB-encoded .png/.jpg/.tif). Half-float EXR values beyond 65504 are clamped (--float keeps
them). OUT is written under a temporary name, read back whole and renamed: an existing OUT is
replaced only by a complete file.

Exit codes: 0 done; 2 bad input (one line on stderr, nothing written); 1 a failure while
working (a full disk, not enough memory: one line, nothing replaced); 130 interrupted
(Ctrl-C), 143 terminated (SIGTERM), temporary files removed. Never a traceback for these.

The accuracy study and the speed benchmark are not part of the engine: `python -m study`.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time

from . import backends
from .atomic_files import ImageError, same_file
from .cli_common import (
    EXIT_BAD_INPUT,
    EXIT_DONE,
    EXIT_FAILED,
    Parser,
    Terminated,
    UsageError,
    error_line,
    stopped,
)
from .envmap import DEFAULT_SIZE
from .imagefiles import check_writable, read_header, read_plate, write_map
from .interrupts import hold_interrupts, raising, silent
from .memory import check_fits, plate_job_bytes
from .methods import MAX_TRIANGLES, METHOD_ALIASES, PLATE_METHODS
from .params import Params
from .table import max_size

NAME = "virtual_reflections"  # how its messages start
PROG = "python -m virtual_reflections"
# --width, per layout: up to the largest map whose lookup table fits its compact form
WIDTH_RANGE = {"latlong": (8, max_size("latlong")), "cube": (4, max_size("cube"))}


def _add_map_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("plate", metavar="PLATE", help="background plate (EXR, HDR, PNG, JPEG, TIFF...)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="output file")
    p.add_argument(
        "--bbox",
        nargs=4,
        type=float,
        required=True,
        metavar=("X0", "Y0", "X1", "Y1"),
        help="object bounds in plate pixels (origin top-left, y down, X1/Y1 exclusive)",
    )
    p.add_argument(
        "--layout",
        choices=("latlong", "cube"),
        default="latlong",
        help="latlong (default): OpenEXR's lat-long map, width 2 x height; cube: OpenEXR's "
        "vertical strip of six faces, +X -X +Y -Y +Z -Z top to bottom (docs/conventions.md)",
    )
    p.add_argument(
        "--width",
        type=int,
        default=None,
        help="lat-long width (height = width/2) or cube face size "
        f"(default {DEFAULT_SIZE['latlong']} lat-long, {DEFAULT_SIZE['cube']} cube; at most "
        f"{WIDTH_RANGE['latlong'][1]} lat-long, {WIDTH_RANGE['cube'][1]} cube)",
    )
    p.add_argument(
        "--triangles",
        type=int,
        default=0,
        help=f"n front-face triangles, a multiple of 4 (4..{MAX_TRIANGLES}); 0 = continuous limit",
    )
    p.add_argument(
        "--enlarge",
        type=float,
        default=Params.enlarge,
        help="enlargement of the bounds, fraction of the image size (default 0.075)",
    )
    p.add_argument(
        "--border",
        type=float,
        default=Params.border,
        help="minimum distance of X from the border, fraction (default 0.15)",
    )
    p.add_argument(
        "--hfov",
        type=float,
        default=None,
        metavar="DEG",
        help="the plate camera's horizontal field of view in degrees (needed by --method camera)",
    )
    p.add_argument(
        "--method",
        choices=PLATE_METHODS + tuple(METHOD_ALIASES),
        metavar="{" + ",".join(PLATE_METHODS) + "}",
        default="camera",
        help="camera (default): the plate placed by --hfov, unseen directions filled from its "
        "edges (the add-on's Camera View); paper: Ropinski et al. 2004 (frustum: an older "
        "name of camera)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog=PROG,
        description="Environment maps from a plate, after Ropinski et al. 2004.",
        allow_abbrev=False,  # `--wid` is no `--width`: each option by its whole name
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    p = sub.add_parser(
        "envmap", help="build the environment map of an object on a plate", allow_abbrev=False
    )
    _add_map_options(p)
    p.add_argument("--float", action="store_true", help="write EXR as 32-bit float (default half)")
    p = sub.add_parser(
        "segment", help="draw the paper's segmentation over the plate", allow_abbrev=False
    )
    _add_map_options(p)
    return parser


def _check_files(args) -> None:
    """The plate and the output are two files, and the output can be written."""
    check_writable(args.output)
    if same_file(args.plate, args.output):
        raise UsageError(f"the output is the plate itself: {args.output} (choose another -o)")


def _check_width(args) -> None:
    if args.width is None:
        return
    low, high = WIDTH_RANGE[args.layout]
    if not low <= args.width <= high:
        raise UsageError(
            f"--width for a {args.layout} map must be from {low} to {high}, not {args.width}"
        )


def _params(args, method=None) -> Params:
    """Params from the options; `method` overrides --method (segment: the paper's regions)."""
    x0, y0, x1, y1 = args.bbox
    if not all(math.isfinite(v) for v in args.bbox):
        raise UsageError(f"--bbox needs four finite numbers, got {' '.join(map(str, args.bbox))}")
    if not (x0 < x1 and y0 < y1):
        raise UsageError(f"--bbox needs X0 < X1 and Y0 < Y1, got {x0:g} {y0:g} {x1:g} {y1:g}")
    method = method or METHOD_ALIASES.get(args.method, args.method)
    if method == "camera" and args.hfov is None:
        raise UsageError(
            "--method camera needs --hfov DEG (the plate camera's horizontal field of view); "
            "or use --method paper"
        )
    try:
        return Params(
            enlarge=args.enlarge,
            border=args.border,
            triangles=args.triangles,
            hfov=args.hfov,
            method=method,
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from exc


def run_envmap(args) -> None:
    from .envmap import apply_table
    from .table import lookup_table

    params = _params(args)
    _check_width(args)
    _check_files(args)
    started = time.perf_counter()
    size = args.width or DEFAULT_SIZE[args.layout]
    header = read_header(args.plate)
    map_pixels = size * size // 2 if args.layout == "latlong" else 6 * size * size
    check_fits(
        plate_job_bytes(
            header.width, header.height, map_pixels, stored_pixels=header.stored_pixels
        ),
        f"a map from the {header.width}x{header.height} plate {args.plate}{header.stored_note}",
    )
    plate = read_plate(args.plate)
    h, w = plate.pixels.shape[:2]
    try:
        table = lookup_table(w, h, tuple(args.bbox), params, args.layout, size)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    env = apply_table(table, plate.pixels)
    clamped = write_map(args.output, env, layout=args.layout, half=not args.float)
    seg = table.segmentation
    notes = []
    if clamped:
        notes.append(f"warning: clamped {clamped} values above 65504 to fit half floats (--float)")
    if plate.nonfinite:
        notes.append(f"replaced {plate.nonfinite} NaN/Inf values")
    if seg.shrunk:
        notes.append("region X is smaller than the object's bounds (near the border)")
    print(
        f"wrote {args.output}: {args.layout} {env.shape[1]}x{env.shape[0]} from a {w}x{h} "
        f"{plate.encoding} plate in {1000 * (time.perf_counter() - started):.0f} ms"
        + "".join(f"; {n}" for n in notes)
    )


def run_segment(args) -> None:
    from .overlay import draw_segmentation
    from .segmentation import segment

    params = _params(args, method="paper")  # the regions are the paper's whatever --method says
    _check_files(args)
    header = read_header(args.plate)
    check_fits(
        plate_job_bytes(header.width, header.height, stored_pixels=header.stored_pixels)
        + header.width * header.height * 24,
        f"a segmentation of the {header.width}x{header.height} plate {args.plate}"
        + header.stored_note,
    )
    plate = read_plate(args.plate)
    h, w = plate.pixels.shape[:2]
    seg = segment(w, h, args.bbox, params)
    write_map(args.output, draw_segmentation(plate.pixels, seg, params.triangles))
    print(
        f"wrote {args.output}: segmentation of a {w}x{h} plate"
        + (" (X shrunk to keep the border distance)" if seg.shrunk else "")
    )


def _numbers_after_bbox(argv):
    """``--bbox -1e2 ...``: argparse takes a token like -1e2 for an option; a leading space
    keeps it a number (float() ignores it)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    for i, token in enumerate(argv):
        if token == "--bbox":
            for j in range(i + 1, min(i + 5, len(argv))):
                try:
                    float(argv[j])
                except ValueError:
                    break
                if argv[j].startswith("-"):
                    argv[j] = " " + argv[j]
    return argv


def _stop(signum):
    """The exception a signal stops the run with (interrupts.raising holds it while a
    compiled kernel loads or runs)."""
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def main(argv=None) -> int:
    previous = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is not signal.SIG_IGN:  # nohup's stays ignored
                previous[sig] = signal.signal(sig, raising(_stop))
    except ValueError:  # not the main thread: leave signals alone
        pass
    hook, held = sys.unraisablehook, []
    sys.unraisablehook = hold_interrupts(hook, held)
    try:
        args = build_parser().parse_args(_numbers_after_bbox(argv))
        with backends.preferring("numpy"):  # one map a call: faster than loading Numba
            if args.command == "envmap":
                run_envmap(args)
            else:
                run_segment(args)
        if held:  # an interrupt that landed in a callback from C
            raise held[-1]
    except (UsageError, ImageError) as exc:
        error_line(NAME, exc)
        return getattr(exc, "exit_code", EXIT_BAD_INPUT)
    except MemoryError as exc:
        error_line(NAME, str(exc) or "out of memory (try a smaller --width or plate)")
        return EXIT_FAILED
    except KeyboardInterrupt as exc:  # Ctrl-C, or Terminated (SIGTERM)
        hook = silent
        return stopped(NAME, exc)
    finally:
        sys.unraisablehook = hook
        for sig, handler in previous.items():
            if handler is not None:  # None: a handler set outside Python
                signal.signal(sig, handler)
    return EXIT_DONE
