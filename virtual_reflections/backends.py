"""The optional back ends, used when they import: compiled kernels (Numba) and OpenCV.

Blender bundles neither and the extension never requires them: every step they speed up has
a NumPy path that stays the reference (tests compare them). Which one does what:

- the per-frame gathers and the mip pyramid: Numba's kernels (kernels.py) when `numba`
  imports (`backend()`);
- else OpenCV's remap and area resize when `cv2` imports (`pyramid_backend()`: OpenCV
  halves the pyramid also when VR_GATHER=opencv leaves Numba out);
- else NumPy.

VR_GATHER=numpy forces NumPy everywhere; VR_GATHER=opencv leaves Numba out; VR_GATHER=numba
asks for it first (each only when it imports).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import sys
import threading

import numpy as np

from .interrupts import uninterrupted

_cv2 = []
_kernels = []
_lock = threading.Lock()


def cv2():
    """The cv2 module, or None when it does not import (imported once)."""
    if not _cv2:
        try:
            import cv2 as module  # optional: never required
        except Exception:  # not installed, or broken: the NumPy path, never an error
            module = None
        _cv2.append(module)
    return _cv2[0]


KERNELS = "virtual_reflections_kernels"  # the compiled kernels' module, by one name


def kernels():
    """The compiled kernels (kernels.py), or None when Numba does not import (once).

    Loaded as the top-level module KERNELS whatever the package is called (the engine, the
    add-on as Blender names it, the tests' copy): Numba's on-disk cache is kept per source
    file and records the module to import when it loads a kernel, so one name serves every
    way the file is imported."""
    if not _kernels:
        try:
            with uninterrupted():  # importing Numba loads llvmlite: see interrupts.py
                module = sys.modules.get(KERNELS) or _load_kernels()
                _start_threads()
        except Exception:  # not installed, or broken: the other back ends, never an error
            module = None
        _kernels.append(module)
    return _kernels[0]


def _start_threads() -> None:
    """Numba's threads: its own scheduler (workqueue) unless NUMBA_THREADING_LAYER names
    another — GNU OpenMP, which Numba would pick where it is installed, aborts a process that
    forks after using it (the study's and a farm's worker pools fork), and the calls here are
    one at a time anyway (`run`) — as many as the engine's threads (VR_THREADS)."""
    import numba

    from .parallel import workers

    if not os.environ.get("NUMBA_THREADING_LAYER"):
        numba.config.THREADING_LAYER = "workqueue"
    numba.set_num_threads(min(workers(), numba.config.NUMBA_NUM_THREADS))


def _load_kernels():
    """Import kernels.py (which imports numba: optional, never required) as KERNELS, its
    compiled kernels cached in `cache_folder` (Numba picks a kernel's cache folder when the
    module defines it, from numba.config.CACHE_DIR: set for this module alone)."""
    import numba

    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "kernels.py")
    spec = importlib.util.spec_from_file_location(KERNELS, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[KERNELS] = module
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = previous or cache_folder()  # a host's own setting stays
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[KERNELS]
        raise
    finally:
        numba.config.CACHE_DIR = previous
    return module


def cache_folder() -> str:
    """Where the compiled kernels are cached: NUMBA_CACHE_DIR when it is set, else the user's
    cache folder (``$XDG_CACHE_HOME`` or ``~/.cache``, ``~/Library/Caches`` on macOS,
    ``%LOCALAPPDATA%`` on Windows) + ``virtual-reflections/numba``; never the package's own
    folder, which an installed extension may not write and an update replaces."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser(r"~\AppData\Local")
    elif sys.platform == "darwin":
        base = os.path.expanduser("~/Library/Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return os.path.join(base, "virtual-reflections", "numba")


_preferred = []  # the back end a caller prefers when VR_GATHER names none (`preferring`)


@contextlib.contextmanager
def preferring(name: str):
    """Use back end `name` when VR_GATHER names none, while the block runs.

    The engine's command line makes one map per call and prefers NumPy: importing Numba and
    loading its kernels costs more than they save on one map (1.4-3.6 times slower per call,
    benchmarks/cli_backend_bench.py); a process making many maps keeps the default.

    Parameters
    ----------
    name : str
        'numba', 'opencv' or 'numpy'.
    """
    if name not in NAMES:
        raise ValueError(f"back end must be one of {', '.join(NAMES)}, got {name!r}")
    _preferred.append(name)
    try:
        yield
    finally:
        _preferred.pop()


def _forced() -> str:
    return os.environ.get("VR_GATHER", "").strip().lower() or (_preferred[-1] if _preferred else "")


def backend() -> str:
    """The gathers' back end, as the module docstring says (VR_GATHER, what imports).

    Returns
    -------
    {"numba", "opencv", "numpy"}
    """
    forced = _forced()
    if forced == "numpy":
        return "numpy"
    if forced != "opencv" and kernels() is not None:
        return "numba"
    return "opencv" if cv2() is not None else "numpy"


def available_backends() -> list:
    """The gathers' back ends that import here, fastest first (NumPy always).

    Returns
    -------
    list of str
    """
    names = ["numba"] if kernels() is not None else []
    return names + (["opencv"] if cv2() is not None else []) + ["numpy"]


NAMES = {"numba": "compiled (Numba)", "opencv": "OpenCV", "numpy": "NumPy"}


def installed() -> list:
    """The optional back ends whose modules are installed, fastest first.

    Found without importing them, so a panel may ask while it draws.

    Returns
    -------
    list of str
        Of "numba", "opencv".
    """
    found = importlib.util.find_spec
    return [name for name, module in (("numba", "numba"), ("opencv", "cv2")) if found(module)]


def describe() -> str:
    """The gathers' back end, named for a panel.

    The one in use once the engine has chosen, else the fastest installed (found, not imported:
    importing Numba takes ~0.5 s).

    Returns
    -------
    str
        A value of NAMES, as "compiled (Numba)".
    """
    if _kernels or _forced():
        return NAMES[backend()]
    return NAMES[(installed() or ["numpy"])[0]]


def pyramid_backend() -> str:
    """The pyramid's back end: Numba's when the gathers use it, else OpenCV's area resize
    when cv2 imports and NumPy is not forced, else NumPy."""
    use = backend()
    if use == "numba":
        return "numba"
    return "opencv" if _forced() != "numpy" and cv2() is not None else "numpy"


def given(array, columns: int = 0, dtype=np.float32) -> np.ndarray:
    """`array`, or for None an empty one (columns wide, 0: one axis): a compiled kernel takes
    an array where an argument is absent."""
    if array is not None:
        return array
    return np.zeros((0, columns) if columns else 0, dtype)


def run(kernel, *args) -> None:
    """Call a compiled kernel, one at a time: Numba's default threading layer must not be
    entered from two threads at once (it would abort the process). A Ctrl-C in the main thread
    waits until the kernel returns: the first call compiles or loads it, which an interrupt
    would leave half freed (interrupts.py)."""
    with uninterrupted(), _lock:
        kernel(*args)
