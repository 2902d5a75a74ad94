"""How much memory a job may still use, and refusing up front a job that cannot fit.

A job that would run out of memory half-way fails late and, under a farm's memory limit, is
killed without a word. The engine and the batch estimate what a job needs from the plate's
header and the map's size, compare it with what this process may still allocate (the
address-space limit, RLIMIT_AS, and the machine's available memory and swap) and refuse with
one line when it does not fit. The estimate is an upper bound of the peak, not the average.
Measured: a 6400x3200 Cycles render of one pass peaks at about 85 bytes a pixel
(`render_job_bytes` says 96).
"""

from __future__ import annotations

import resource


class MemoryLimitError(MemoryError):
    """A job that cannot fit in the memory this process may use; the message is one line.
    Exit code 1: not bad input, the same job may run on a bigger machine."""

    exit_code = 1


def _status_bytes(field: str, path: str = "/proc/self/status") -> int | None:
    try:
        with open(path, encoding="ascii") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024  # kB
    except (OSError, ValueError, IndexError):
        return None
    return None


def available_bytes() -> int:
    """Bytes this process may still allocate: the smaller of the address-space limit left
    (RLIMIT_AS minus what is mapped now) and the machine's available memory plus free swap."""
    limits = []
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    if soft != resource.RLIM_INFINITY:
        limits.append(max(0, soft - (_status_bytes("VmSize") or 0)))
    available = _status_bytes("MemAvailable", "/proc/meminfo")
    if available is not None:
        limits.append(available + (_status_bytes("SwapFree", "/proc/meminfo") or 0))
    return min(limits) if limits else 1 << 62


def plate_job_bytes(
    width: int, height: int, map_pixels: int = 0, stored_bytes: int = 4, stored_pixels=None
) -> int:
    """An upper bound of the peak memory of one map from a plate.

    The file's pixels as stored, two float32 RGB copies of the larger (decoded, cleaned), and
    the map with its lookup table.

    Parameters
    ----------
    width, height : int
        The plate's size in pixels.
    map_pixels : int, optional
        The map's texels.
    stored_bytes : int, optional
        Bytes a channel as stored (4 channels at most).
    stored_pixels : int, optional
        Pixels as stored: an EXR's data window, which may be far larger than the plate;
        default the plate's.

    Returns
    -------
    int
        Bytes.
    """
    plate = width * height
    stored = plate if stored_pixels is None else stored_pixels
    return stored * 4 * stored_bytes + 2 * max(stored, plate) * 12 + map_pixels * 64


def check_fits(need: int, what: str) -> None:
    """Refuse a job that needs more memory than `available_bytes`.

    Parameters
    ----------
    need : int
        Bytes.
    what : str
        The job, for the message.

    Raises
    ------
    MemoryLimitError
        One line, when it does not fit.
    """
    have = available_bytes()
    if need > have:
        raise MemoryLimitError(
            f"{what} needs about {need / 2**30:.1f} GiB of memory, "
            f"{have / 2**30:.1f} GiB available: refused before starting"
        )


def render_job_bytes(width: int, height: int, passes: int = 1, compositing: bool = False) -> int:
    """An upper bound of the peak memory of rendering an image and reading it back.

    Per pass the renderer's buffer and the render result (float RGBA, 16 bytes a pixel each),
    plus four float RGBA copies (the EXR written and read back, the CG element, the composite)
    and two more with the compositor (measured: the module docstring).

    Parameters
    ----------
    width, height : int
        The render's size in pixels.
    passes : int, optional
        Render passes in all (each view layer's, Combined included).
    compositing : bool, optional
        The compositor runs.

    Returns
    -------
    int
        Bytes.
    """
    copies = 2 * max(1, passes) + 4 + (2 if compositing else 0)
    return width * height * 16 * copies
