"""The headless batch's options (render_shot.py, operators/batch/shot.py), typed and checked once.

`BatchOptions` holds every option the batch reads, each field with its command-line option
(help, default, choices, a type that converts the text): `add_arguments` builds render_shot's
parser from them and `BatchOptions.from_namespace` builds the options from what it parsed;
sample_scenes/render_sample.py constructs them directly. The values are checked once, in
`__post_init__`: bad input is one ValueError of one line, before anything is opened or written.
The choice lists are the engine's (virtual_reflections/methods.py).

No bpy here: nothing but the values and their checks.
"""

from __future__ import annotations

import argparse
import math
import os
import unicodedata
from dataclasses import MISSING, dataclass, field, fields

from ...virtual_reflections import methods
from ...virtual_reflections.cli_common import words
from ...virtual_reflections.frames import parse_frames
from ...virtual_reflections.mapsize import WIDTHS
from ...virtual_reflections.methods import MAX_TRIANGLES
from ...virtual_reflections.params import MAX_SKY_GAIN, SKY_GAINS

# The choice lists of the engine's definitions (virtual_reflections/methods.py)
COMBINES = methods.COMBINE_NAMES
METHODS = methods.METHOD_NAMES
SURROUNDINGS = methods.SURROUNDINGS_NAMES  # custom: --sky-brightness, --sky-tint
ENGINES = ("CYCLES", "EEVEE")
FORMATS = ("exr", "png")
RESOLUTIONS = WIDTHS
MAX_SMOOTHING = 0.95
RANGES = {"scale": (1, 10000), "samples": (1, 1 << 24), "max_passes": (1, 100)}
SHOTS_OWN_AT_0 = ("samples", "max_passes")  # 0 keeps the shot's own (--scale 0 is refused)
# What the batch appends to a name (<name>_render.exr, <name>_render.0001.exr,
# <name>_composite.png): a name ending in one would write another name's files.
SUFFIXES = ("_render", "_composite")
# Numbers of a closed range (None: not given, the shot's own setting).
FLOAT_RANGES = {
    "sky_brightness": (0.0, MAX_SKY_GAIN),
    "contact_shadow": (0.0, 1.0),
    "sky_texture": (0.0, 1.0),
    "smoothing": (0.0, MAX_SMOOTHING),
}


def _is_int(value):
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def check_name(name, what="--name"):
    """ValueError (one line) for an output stem whose files another stem's could be (one
    ending in a SUFFIXES entry: ``a_render.0001.exr`` is run ``a``'s CG element) or that
    holds a control character (a newline in a file name breaks every line-based tool).
    ``what``: how the message names it (the .blend's name is the default --name)."""
    if any(unicodedata.category(c) == "Cc" for c in name):
        raise ValueError(f"{what} must be a file name without control characters, not {name!r}")
    folded = name.casefold()
    for suffix in SUFFIXES:
        if folded.endswith(suffix):
            raise ValueError(
                f"{what} must not end in {words(SUFFIXES)}, not {name!r}: the batch names "
                f"its own files so (<name>{suffix}...); choose another --name"
            )


def _option(default=None, help="", **parsing):
    """A BatchOptions field and its command-line option: ``help`` and argparse's keywords
    (``type`` converts the text, ``choices``, ``metavar``, ``nargs``, ``action``). The types
    only convert: every value is checked once, in `BatchOptions.__post_init__`."""
    return field(default=default, metadata={"help": help, **parsing})


def _required(help=""):
    """A BatchOptions field without a default: a required option."""
    return field(metadata={"help": help})


def _resolution(text):
    """--resolution's text: AUTO (any case), a width, or the text itself (refused by
    BatchOptions, naming the widths)."""
    if text.upper() == "AUTO":
        return "AUTO"
    try:
        return int(text)
    except ValueError:
        return text


def _passes(text):
    """--passes' text: a number, or the text itself (auto, or refused by BatchOptions)."""
    return int(text) if text.strip().lstrip("-").isdigit() else text


