"""Headless batch entry: render a shot's frame with virtual reflections and the composite.

    blender -b shot.blend --python <extension>/render_shot.py -- --plate PLATE --out DIR
    python -m render_shot shot.blend --plate PLATE --out DIR        (bpy module, repo root)

Options: --objects NAME [NAME ...] (default: marked objects, else every visible mesh-like
object), --combine REPLACE|MODULATE|MIX|WORLD, --resolution W, --triangles N, --frame F,
--engine CYCLES|EEVEE, --samples N, --scale PERCENT, --no-reflections (the plain render, for
comparisons). Writes DIR/<shot>_render.exr (RGBA, linear), DIR/<shot>_composite.png (sRGB)
and .exr (linear), and prints one line per stage with its time. Bad input: one line on
stderr and exit code 2.
"""

import argparse
import importlib.util
import os
import sys
import time

EXIT_BAD_INPUT = 2


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


def parse(argv):
    p = argparse.ArgumentParser(prog="render_shot", description=__doc__.splitlines()[0])
    p.add_argument("blend", nargs="?", help="the shot (.blend); omit under blender -b shot.blend")
    p.add_argument("--plate", required=True, help="background plate image file")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--objects", nargs="+", default=None)
    p.add_argument("--combine", choices=("REPLACE", "MODULATE", "MIX", "WORLD"), default=None)
    p.add_argument("--resolution", type=int, default=None, help="lat-long map width")
    p.add_argument("--triangles", type=int, default=None, help="0 = continuous")
    p.add_argument("--frame", type=int, default=None)
    p.add_argument("--engine", choices=("CYCLES", "EEVEE"), default=None)
    p.add_argument("--samples", type=int, default=None)
    p.add_argument("--scale", type=int, default=None, help="resolution percentage")
    p.add_argument("--no-reflections", action="store_true")
    p.add_argument("--name", default=None, help="output file stem (default: the .blend's name)")
    return p.parse_args(argv)


def main(argv=None):
    import bpy

    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    try:
        args = parse(argv)
    except SystemExit as exc:
        return EXIT_BAD_INPUT if exc.code else 0
    addon, own = _addon()
    try:
        return run(bpy, addon, own, args)
    except (ValueError, OSError, RuntimeError) as exc:
        print(f"render_shot: error: {str(exc).strip().splitlines()[0]}", file=sys.stderr)
        return EXIT_BAD_INPUT


def run(bpy, addon, own, args):
    started = time.perf_counter()
    if args.blend:
        if not os.path.isfile(args.blend):
            raise ValueError(f"shot not found: {args.blend}")
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
    registered = own and not hasattr(bpy.types.Scene, "virtual_reflections")
    if registered:
        addon.register()
    try:
        from importlib import import_module

        batch = import_module(addon.__name__ + ".operators.batch")
        return batch.render_shot(args, started)
    finally:
        if registered:  # the bpy 4.5 module hangs at exit while classes stay registered
            addon.unregister()


if __name__ == "__main__":
    sys.exit(main())
