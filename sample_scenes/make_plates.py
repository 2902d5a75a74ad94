"""Make the sample plates from Blender's bundled world HDRIs (CC0, Poly Haven).

Run from the repository root with the Python that has the `bpy` wheel installed:

    .venv/bin/python sample_scenes/make_plates.py

`bpy` is only *located* (importlib's find_spec), never imported: the HDRIs live in
`<bpy package>/<version>/datafiles/studiolights/world/`. For every plate it writes into
`sample_scenes/plates/`:

- `<name>.exr`  scene-linear Rec.709, half float, lossless zip (the plate the engine reads);
- `<name>.jpg`  the same pixels encoded with the sRGB OETF, clipped, 8-bit, quality 92;
- `<name>.json` the camera that sees exactly this plate when the world is the same HDRI on an
  Environment Texture with Blender's default mapping (location, rotation_euler XYZ in radians,
  sensor fit, lens for a 36 mm sensor);

and a contact sheet `docs/images/sample_plates.png` (each plate above its HDRI, with the plate's
field of view outlined on the HDRI).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import sys

import numpy as np
import OpenImageIO as oiio

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # a script run from the checkout, not part of the extension
    sys.path.insert(0, str(ROOT))
imagefiles = importlib.import_module("virtual_reflections.imagefiles")
panorama = importlib.import_module("study.panorama")

WIDTH, HEIGHT = 1280, 720
HFOV_DEG = 60.0
SENSOR_WIDTH_MM = 36.0
SUPERSAMPLE = 3
HALF_MAX = 65504.0

# (plate name, bundled HDRI, heading, pitch): each has a ground to stand a chrome sphere on,
# detail on both sides and a sky or wall above.
PLATES = (
    ("courtyard", "courtyard.exr", -120.0, -8.0),  # garage door, yellow walls, paving
    ("city", "city.exr", -150.0, -8.0),  # landing pad, car park, office towers, sky
    ("sunset", "sunset.exr", -10.0, -8.0),  # Venice waterfront, people, water, dusk sky
)


def studiolight_world_dir():
    """`<bpy>/<version>/datafiles/studiolights/world` of the installed bpy (found, not imported)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("the bpy package is not installed in this Python")
    for location in spec.submodule_search_locations:
        found = sorted(pathlib.Path(location).glob("*/datafiles/studiolights/world"))
        if found:
            return found[-1]
    raise SystemExit("no datafiles/studiolights/world folder in the bpy package")


def write_exr(path, linear):
    """`(H, W, 3)` scene-linear Rec.709 -> half-float zip EXR, colour space named explicitly.

    Not `imagefiles.write_map`: a plate's header names its colour space, and has no time stamp.
    """
    pixels = np.clip(linear, 0.0, HALF_MAX).astype(np.float32)
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, oiio.HALF)
    spec.attribute("compression", "zip:9")  # lossless: the plate is reference data
    spec.attribute("DateTime", "")  # no time stamp: regenerating gives identical files
    spec.attribute("oiio:ColorSpace", "lin_rec709")
    # OIIO 3.0 keeps oiio:ColorSpace out of EXR headers, so name the space in the header too:
    # OpenEXR's colorInteropID (Color Interop Forum id) and the primaries and white point.
    spec.attribute("colorInteropID", "lin_rec709_scene")
    spec.attribute("chromaticities", oiio.TypeDesc("float[8]"), imagefiles.REC709_CHROMATICITIES)
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec):
        raise OSError(f"cannot write {path}: {oiio.geterror()}")
    ok = out.write_image(np.ascontiguousarray(pixels))
    out.close()
    if not ok:
        raise OSError(f"cannot write {path}: {out.geterror()}")


def camera_json(hdri, heading, pitch):
    """The Blender camera that renders the plate (rotation in radians, Euler 'XYZ')."""
    return {
        "hdri": hdri,
        "width": WIDTH,
        "height": HEIGHT,
        "hfov_deg": HFOV_DEG,
        "heading_deg": heading,
        "pitch_deg": pitch,
        "roll_deg": 0.0,
        "camera_location": [0.0, 0.0, 0.0],
        "camera_rotation_euler": list(panorama.camera_rotation_euler(heading, pitch, 0.0)),
        "rotation_mode": "XYZ",
        "sensor_fit": "HORIZONTAL",
        "sensor_width_mm": SENSOR_WIDTH_MM,
        "lens_mm": panorama.lens_mm(HFOV_DEG, SENSOR_WIDTH_MM),
        "world": "Environment Texture of the HDRI, default mapping, Linear interpolation",
        "pixel_filter": f"box, {SUPERSAMPLE}x{SUPERSAMPLE} stratified samples per pixel",
        "colorspace": "lin_rec709",
    }