def _colour(text):
    """--sky-tint's R,G,B as three numbers (their range checked by BatchOptions)."""
    parts = text.split(",")
    try:
        if len(parts) != 3:
            raise ValueError
        return tuple(float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected R,G,B (three numbers), not {text!r}") from None


def _braced(choices):
    return "{" + ",".join(choices) + "}"


@dataclass(frozen=True)
class BatchOptions:
    """Every option of the headless batch, each with its command line's definition (render_shot
    builds its parser from these fields). None means "not given, keep the shot's own setting"."""

    plate: str = _required(
        "background plate: a still image, a sequence (plate.####.exr) or a movie"
    )
    out: str = _required("output folder (created)")
    blend: str | None = _option(
        help="the shot (.blend); omit under blender -b shot.blend", positional=True, nargs="?"
    )
    objects: tuple[str, ...] | None = _option(
        help="the reflective objects (default: those marked in the panel, else every visible "
        "object with a surface but the ground they stand on: a shadow catcher, the chosen "
        "ground, the floor under them)",
        nargs="+",
        metavar="NAME",
    )
    combine: str | None = _option(
        help="the look: REPLACE (chrome: the object shows the map), MODULATE (the material's "
        "colour times the map), MIX (the map blended over the material's own shader by "
        "strength and Fresnel), WORLD (one shared map as world lighting for any material); "
        "default: the shot's setting",
        choices=COMBINES,
    )
    resolution: int | str | None = _option(help="lat-long map width, or AUTO", type=_resolution)
    triangles: int | None = _option(help="0 = continuous", type=int)
    method: str | None = _option(
        help="ground: the camera view with the ground seen from the object; camera: the plate "
        "placed by the camera's field of view; paper: Ropinski et al. (default: the shot's "
        "setting)",
        choices=METHODS,
    )
    ground_object: str | None = _option(
        help="the object the reflective objects stand on, for --method ground (default: the "
        "shot's setting, else a shadow catcher, else a flat mesh under them, else their lowest "
        "point)",
        metavar="NAME",
    )
    surroundings: str | None = _option(
        help="for --method ground, how bright the sky the plate does not show is taken to be: "
        "open (outdoors under open sky), enclosed (a dim room, a studio, a walled yard), auto "
        "(nothing known, or a brightly lit interior), world (the shot's world holds the on-set "
        "HDRI: it is used there) or custom (the shot's Sky Brightness, or --sky-brightness); "
        "default: the shot's setting",
        choices=SURROUNDINGS,
    )
    sky_brightness: float | None = _option(
        help="Surroundings custom: the unseen sky is G times the ground's brightness in the "
        f"plate (0..{MAX_SKY_GAIN:g}; an average place is near {SKY_GAINS['auto']:g}, open "
        f"{SKY_GAINS['open']:g}, enclosed {SKY_GAINS['enclosed']:g}); default: the shot's "
        "setting",
        type=float,
        metavar="G",
    )
    sky_tint: tuple | None = _option(
        help="Surroundings custom: the unseen sky's colour, its brightness taken out (linear, "
        "0..1 each, e.g. 0.6,0.75,1 for a blue sky); default: the shot's setting",
        type=_colour,
        metavar="R,G,B",
    )
    contact_shadow: float | None = _option(
        help="for --method ground, how much the objects darken the ground they reflect around "
        "them: 1 the share of the sky they hide, 0 none (a plate that already shows their "
        "shadow); default: the shot's setting",
        type=float,
        metavar="K",
    )
    sky_texture: float | None = _option(
        help="for --method ground, how much of the plate's own texture the unseen sky takes, "
        "0..1 (0: a flat colour estimated from the plate; the skyline the plate shows "
        "continues around the camera, its average brightness still the --surroundings' "
        "estimate; not used where --surroundings world reads an HDRI); default: the shot's "
        "setting",
        type=float,
        metavar="K",
    )
    frame: int | None = _option(help="the frame (default: the shot's)", type=int)
    engine: str | None = _option(help="default: the shot's", choices=ENGINES)
    samples: int | None = _option(help="render samples (default: the shot's)", type=int)
    scale: int | None = _option(help="resolution percentage, 1 to 10000", type=int)
    passes: int | str = _option(
        1, help="inter-reflection passes r, or auto (default 1)", type=_passes
    )
    tolerance: float | None = _option(help="--passes auto: stop below", type=float)
    max_passes: int | None = _option(help="--passes auto: at most", type=int)
    no_reflections: bool = _option(
        False,
        help="render the shot over the plate without virtual reflections (a reference)",
        action="store_true",
    )
    name: str | None = _option(help="output file stem (default: the .blend's name)")
    frames: str | None = _option(help="1-240, 1..240, 1-10x2, 5 or 1,3,7-9")
    format: str = _option("exr", help="frame range output", choices=FORMATS)
    overwrite: bool = _option(False, help="render complete frames again", action="store_true")
    report: str | None = _option(
        help="report path (default DIR/<name>.report.json); never an input, an output of the "
        "run or a file other than an earlier report"
    )
    smoothing: float | None = _option(help=f"bounds smoothing 0..{MAX_SMOOTHING}", type=float)

    @classmethod
    def from_namespace(cls, namespace):
        """From render_shot's argparse namespace (its attributes are exactly these fields)."""
        return cls(**vars(namespace))

    def __post_init__(self):
        self._check_texts()
        self._check_choices_and_numbers()
        self._check_name_frame_and_passes()
        self._check_sky()
        self._check_switches_and_frames()

    def _check_texts(self):
        """The paths and names are text (a path-like made text), the objects a list of names."""
        for key in ("plate", "out", "blend", "name", "report"):
            value = getattr(self, key)
            if isinstance(value, os.PathLike):
                object.__setattr__(self, key, value := os.fspath(value))
            if value is None and key not in ("plate", "out"):
                continue
            if not isinstance(value, str):
                raise ValueError(f"--{key} must be text, not {value!r}")
        if self.objects is not None:
            if isinstance(self.objects, str) or not all(isinstance(n, str) for n in self.objects):
                raise ValueError(f"--objects must be a list of object names, not {self.objects!r}")
            object.__setattr__(self, "objects", tuple(self.objects))

    def _check_choices_and_numbers(self):
        """Each choice one of its list, each count a whole number >= 0, each ranged setting
        in its range, the triangles a multiple of 4."""
        for key, choices in (
            ("combine", COMBINES),
            ("method", METHODS),
            ("surroundings", SURROUNDINGS),
            ("engine", ENGINES),
            ("format", FORMATS),
        ):
            value = getattr(self, key)
            if (value is not None or key == "format") and value not in choices:
                raise ValueError(f"--{key} must be {words(choices)}, not {value!r}")
        if self.resolution is not None and self.resolution not in (*RESOLUTIONS, "AUTO"):
            raise ValueError(
                f"--resolution must be {words((*RESOLUTIONS, 'AUTO'))}, not {self.resolution!r}"
            )
        for key in ("triangles", "samples", "scale", "max_passes"):
            value = getattr(self, key)
            if value is not None and not (_is_int(value) and value >= 0):
                raise ValueError(f"--{key.replace('_', '-')} must be a number >= 0, not {value!r}")
        for key, (low, high) in RANGES.items():
            value = getattr(self, key)
            own = key in SHOTS_OWN_AT_0
            if value is not None and not (own and value == 0) and not low <= value <= high:
                raise ValueError(
                    f"--{key.replace('_', '-')} must be from {low} to {high}"
                    + (" (0: the shot's own)" if own else "")
                    + f", not {value!r}"
                )
        if self.max_passes == 0:
            raise ValueError("--max-passes must be at least 1, not 0")
        t = self.triangles
        if t is not None and t != 0 and not (t % 4 == 0 and 4 <= t <= MAX_TRIANGLES):
            raise ValueError(
                f"--triangles must be 0 or a multiple of 4 from 4 to {MAX_TRIANGLES}, not {t}"
            )

    def _check_name_frame_and_passes(self):
        """The report's name a plain file name, the frame a number, the passes a number >= 1
        or auto, the tolerance a number >= 0."""
        if self.name is not None and (
            not self.name.strip()
            or self.name.startswith(".")
            or os.sep in self.name
            or (os.altsep and os.altsep in self.name)
        ):
            raise ValueError(
                f"--name must be a file name without a folder or a leading dot, not {self.name!r}"
            )
        if self.name is not None:
            check_name(self.name)
        if self.frame is not None and not _is_int(self.frame):
            raise ValueError(f"--frame must be a frame number, not {self.frame!r}")
        if self.passes != "auto" and not (_is_int(self.passes) and self.passes >= 1):
            raise ValueError(
                f"--passes: expected a number of passes >= 1 or auto, not {self.passes!r}"
            )
        if self.tolerance is not None:
            if not (_is_number(self.tolerance) and self.tolerance >= 0):
                raise ValueError(f"--tolerance must be a number >= 0, not {self.tolerance!r}")
            object.__setattr__(self, "tolerance", float(self.tolerance))

    def _check_sky(self):
        """Each float setting in its range, the sky tint an R,G,B not all 0, and the sky's
        brightness and tint only with Surroundings Custom (or none)."""
        for key, (low, high) in FLOAT_RANGES.items():
            value = getattr(self, key)
            if value is None:
                continue
            if not (_is_number(value) and low <= value <= high):
                raise ValueError(
                    f"--{key.replace('_', '-')}: expected a number from {low:g} to {high:g}, "
                    f"not {value!r}"
                )
            object.__setattr__(self, key, float(value))
        if self.sky_tint is not None:
            tint = self.sky_tint
            if (
                isinstance(tint, str)
                or len(tuple(tint)) != 3
                or not all(_is_number(v) and 0.0 <= v <= 1.0 for v in tint)
                or max(tint) <= 0.0
            ):
                raise ValueError(
                    f"--sky-tint: expected R,G,B from 0 to 1, not all 0, not {self.sky_tint!r}"
                )
            object.__setattr__(self, "sky_tint", tuple(float(v) for v in tint))
        for key in ("sky_brightness", "sky_tint"):
            if getattr(self, key) is not None and self.surroundings not in (None, "custom"):
                raise ValueError(
                    f"--{key.replace('_', '-')} sets Surroundings Custom: not with "
                    f"--surroundings {self.surroundings}"
                )

    def _check_switches_and_frames(self):
        """The switches on or off, --no-reflections with one pass, and --frames a range
        (not with --frame)."""
        for key in ("no_reflections", "overwrite"):
            if not isinstance(getattr(self, key), bool):
                raise ValueError(
                    f"--{key.replace('_', '-')} is on or off, not {getattr(self, key)!r}"
                )
        if self.no_reflections and self.passes != 1:
            raise ValueError(
                f"--passes {self.passes} with --no-reflections: passes are reflections between "
                "the objects; drop one of the two"
            )
        if self.frames is not None:
            if self.frame is not None:
                raise ValueError("give --frame or --frames, not both")
            if not isinstance(self.frames, str):
                raise ValueError(f"--frames must be a range like 1-240, not {self.frames!r}")
            parse_frames(self.frames)  # ValueError naming the bad part, one line


FIELDS = tuple(f.name for f in fields(BatchOptions))


def add_arguments(parser) -> None:
    """Add every BatchOptions field to ``parser`` (an argparse parser) as its option: the
    namespace it parses has exactly these fields, with their defaults (`from_namespace`)."""
    for f in fields(BatchOptions):
        parsing = dict(f.metadata)
        if parsing.pop("positional", False):
            parser.add_argument(f.name, **parsing)
            continue
        if f.default is MISSING:
            parsing["required"] = True
        else:
            parsing["default"] = f.default
        parser.add_argument("--" + f.name.replace("_", "-"), **parsing)
