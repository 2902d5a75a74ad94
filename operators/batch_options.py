"""The headless batch's options (render_shot.py, operators/batch.py), typed and checked once.

`BatchOptions` holds every option the batch reads, each with render_shot's command-line
default; `BatchOptions.from_namespace` builds it from render_shot's argparse namespace and
sample_scenes/render_sample.py constructs it directly. The values are checked in
`__post_init__`: bad input is one ValueError of one line, before anything is opened or written.

No bpy here: nothing but the values and their checks.
"""

from __future__ import annotations

import math
import os
import unicodedata
from dataclasses import dataclass, fields

from ..virtual_reflections.frames import parse_frames
from ..virtual_reflections.mapsize import WIDTHS
from ..virtual_reflections.params import MAX_SKY_GAIN

COMBINES = ("REPLACE", "MODULATE", "MIX", "WORLD")
METHODS = ("ground", "camera", "paper")
# params.SKY_GAINS; world: its HDRI; custom: --sky-brightness (the scene's Sky Brightness)
SURROUNDINGS = ("auto", "open", "enclosed", "world", "custom")
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
    "smoothing": (0.0, MAX_SMOOTHING),
}


def _words(choices):
    """("a", "b", "c") -> "a, b or c"."""
    choices = [str(c) for c in choices]
    return ", ".join(choices[:-1]) + " or " + choices[-1] if len(choices) > 1 else choices[0]


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
                f"{what} must not end in {_words(SUFFIXES)}, not {name!r}: the batch names "
                f"its own files so (<name>{suffix}...); choose another --name"
            )


@dataclass(frozen=True)
class BatchOptions:
    """Every option of the headless batch. The defaults are render_shot's (argparse's):
    None means "not given, keep the shot's own setting"."""

    plate: str  # a still image, a sequence pattern (plate.####.exr) or a movie
    out: str  # the output folder (created)
    blend: str | None = None  # the shot to open; None: the file already open
    objects: tuple[str, ...] | None = None  # None: marked objects, else visible mesh-likes
    combine: str | None = None  # REPLACE, MODULATE, MIX or WORLD
    resolution: int | str | None = None  # lat-long map width, or "AUTO"
    triangles: int | None = None  # 0: continuous front face
    method: str | None = None  # ground, camera or paper
    ground_object: str | None = None  # the ground for --method ground (None: the shot's)
    surroundings: str | None = None  # auto, open, enclosed, world or custom (--method ground)
    sky_brightness: float | None = None  # Surroundings Custom's, 0..MAX_SKY_GAIN; implies custom
    sky_tint: tuple | None = None  # Surroundings Custom's sky colour (R, G, B 0..1); implies custom
    contact_shadow: float | None = None  # the ground's contact shadow strength, 0..1
    frame: int | None = None  # one frame of the scene
    engine: str | None = None  # CYCLES or EEVEE
    samples: int | None = None  # render samples (0: the shot's)
    scale: int | None = None  # resolution percentage (0: the shot's)
    passes: int | str = 1  # inter-reflection passes >= 1, or "auto"
    tolerance: float | None = None  # passes "auto": stop below (None or 0: interreflect's)
    max_passes: int | None = None  # passes "auto": at most (None or 0: interreflect's)
    no_reflections: bool = False  # the plain render, for comparisons
    name: str | None = None  # output file stem; None: the .blend's name
    frames: str | None = None  # a range: 1-240, 1..240, 1-10x2, 5 or 1,3,7-9
    format: str = "exr"  # a frame range's output: exr or png
    overwrite: bool = False  # render frames that are already complete again
    report: str | None = None  # report path; None: OUT/<name>.report.json
    smoothing: float | None = None  # bounds smoothing over frames, 0..0.95

    @classmethod
    def from_namespace(cls, namespace):
        """From render_shot's argparse namespace (its attributes are exactly these fields)."""
        return cls(**vars(namespace))

    def __post_init__(self):
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
        for key, choices in (
            ("combine", COMBINES),
            ("method", METHODS),
            ("surroundings", SURROUNDINGS),
            ("engine", ENGINES),
            ("format", FORMATS),
        ):
            value = getattr(self, key)
            if (value is not None or key == "format") and value not in choices:
                raise ValueError(f"--{key} must be {_words(choices)}, not {value!r}")
        if self.resolution is not None and self.resolution not in (*RESOLUTIONS, "AUTO"):
            raise ValueError(
                f"--resolution must be {_words((*RESOLUTIONS, 'AUTO'))}, not {self.resolution!r}"
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
        if t is not None and t != 0 and not (t % 4 == 0 and 4 <= t <= 1024):
            raise ValueError(f"--triangles must be 0 or a multiple of 4 from 4 to 1024, not {t}")
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
