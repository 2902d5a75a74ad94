"""Command line of the study (run from the repository root):

    python -m study evaluate [--quick] [--out DIR] [--hdri NAME ...] [--jobs N]
    python -m study bench [--repeat N] [--chart PNG]
    python -m study scenes [--quick] [--cases failures|inter|motion|heldout|polyhaven] [--out DIR]
    python -m study scenes --mirror-only [--quick] [--cases more|heldout|polyhaven|all]
        [--cache DIR] [--sky-gain G] [--split]
        [--oracle shadow|proxies] [--contact-shadow K] [--out DIR]
    python -m study scenes --sheet PNG [--cache DIR] [--width W] [--samples N]
    python -m study sky-prior [--polyhaven]

`evaluate` measures every method against ground truth cut from Blender's bundled HDRIs
(docs/accuracy.md); `bench` times the engine's lookup tables against py360convert
(docs/benchmarks.md); `scenes` renders 3D scenes in Cycles with the bpy module and scores every
method against the path-traced truth (docs/scenes3d.md); `sky-prior` derives the ground
method's sky gain from the HDRIs (docs/ground.md). Bad input prints one line on stderr
and exits with code 2.
"""

from __future__ import annotations

import argparse
import sys

from virtual_reflections.atomic_files import ImageError

EXIT_BAD_INPUT = 2


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit code 2 (argparse prints the usage too)
        raise UsageError(message)


def _positive(text) -> int:
    """A whole number >= 1 (argparse type: a bad one is a one-line usage error)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="python -m study",
        description="Accuracy and speed of Virtual Reflections' environment maps.",
        allow_abbrev=False,
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_bench(sub)
    _add_evaluate(sub)
    p = sub.add_parser(
        "scenes", help="3D scenes path-traced in Cycles (docs/scenes3d.md)", allow_abbrev=False
    )
    _add_scenes_sets(p)
    _add_mirror_loop(p)
    _add_mirror_extras(p)
    p = sub.add_parser(
        "sky-prior",
        help="the ground method's sky gain from the HDRIs (docs/ground.md)",
        allow_abbrev=False,
    )
    p.add_argument(
        "--polyhaven",
        action="store_true",
        help="also derive the mirror's gain on the 15 Poly Haven HDRIs (study/polyhaven.py)",
    )
    return parser


def _add_bench(sub) -> None:
    """The `bench` sub-command's parser."""
    p = sub.add_parser(
        "bench", help="time table building and applying against py360convert", allow_abbrev=False
    )
    p.add_argument("--repeat", type=_positive, default=15, help="runs per figure (median)")
    p.add_argument(
        "--chart", metavar="PNG", help="also chart time and memory against map and plate size"
    )


def _add_evaluate(sub) -> None:
    """The `evaluate` sub-command's parser."""
    p = sub.add_parser(
        "evaluate", help="accuracy against Blender's HDRIs (docs/accuracy.md)", allow_abbrev=False
    )
    p.add_argument("--quick", action="store_true", help="a one-minute subset: print the ranking")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write DIR/accuracy.json, DIR/images/accuracy_*.png and the tables of "
        "DIR/accuracy.md (default: docs; with --quick nothing unless given)",
    )
    p.add_argument("--hdri", nargs="+", metavar="NAME", help="only these bundled HDRIs")
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: cores)")


def _add_scenes_sets(p) -> None:
    """`scenes`: which sets, how small, where the outputs go."""
    p.add_argument("--quick", action="store_true", help="two scenes, small: print the means")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write DIR/scenes3d.json, the tables of DIR/scenes3d.md and "
        "DIR/images/scenes3d_*.png (default: docs; with --quick nothing unless given)",
    )
    p.add_argument(
        "--cases",
        choices=("default", "failures", "inter", "motion", "heldout", "more", "polyhaven", "all"),
        default="default",
        help="failures: the failure cases instead (floating, looking up, wall, border, large, "
        "tiny): DIR/scenes3d_failures.json and the 'Where it fails' table of DIR/scenes3d.md; "
        "inter: two or three mirrors side by side, one pass against the passes: "
        "DIR/scenes3d_inter.json and the 'Inter-reflections' table; "
        "motion: a sliding sphere and a moving camera, the change per frame pair: "
        "DIR/scenes3d_motion.json and the 'In motion' table; "
        "heldout: 8 scenes under the two HDRIs nothing was tuned on: "
        "DIR/scenes3d_heldout.json and the 'Held-out HDRIs' table; "
        "more (with --mirror-only): 32 scenes more drawn as the default 16 are; "
        "polyhaven: 30 scenes under 15 Poly Haven HDRIs, none of Blender's, fetched once "
        "with npm (study/polyhaven.py): DIR/scenes3d_polyhaven.json and the 'Poly Haven "
        "HDRIs' table; all (with --mirror-only): default, more, heldout and polyhaven in "
        "turn, and the mirror over every set",
    )
    p.add_argument("--jobs", type=int, default=1, help="processes (only 1: Cycles uses every core)")