def _thumbnail(linear, width, height):
    """Scene-linear thumbnail, clipped to [0, 1] first (what an sRGB picture shows): a bright
    sun would ring through the resampling filter."""
    buf = oiio.ImageBufAlgo.resize(
        oiio.ImageBuf(np.ascontiguousarray(np.clip(linear, 0.0, 1.0), dtype=np.float32)),
        roi=oiio.ROI(0, width, 0, height, 0, 1, 0, 3),
    )
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32)


def _outline_on_equirect(thumb, heading, pitch):
    """Draw the plate's border (its field of view) onto an `(h, w, 3)` linear HDRI thumbnail."""
    h, w = thumb.shape[:2]
    # a smaller grid with the same field of view has the same border directions
    cam = panorama.camera_frame_directions(256, 144, HFOV_DEG)
    border = np.concatenate([cam[0], cam[-1], cam[:, 0], cam[:, -1]])
    world = panorama.camera_to_blender_world(border, panorama.camera_rotation(heading, pitch))
    xy = panorama.blender_equirect_lookup(world, w, h).astype(int)
    for dx, dy in ((0, 0), (1, 0), (0, 1), (1, 1)):
        thumb[np.clip(xy[:, 1] + dy, 0, h - 1), (xy[:, 0] + dx) % w] = (
            1.0,
            0.033,
            0.01,
        )  # sRGB (1, 0.2, 0.1)
    return thumb


def contact_sheet(path, entries, column=320, gap=6, label_height=22):
    """One column per plate: its label, the plate, its HDRI with the plate's view outlined.

    Composed in scene-linear and written sRGB-encoded by `imagefiles.write_map`.
    """
    plate_h = column * HEIGHT // WIDTH
    hdri_h = column // 2
    sheet_w = len(entries) * column + (len(entries) + 1) * gap
    sheet_h = label_height + plate_h + hdri_h + 3 * gap
    sheet = np.full((sheet_h, sheet_w, 3), 0.013, dtype=np.float32)  # sRGB 0.12
    for i, (_name, plate, equirect, heading, pitch) in enumerate(entries):
        x0 = gap + i * (column + gap)
        y0 = label_height + gap
        sheet[y0 : y0 + plate_h, x0 : x0 + column] = _thumbnail(plate, column, plate_h)
        y1 = y0 + plate_h + gap
        thumb = _thumbnail(equirect, column, hdri_h)
        sheet[y1 : y1 + hdri_h, x0 : x0 + column] = _outline_on_equirect(thumb, heading, pitch)
    buf = oiio.ImageBuf(np.ascontiguousarray(sheet))
    for i, (name, _plate, _equirect, heading, pitch) in enumerate(entries):
        label = f"{name}   heading {heading:+.0f}°  pitch {pitch:+.0f}°  hfov {HFOV_DEG:.0f}°"
        oiio.ImageBufAlgo.render_text(
            buf, gap + i * (column + gap) + 2, label_height - 6, label, 14, "DroidSans", [0.79] * 3
        )
    imagefiles.write_map(str(path), np.asarray(buf.get_pixels(oiio.FLOAT))[:, :, :3])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("--hdri-dir", type=pathlib.Path, help="default: the bpy studiolights")
    parser.add_argument("--out", type=pathlib.Path, default=ROOT / "sample_scenes" / "plates")
    parser.add_argument(
        "--sheet", type=pathlib.Path, default=ROOT / "docs" / "images" / "sample_plates.png"
    )
    args = parser.parse_args(argv)
    hdri_dir = args.hdri_dir or studiolight_world_dir()
    args.out.mkdir(parents=True, exist_ok=True)
    args.sheet.parent.mkdir(parents=True, exist_ok=True)

    entries = []
    for name, hdri, heading, pitch in PLATES:
        equirect = panorama.load_equirect(hdri_dir / hdri)
        plate = panorama.perspective_plate(
            equirect, WIDTH, HEIGHT, HFOV_DEG, heading, pitch, 0.0, supersample=SUPERSAMPLE
        )
        write_exr(args.out / f"{name}.exr", plate)
        imagefiles.write_map(str(args.out / f"{name}.jpg"), plate)  # sRGB 8-bit, quality 92
        (args.out / f"{name}.json").write_text(
            json.dumps(camera_json(hdri, heading, pitch), indent=2) + "\n"
        )
        entries.append((name, plate, equirect, heading, pitch))
        print(f"{name}: {hdri} heading {heading:+.0f} pitch {pitch:+.0f} -> {args.out}")
    contact_sheet(args.sheet, entries)
    print(f"contact sheet -> {args.sheet}")


if __name__ == "__main__":
    main()
