"""Regenerate the README's pictures in docs/images/ (nobody pastes pictures by hand).

    .venv/bin/python sample_scenes/make_pictures.py [--out docs/images] [--samples 32]
        [--width 800]

Writes (sRGB PNGs, each well under 300 KB):

- ``spheres_courtyard.png``, ``fig10_city.png``, ``car_sunset.png``: without / with virtual
  reflections side by side (render_sample.py's renders at 50 %, scaled to ``--width``);
- ``segmentation.png``: the paper's segmentation (§3.1-3.2, Fig. 3 a) of the courtyard plate
  around the chrome sphere's screen bounds with n = 32 triangles, drawn by
  ``python -m virtual_reflections segment PLATE -o OUT --bbox X0 Y0 X1 Y1 --triangles 32``
  and lettered;
- ``map_latlong.png`` and ``map_cube.png``: that map (n = 32) from
  ``python -m virtual_reflections envmap --method paper``, as a lat-long and as a labelled
  cube cross.
  (The sample renders use the add-on's default, the continuous front face.)

The cube cross is seen from inside the cube, the back face +Z (what the plate sees behind the
object) in the middle: +X (the plate's left) to its left, -X right of it, then -Z (the front
face, toward the camera); +Y above and -Y below +Z. OpenEXR's cube faces (layouts.py) join up
this way as stored, except +Y and -Y, which are turned 180 degrees.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
PICTURES = (("spheres", "courtyard"), ("fig10", "city"), ("car", "sunset"))
MAP_PLATE = "courtyard"  # the segmentation and the maps: the chrome sphere on this plate
TRIANGLES = 32  # the paper's Fig. 3
MAX_BYTES = 300_000


def _load(name, filename):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / filename)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def resize(pixels, width):
    """(H, W, 3) scene-linear -> the same picture ``width`` pixels wide (OIIO's filter)."""
    import OpenImageIO as oiio

    h, w = pixels.shape[:2]
    height = max(1, round(h * width / w))
    buf = oiio.ImageBufAlgo.resize(
        oiio.ImageBuf(np.ascontiguousarray(pixels, dtype=np.float32)),
        roi=oiio.ROI(0, width, 0, height, 0, 1, 0, 3),
    )
    return np.clip(np.asarray(buf.get_pixels(oiio.FLOAT))[:, :, :3], 0.0, None)


def text(pixels, x, y, words, size, colour=(1.0, 1.0, 1.0), shadow=True):
    """Draw ``words`` with its baseline at (x, y) on a scene-linear picture; returns it."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(np.ascontiguousarray(pixels, dtype=np.float32))
    if shadow:
        oiio.ImageBufAlgo.render_text(buf, x + 1, y + 1, words, size, "", [0.0, 0.0, 0.0])
    oiio.ImageBufAlgo.render_text(buf, x, y, words, size, "", list(colour))
    return np.asarray(buf.get_pixels(oiio.FLOAT))[:, :, :3]


def cube_cross(strip):
    """(6S, S, 3) OpenEXR cube strip (+X, -X, +Y, -Y, +Z, -Z) -> (3S, 4S, 3) cross, dark
    where there is no face. Layout in the module docstring."""
    s = strip.shape[1]
    face = {
        name: strip[i * s : (i + 1) * s]
        for i, name in enumerate(("+X", "-X", "+Y", "-Y", "+Z", "-Z"))
    }
    cross = np.full((3 * s, 4 * s, 3), 0.02, np.float32)
    cross[0:s, s : 2 * s] = face["+Y"][::-1, ::-1]
    cross[s : 2 * s, 0:s] = face["+X"]
    cross[s : 2 * s, s : 2 * s] = face["+Z"]
    cross[s : 2 * s, 2 * s : 3 * s] = face["-X"]
    cross[s : 2 * s, 3 * s : 4 * s] = face["-Z"]
    cross[2 * s : 3 * s, s : 2 * s] = face["-Y"][::-1, ::-1]
    return cross


CROSS_LABELS = (  # (column, row) of the face in the cross, label
    ((1, 0), "+Y top"),
    ((0, 1), "+X left"),
    ((1, 1), "+Z back"),
    ((2, 1), "-X right"),
    ((3, 1), "-Z front"),
    ((1, 2), "-Y bottom"),
)


LATLONG_LABELS = (  # (x / width, label): the longitudes of the cube's side faces' centres
    (0.0, "-Z front"),
    (0.25, "+X left"),
    (0.5, "+Z back"),
    (0.75, "-X right"),
    (1.0, "-Z front"),
)


def engine_cli(*args):
    """``python -m virtual_reflections ARGS`` from the repository root; its output line."""
    run = subprocess.run(
        [sys.executable, "-m", "virtual_reflections", *map(str, args)],
        cwd=ROOT,
        capture_output=True,
        text=True,
    )
    if run.returncode:
        raise RuntimeError(f"virtual_reflections {args[0]}: {run.stderr.strip()}")
    return run.stdout.strip()


def _plate_size(imagefiles, path):
    h, w = imagefiles.read_plate(str(path)).pixels.shape[:2]
    return w, h


def letter_regions(picture, seg, scale, size):
    """Letter the paper's regions X, L, R, T, B and F at their middles (picture = plate scaled
    by ``scale``)."""
    X, inner, (cx, cy) = seg.x, seg.inner, seg.centre
    places = {
        "X": ((X.x0 + X.x1) / 2, (X.y0 + X.y1) / 2),
        "L": ((inner.x0 + X.x0) / 2, cy),
        "R": ((inner.x1 + X.x1) / 2, cy),
        "T": (cx, (inner.y0 + X.y0) / 2),
        "B": (cx, (inner.y1 + X.y1) / 2),
    }
    w, h = seg.width, seg.height
    places = [*places.items(), ("F", (inner.x0 / 2, cy)), ("F", ((inner.x1 + w) / 2, cy))]
    places += [("F", (cx, inner.y0 / 2)), ("F", (cx, (inner.y1 + h) / 2))]
    for letter, (x, y) in places:
        x, y = x * scale - size * 0.3, y * scale + size * 0.35
        picture = text(picture, round(x), round(y), letter, size, (1.0, 0.9, 0.2))
    return picture


def _map_pictures(imagefiles, segmentation, params, build_scenes, bbox, work, out, clock):
    """The pictures of the map plate's engine outputs into ``out``: the segmentation with its
    regions lettered, the paper's lat-long map and its cube cross, labelled (``bbox``: the
    spheres' bounds on that plate; ``work``: a scratch folder). Returns their paths."""
    written = []
    plate_path = build_scenes.plate_files(MAP_PLATE)[0]
    box = ["--bbox", *(f"{v:.1f}" for v in bbox), "--triangles", TRIANGLES]
    overlay = os.path.join(work, "segmentation.png")
    clock(engine_cli("segment", plate_path, "-o", overlay, *box))
    picture = resize(imagefiles.read_plate(overlay).pixels, 640)
    plate_w, plate_h = _plate_size(imagefiles, plate_path)
    seg = segmentation.segment(plate_w, plate_h, bbox, params.Params())
    picture = letter_regions(picture, seg, 640 / plate_w, 16)
    path = os.path.join(out, "segmentation.png")
    imagefiles.write_map(path, picture)
    written.append(path)

    latlong = os.path.join(work, "latlong.exr")
    paper = ("--method", "paper")  # the engine CLI's default is Camera View
    clock(engine_cli("envmap", plate_path, "-o", latlong, *box, *paper, "--width", 1024))
    picture = resize(imagefiles.read_plate(latlong).pixels, 640)
    for fx, label in LATLONG_LABELS:
        x = min(max(4, round(fx * 640 - 3.2 * len(label))), 640 - 7 * len(label))
        picture = text(picture, x, 312, label, 13)
    path = os.path.join(out, "map_latlong.png")
    imagefiles.write_map(path, picture)
    written.append(path)

    strip = os.path.join(work, "cube.exr")
    cube = ("--layout", "cube", "--width", 160)
    clock(engine_cli("envmap", plate_path, "-o", strip, *box, *paper, *cube))
    cross = cube_cross(imagefiles.read_plate(strip).pixels)
    s = cross.shape[1] // 4
    for (col, row), label in CROSS_LABELS:
        cross = text(cross, col * s + 5, row * s + 16, label, 13)
    path = os.path.join(out, "map_cube.png")
    imagefiles.write_map(path, cross)
    written.append(path)
    return written


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="make_pictures", description=__doc__.splitlines()[0], allow_abbrev=False
    )
    p.add_argument("--out", default=str(ROOT / "docs" / "images"))
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--width", type=int, default=960, help="side-by-side width in pixels")
    args = p.parse_args(argv)

    render_sample = _load("vr_sample_render_sample", "render_sample.py")
    build_scenes = render_sample.load_build_scenes()
    clock = render_sample.Clock()
    addon, registered = build_scenes.addon()
    from importlib import import_module

    imagefiles = import_module(addon.__name__ + ".virtual_reflections.imagefiles")
    segmentation = import_module(addon.__name__ + ".virtual_reflections.segmentation")
    params = import_module(addon.__name__ + ".virtual_reflections.params")
    os.makedirs(args.out, exist_ok=True)
    written = []
    try:
        with tempfile.TemporaryDirectory(prefix="vr-pictures-") as work:
            bbox = None
            for kind, plate in PICTURES:
                without, with_, built = render_sample.render_pair(
                    addon, kind, plate, work, scale=50, samples=args.samples, clock=clock
                )
                if kind == "spheres" and plate == MAP_PLATE:
                    bbox = tuple(built.objects[0].virtual_reflections.bounds)
                panel = (args.width - render_sample.GAP) // 2
                labels = ("without reflections", f"virtual reflections ({built.combine.lower()})")
                picture = render_sample.side_by_side(
                    resize(without, panel), resize(with_, panel), labels
                )
                path = os.path.join(args.out, f"{kind}_{plate}.png")
                imagefiles.write_map(path, picture)
                written.append(path)
                clock(f"wrote {path}")

            written += _map_pictures(
                imagefiles, segmentation, params, build_scenes, bbox, work, args.out, clock
            )
    finally:
        if registered:  # the bpy 4.5 module hangs at exit while the add-on is registered
            addon.unregister()
    for path in written:
        size = os.path.getsize(path)
        note = "" if size <= MAX_BYTES else f"  (over {MAX_BYTES // 1000} KB: lower --width)"
        print(f"{path}: {size // 1000} KB{note}")
    clock("total")
    return 0


if __name__ == "__main__":
    sys.exit(main())
