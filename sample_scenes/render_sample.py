"""Render a sample scene without and with virtual reflections, and the two side by side.

    .venv/bin/python sample_scenes/render_sample.py [--scene spheres|fig10|car|all]
        [--plate courtyard|city|sunset|PATH] [--out out] [--scale 50] [--samples 16]

(or ``tools/render-sample ...``, which makes the environment first). Default: the chrome
sphere on the courtyard plate. For each scene it builds the scene over the plate
(build_scenes.py), renders it twice through the batch entry (render_shot.py's
``operators.batch.shot.render_shot``) -- first with the objects' own materials, then after
generating their virtual reflections -- each composited over the plate, and writes

    OUT/<scene>_without.png   OUT/<scene>_with.png   OUT/<scene>_side_by_side.png

(sRGB PNGs of the scene-linear composites; the side-by-side is labelled). Prints one line per
stage with the time since the start, and the total. Works with the bpy module (Blender 4.5
and 5.x) and inside Blender: ``blender -b --python sample_scenes/render_sample.py -- ...``.
Bad input: one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import pathlib
import re
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
EXIT_BAD_INPUT = 2
LABEL_SIZE = 14  # px at a 640 px wide panel; scaled with the panel, at least 11 px
GAP = 4  # px between the panels


def load_build_scenes():
    """build_scenes.py beside this file (the folder is not a package, and under Blender it is
    not on sys.path)."""
    name = "vr_sample_build_scenes"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / "build_scenes.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def parse(argv=None):
    build_scenes = load_build_scenes()
    p = argparse.ArgumentParser(
        prog="render_sample", description=__doc__.splitlines()[0], allow_abbrev=False
    )
    p.add_argument("--scene", choices=(*build_scenes.SCENES, "all"), default="spheres")
    p.add_argument("--plate", default="courtyard", help="courtyard, city, sunset or an image")
    p.add_argument("--out", default="out", help="output folder (created)")
    p.add_argument("--scale", type=int, default=50, help="resolution percentage of the plate")
    p.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel")
    p.add_argument("--no-ground", action="store_true", help="no shadow-catcher ground")
    args = p.parse_args(argv)
    if not 1 <= args.scale <= 100:
        p.error(f"--scale must be 1..100, got {args.scale}")
    if args.samples < 1:
        p.error(f"--samples must be at least 1, got {args.samples}")
    return args


class Clock:
    """Prints ``[  t s] message`` lines, t the time since ``started``."""

    def __init__(self, started=None):
        self.started = time.perf_counter() if started is None else started

    def __call__(self, message):
        print(f"[{time.perf_counter() - self.started:6.2f} s] {message}", flush=True)


# What the renderer prints that is noise here: its progress and file lines (4.5: "Fra: ...",
# 5.x: "00:03.291  render  | Saved: ..."), and Cycles saying there is no CUDA driver.
_NOISE = re.compile(r"^(\d+:\d+\.\d+\s+\w+\s+\|\s+)?(Fra:|Saved:|Time:|WARNING CUEW)")


@contextlib.contextmanager
def renderer_quiet(enabled=True):
    """Hold back the renderer's progress lines, which the bpy module prints straight to file
    descriptor 1; everything else printed meanwhile is passed on when the block ends."""
    if not enabled:
        yield
        return
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
            held.seek(0)
            for line in held.read().decode(errors="replace").splitlines():
                if line.strip() and not _NOISE.match(line):
                    print(line, flush=True)


def batch_options(options_type, kind, built, work_dir, reflections, *, scale=50, samples=16):
    """The batch's options (``options_type``: the add-on's operators.batch.options.BatchOptions)
    for rendering scene ``kind`` as ``built`` without or with virtual reflections into
    ``work_dir``; the output stem is ``<kind>_without`` or ``<kind>_with``."""
    return options_type(
        plate=built.plate_path,
        out=str(work_dir),
        objects=tuple(o.name for o in built.objects),
        combine=built.combine,
        samples=samples,
        scale=scale,
        no_reflections=not reflections,
        name=f"{kind}_{'with' if reflections else 'without'}",
    )


def render_pair(
    addon,
    kind,
    plate,
    work_dir,
    *,
    scale=50,
    samples=16,
    ground=True,
    denoise=True,
    clock=None,
    quiet=True,
):
    """Build ``kind`` over ``plate`` in a new empty file and render it without, then with,
    virtual reflections, each composited over the plate. Returns (without, with, built):
    two (H, W, 3) float32 scene-linear composites, top row first, and the build_scenes.Built.
    Intermediate files go to ``work_dir``."""
    from importlib import import_module

    build_scenes = load_build_scenes()
    batch = import_module(addon.__name__ + ".operators.batch.shot")
    BatchOptions = import_module(addon.__name__ + ".operators.batch.options").BatchOptions
    imagefiles = import_module(addon.__name__ + ".virtual_reflections.imagefiles")
    clock = clock or Clock()

    t = time.perf_counter()
    with renderer_quiet(quiet):
        build_scenes.new_file()
        built = build_scenes.build(
            kind, plate, scale=scale, samples=samples, ground=ground, denoise=denoise
        )
    clock(
        f"built {kind} on {pathlib.Path(built.plate_path).name}: "
        f"{', '.join(o.name for o in built.objects)}"
        f"{' + shadow catcher' if built.ground else ''} in {time.perf_counter() - t:.2f} s"
    )
    composites = []
    for reflections in (False, True):
        options = batch_options(
            BatchOptions, kind, built, work_dir, reflections, scale=scale, samples=samples
        )
        clock(f"{options.name}: rendering")
        with renderer_quiet(quiet):
            batch.render_shot(options, clock.started)
        path = os.path.join(work_dir, f"{options.name}_composite.exr")
        composites.append(imagefiles.read_plate(path).pixels)
    return composites[0], composites[1], built


def _label(image, text, size):
    """Draw ``text`` at the top-left of a (H, W, 3) scene-linear image, on a dark band; the
    image unchanged when this OpenImageIO has no font (as inside some Blender builds)."""
    import OpenImageIO as oiio

    pad = max(2, size // 3)
    extent = oiio.ImageBufAlgo.text_size(text, size, "")
    width = extent.width if extent.defined else int(len(text) * size * 0.6)
    labelled = np.array(image, dtype=np.float32)
    band = labelled[: size + 2 * pad, : width + 2 * pad]
    band[:] = 0.15 * np.clip(band, 0.0, 1.0)  # dark enough for white text, even over a sky
    buf = oiio.ImageBuf(labelled)
    if not oiio.ImageBufAlgo.render_text(buf, pad, pad + size - 2, text, size, "", [1.0] * 3):
        buf.geterror()  # read, so OpenImageIO does not print it when the buffer goes
        return image
    return np.asarray(buf.get_pixels(oiio.FLOAT))[:, :, :3]


def side_by_side(left, right, labels=None, gap=GAP):
    """Two (H, W, 3) scene-linear pictures next to each other, a dark gap between them, each
    labelled at its top-left when ``labels`` = (left text, right text) is given."""
    h, w = left.shape[:2]
    out = np.full((h, 2 * w + gap, 3), 0.01, np.float32)
    out[:, :w], out[:, w + gap :] = left, right
    if labels:
        size = max(11, round(LABEL_SIZE * w / 640))
        try:
            out[:, :w] = _label(out[:, :w], labels[0], size)
            out[:, w + gap :] = _label(out[:, w + gap :], labels[1], size)
        except ImportError:  # without OpenImageIO: unlabelled
            pass
    return out


def write_outputs(addon, kind, without, with_, out_dir, combine):
    """OUT/<kind>_without.png, _with.png, _side_by_side.png (sRGB). Returns the paths."""
    from importlib import import_module

    imagefiles = import_module(addon.__name__ + ".virtual_reflections.imagefiles")
    os.makedirs(out_dir, exist_ok=True)
    paths = [os.path.join(out_dir, f"{kind}_{suffix}.png") for suffix in ("without", "with")]
    paths.append(os.path.join(out_dir, f"{kind}_side_by_side.png"))
    imagefiles.write_map(paths[0], without)
    imagefiles.write_map(paths[1], with_)
    labels = ("without reflections", f"virtual reflections ({combine.lower()})")
    imagefiles.write_map(paths[2], side_by_side(without, with_, labels))
    return paths


def run(args, clock):
    import bpy

    build_scenes = load_build_scenes()
    build_scenes.plate_files(args.plate)  # bad input fails before any rendering
    os.makedirs(args.out, exist_ok=True)
    if not os.access(args.out, os.W_OK):
        raise ValueError(f"output folder is not writable: {args.out}")
    addon, registered = build_scenes.addon()
    clock(f"loaded bpy {bpy.app.version_string} and the add-on")
    kinds = build_scenes.SCENES if args.scene == "all" else (args.scene,)
    try:
        with tempfile.TemporaryDirectory(prefix="vr-sample-") as work:
            for kind in kinds:
                render_one(addon, kind, args, work, clock)
    finally:
        if registered:  # the bpy 4.5 module hangs at exit while the add-on is registered
            addon.unregister()
    clock("total")
    return 0


def render_one(addon, kind, args, work, clock):
    started = time.perf_counter()
    without, with_, built = render_pair(
        addon,
        kind,
        args.plate,
        work,
        scale=args.scale,
        samples=args.samples,
        ground=not args.no_ground,
        clock=clock,
    )
    t = time.perf_counter()
    paths = write_outputs(addon, kind, without, with_, args.out, built.combine)
    clock(f"wrote {', '.join(paths)} in {time.perf_counter() - t:.2f} s")
    clock(f"{kind}: {time.perf_counter() - started:.2f} s")


def main(argv=None):
    if argv is None:
        argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else sys.argv[1:]
    clock = Clock()  # from the start: importing bpy (in parse) is a stage too
    try:
        args = parse(argv)
    except SystemExit as exc:
        return EXIT_BAD_INPUT if exc.code else 0
    try:
        return run(args, clock)
    except Exception as exc:  # bad input is one line; a bug keeps its traceback
        if not isinstance(exc, (ValueError, OSError, RuntimeError)):
            if type(exc).__name__ != "ImageError":  # the engine's, from the add-on package
                raise
        print(f"render_sample: error: {str(exc).strip().splitlines()[0]}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":
    sys.exit(main())
