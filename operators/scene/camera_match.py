"""Matching the camera to the photograph: the focal length from the plate's metadata, and a
warning when the camera was framed for another aspect than the plate's.

Set Up From Plate makes the render the plate's size; it cannot know where the photograph was
taken from. What it can know: the photo's EXIF focal length (``FocalLengthIn35mmFilm``, the
35 mm equivalent, gives the field of view; ``FocalLength`` alone does not, without the sensor
size). The documented route for the camera's position and rotation is fSpy and its Blender
importer (README, "Matching the camera").
"""

import math

from . import plate

FULL_FRAME = 36.0, 24.0  # mm: the "35 mm film" frame of FocalLengthIn35mmFilm
ASPECT_TOLERANCE = 0.01  # relative aspect difference reported as a mismatch
FSPY = "match the camera to the photo (fSpy and its Blender importer)"


def focal_lengths(image) -> tuple[float | None, float | None]:
    """(focal length mm, 35 mm equivalent mm) from the plate file's EXIF, None where absent
    (no file, no OpenImageIO, no tag)."""
    path = plate.disk_path(image)
    if path is None:
        return None, None
    try:
        import OpenImageIO as oiio
    except ImportError:
        return None, None
    found = oiio.ImageInput.open(path)
    if found is None:  # a movie, or a format OpenImageIO does not read: no metadata
        oiio.geterror()  # clear it, or OpenImageIO prints it at exit
        return None, None
    spec = found.spec()
    focal, focal35 = spec.get("Exif:FocalLength"), spec.get("Exif:FocalLengthIn35mmFilm")
    found.close()
    positive = [float(v) if v is not None and float(v) > 0 else None for v in (focal, focal35)]
    return positive[0], positive[1]


def lens_for(focal35, width, height) -> float:
    """Blender's Focal Length (mm) on a 36 mm sensor fitted horizontally that gives the plate
    (width x height pixels) the field of view of a 35 mm-equivalent focal length: the
    equivalent is defined on the diagonal (43.3 mm), so a plate's width spans
    43.3 mm * W / hypot(W, H) at that focal length."""
    diagonal = math.hypot(*FULL_FRAME)
    spans = diagonal * width / math.hypot(width, height)
    return focal35 * FULL_FRAME[0] / spans


def match_lens(camera, image, width, height):
    """Set the camera's lens from the plate's 35 mm-equivalent focal length; returns the record
    of the camera data's previous lens settings, or None (no tag, no camera)."""
    focal35 = focal_lengths(image)[1]
    if focal35 is None or camera is None or camera.type != "CAMERA":
        return None
    data = camera.data
    record = {
        "data": data.name,
        "lens": data.lens,
        "sensor_width": data.sensor_width,
        "sensor_fit": data.sensor_fit,
        "lens_unit": data.lens_unit,
        "type": data.type,
    }
    data.type, data.lens_unit = "PERSP", "MILLIMETERS"
    data.sensor_width, data.sensor_fit = FULL_FRAME[0], "HORIZONTAL"
    data.lens = lens_for(focal35, width, height)
    record["set"] = data.lens
    return record


def undo_lens(record, cameras):
    data = cameras.get(record["data"]) if record else None
    if data is None:
        return
    for name in ("type", "lens_unit", "sensor_width", "sensor_fit", "lens"):
        setattr(data, name, record[name])


def advice(image, previous_size, lens_record) -> list[str]:
    """One line each: the lens set from the metadata (or what the metadata lacks), and a
    warning when the previous render frame (``previous_size``: display width, height, i.e.
    resolution x pixel aspect) had another aspect than the plate."""
    width, height = plate.size(image)
    lines = []
    focal, focal35 = focal_lengths(image)
    if lens_record is not None:
        lines.append(
            f"Camera Focal Length set to {lens_record['set']:.1f} mm (36 mm sensor) from the "
            f"photo's {focal35:g} mm (35 mm equivalent); {FSPY} for its position"
        )
    elif focal35 is not None:
        lens = lens_for(focal35, width, height)
        lines.append(
            f"The photo's metadata gives {focal35:g} mm (35 mm equivalent): Focal Length "
            f"{lens:.1f} mm on a 36 mm sensor (Sensor Fit Horizontal); {FSPY} for its position"
        )
    elif focal is not None:
        lines.append(
            f"The photo's metadata gives a {focal:g} mm focal length but no sensor size; {FSPY}"
        )
    else:
        lines.append(f"No focal length in the plate's metadata: {FSPY}")
    before = previous_size[0] / previous_size[1] if previous_size[1] else 0.0
    after = width / height
    if before and abs(before - after) / after > ASPECT_TOLERANCE:
        lines.append(
            f"Warning: the camera was framed for {before:.3f}:1, the plate is {after:.3f}:1, "
            f"so the camera's view changed; {FSPY}"
        )
    return lines
