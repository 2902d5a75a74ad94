"""Frame numbers and the files of image sequences: the grammar of ``--frames`` and Blender's
rules for a sequence's file names and an image user's frame mapping. Pure Python (no bpy), so
the add-on (operators/sequence.py, batch.py) and the farm driver (pipeline/farm.py) share it.
"""

import os
import re

MOVIE_EXTENSIONS = {
    ".avi", ".dv", ".flv", ".m2t", ".m2ts", ".m4v", ".mkv", ".mov", ".mp4", ".mpeg",
    ".mpg", ".mts", ".mxf", ".ogg", ".ogv", ".webm", ".wmv",
}  # fmt: skip
FRAMES_HELP = "frames: 1-240 or 1..240, 1-10x2 (every 2nd), 5, or a list like 1,3,7-9"
MAX_FRAMES = 1_000_000
_PART = re.compile(r"^(-?\d+)(?:(?:-|\.\.)(-?\d+)(?:x(\d+))?)?$")


def parse_frames(text: str) -> list[int]:
    """Parse a frame list into sorted distinct frame numbers.

    ``"1-240"``, ``"1-10x2"``, ``"5"``, ``"1,3,7-9"``; Blender's own syntax (``blender -f 1..10``,
    ``1,3,5..7``: ``..`` joins the first and last frame, both included) beside it.

    Parameters
    ----------
    text : str

    Returns
    -------
    list of int

    Raises
    ------
    ValueError
        One line naming the bad part: anything else, an empty list, an end before its start, a
        step below 1, or more than MAX_FRAMES frames.
    """
    found = set()
    for part in str(text).replace(" ", "").split(","):
        m = _PART.match(part)
        if not m:
            raise ValueError(f"bad frame range {part!r} ({FRAMES_HELP})")
        first, last, step = m.groups()
        first = int(first)
        last = first if last is None else int(last)
        step = int(step or 1)
        if last < first or step < 1:
            raise ValueError(f"bad frame range {part!r} ({FRAMES_HELP})")
        if (last - first) // step + 1 + len(found) > MAX_FRAMES:
            raise ValueError(f"frame range {part!r} has more than {MAX_FRAMES} frames")
        found.update(range(first, last + 1, step))
    return sorted(found)


def user_frame(frame, start=1, duration=0, offset=0, cyclic=False) -> int:
    """The plate frame an image user shows at a scene frame (``BKE_image_user_frame_get``).

    Parameters
    ----------
    frame : int
        The scene frame.
    start, duration, offset : int, optional
        The image user's; `duration` 0 (an image user never set up) gives `frame` itself.
    cyclic : bool, optional
        Wrap past the duration instead of holding the last frame.

    Returns
    -------
    int
        ``frame - start + 1`` clamped to 0..duration (wrapped with `cyclic`), plus `offset`.
    """
    if duration <= 0:
        return frame
    n = frame - start + 1
    if cyclic:
        n %= duration
        if n == 0:
            n = duration
    return min(max(n, 0), duration) + offset


def sequence_path(path: str, number: int) -> str:
    """The file of one frame of a sequence, from one of its files (``BLI_path_sequence_decode``).

    The last run of digits in the file name before its extension is replaced by the number,
    padded to the run's width.

    Parameters
    ----------
    path : str
        One file of the sequence.
    number : int
        The frame.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        The file name holds no digits.
    """
    folder, name = os.path.split(path)
    stem, ext = os.path.splitext(name)
    m = re.search(r"(\d+)(\D*)$", stem)
    if m is None:
        raise ValueError(f"{name}: no frame number in the file name")
    digits = m.group(1)
    return os.path.join(folder, f"{stem[: m.start(1)]}{number:0{len(digits)}d}{m.group(2)}{ext}")


def sequence_range(path: str, limit: int = MAX_FRAMES) -> tuple[int, int]:
    """The run of existing files of the sequence one of whose files is given.

    From its own number down and up while the files exist (Blender's image user needs the count;
    ``Image.frame_duration`` stays 1 for a sequence loaded from Python).

    Parameters
    ----------
    path : str
        One file of the sequence.
    limit : int, optional
        The most frames counted on either side.

    Returns
    -------
    (first, count) : tuple of 2 ints

    Raises
    ------
    ValueError
        The file name holds no digits.
    """
    stem = os.path.splitext(os.path.basename(path))[0]
    m = re.search(r"(\d+)\D*$", stem)
    if m is None:
        raise ValueError(f"{os.path.basename(path)}: no frame number in the file name")
    first = last = int(m.group(1))
    while first > 0 and last - first < limit and os.path.isfile(sequence_path(path, first - 1)):
        first -= 1
    while last - first < limit and os.path.isfile(sequence_path(path, last + 1)):
        last += 1
    return first, last - first + 1


def is_pattern(text: str) -> bool:
    """Whether a path is a sequence pattern: ``plate.####.exr`` or ``plate.%04d.exr``.

    Parameters
    ----------
    text : str

    Returns
    -------
    bool
    """
    return (
        "#" in os.path.basename(text) or re.search(r"%0?\d*d", os.path.basename(text)) is not None
    )


def pattern_path(pattern: str, number: int) -> str:
    """A pattern's file for one frame.

    A run of n ``#`` (the last in the file name) becomes the number padded to n digits, ``%0Nd``
    is printf's; negative numbers keep their sign.

    Parameters
    ----------
    pattern : str
    number : int

    Returns
    -------
    str
    """
    folder, name = os.path.split(pattern)
    if "#" in name:
        runs = list(re.finditer(r"#+", name))
        run = runs[-1]
        name = f"{name[: run.start()]}{number:0{len(run.group())}d}{name[run.end() :]}"
    else:
        name = re.sub(r"%(0?\d*)d", lambda m: f"%{m.group(1)}d" % number, name, count=1)
    return os.path.join(folder, name)


def pattern_frame(pattern: str, path: str) -> int | None:
    """The frame number whose file of a pattern (`pattern_path`) is a path, existing or not.

    ``plate.####.exr`` names ``plate.0012.exr`` (12), not ``plate.12.exr``; folders are compared
    as real paths.

    Parameters
    ----------
    pattern : str
    path : str

    Returns
    -------
    int or None
        None when `path` is no file of `pattern`.
    """
    folder, name = os.path.split(os.path.abspath(path))
    base = os.path.basename(pattern)
    if "#" in base:
        token = list(re.finditer(r"#+", base))[-1]
    else:
        token = re.search(r"%(0?\d*)d", base)
        if token is None:
            return None
    m = re.fullmatch(
        re.escape(base[: token.start()]) + r"(-?\d+)" + re.escape(base[token.end() :]), name
    )
    if m is None:
        return None
    number = int(m.group(1))
    if os.path.basename(pattern_path(pattern, number)) != name:
        return None
    same = os.path.realpath(folder) == os.path.realpath(os.path.dirname(os.path.abspath(pattern)))
    return number if same else None


def is_movie_path(path: str) -> bool:
    """Whether a path names a movie file by its extension (MOVIE_EXTENSIONS).

    Parameters
    ----------
    path : str

    Returns
    -------
    bool
    """
    return os.path.splitext(path)[1].lower() in MOVIE_EXTENSIONS