def _add_mirror_loop(p) -> None:
    """`scenes`: the fast mirror loop and the panel's settings it runs with."""
    p.add_argument(
        "--mirror-only",
        action="store_true",
        help="a fast loop: only the mirror subject, the default method and the plate mean; "
        "the plate, truth and plate-mean renders are cached (--cache), so a re-run renders "
        "only the method; prints the table (with --out: DIR/scenes3d_mirror.json only)",
    )
    p.add_argument(
        "--cache",
        metavar="DIR",
        help="with --mirror-only: where the renders are kept (default: "
        "$TMPDIR/vr_scenes3d_mirror_cache)",
    )
    p.add_argument(
        "--sky-gain",
        type=float,
        metavar="G",
        help="with --mirror-only: build the default method's maps with this sky prior gain "
        "(Params.sky_gain; default: the add-on's)",
    )
    p.add_argument(
        "--surroundings",
        choices=("auto", "open", "enclosed", "world", "artist"),
        help="with --mirror-only: the panel's Surroundings in every scene; artist: each "
        "scene's by the kind of its HDRI (open sky or enclosed: study/sky_prior.py KINDS); "
        "world: the scene's HDRI dome, as an on-set HDRI, read from the world",
    )
    p.add_argument(
        "--contact-shadow",
        type=float,
        metavar="K",
        help="with --mirror-only: the panel's Contact Shadow in every scene (0..1; default: "
        "the add-on's, 1)",
    )


def _add_mirror_extras(p) -> None:
    """`scenes`: what the fast mirror loop adds (the split, an oracle, another size) and the
    mirror sheet."""
    p.add_argument(
        "--split",
        action="store_true",
        help="with --mirror-only: also where the default's error lies: on the pixels the sky "
        "prior sets (found by a second render with the prior black) or on the rest",
    )
    p.add_argument(
        "--oracle",
        choices=("shadow", "proxies"),
        help="with --mirror-only: also the default given what no plate holds (study/scenes3d/"
        "oracles.py): shadow, the subject's own shadow in the plate; proxies, the ray-traced "
        "pass without and with the scene's true boxes for the mirror's rays",
    )
    p.add_argument(
        "--width",
        type=int,
        metavar="W",
        help="with --mirror-only: render W pixels wide (the height 9/16 of it; default 320)",
    )
    p.add_argument(
        "--samples",
        type=int,
        metavar="N",
        help="with --mirror-only: Cycles samples per pixel (default 32)",
    )
    p.add_argument(
        "--sheet",
        metavar="PNG",
        help="only the mirror sheet: a dozen held-out and Poly Haven scenes, truth | default | "
        "on-set probe | plate mean with PSNR and FLIP (study/scenes3d/sheet.py), written to PNG; "
        "renders cached as --mirror-only's (--cache; --width and --samples: default 320, 32)",
    )


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.command == "evaluate":
            from .evaluate import StudyInputError, run_command

            try:
                run_command(quick=args.quick, out=args.out, hdris=args.hdri, jobs=args.jobs)
            except StudyInputError as exc:
                raise UsageError(str(exc)) from exc
        elif args.command == "scenes":
            from .scenes3d import ScenesInputError
            from .scenes3d import run_command as run_scenes

            try:
                run_scenes(
                    quick=args.quick,
                    out=args.out,
                    jobs=args.jobs,
                    cases=args.cases,
                    mirror_only=args.mirror_only,
                    cache=args.cache,
                    sky_gain=args.sky_gain,
                    split=args.split,
                    surroundings=args.surroundings,
                    oracle=args.oracle,
                    contact_shadow=args.contact_shadow,
                    width=args.width,
                    samples=args.samples,
                    sheet=args.sheet,
                )
            except ScenesInputError as exc:
                raise UsageError(str(exc)) from exc
        elif args.command == "sky-prior":
            from .polyhaven import PolyHavenError
            from .sky_prior import run as run_sky_prior

            try:
                run_sky_prior(polyhaven=args.polyhaven)
            except PolyHavenError as exc:
                raise UsageError(str(exc)) from exc
        else:
            from .bench import run_bench, run_sweep

            run_bench(repeat=args.repeat)
            if args.chart:
                run_sweep(args.chart)
    except (UsageError, ImageError) as exc:
        print(f"study: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("study: interrupted", file=sys.stderr)
        return 130
    return 0
