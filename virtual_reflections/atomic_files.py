"""Image files that appear whole or not at all, and the one-line errors of image files.

Every writer writes a temporary file beside the target (`temp_path`: hidden, named with the
writer's process id), which `commit` reads back whole with OpenImageIO before renaming it into
place, so a full disk or a dying writer never replaces a good file with a partial one (some
image libraries report no error on a full disk: libpng; the read-back catches that). Temporary
files of writers that died (SIGKILL) are removed by the next write of the same target
(`remove_stale_temps`). What the libraries print on the process's stderr themselves is
silenced or held (`quiet_stderr`, `held_stderr`), so a failure is the tool's one line:
`ImageError` (bad input, exit code 2) or `WriteError` (a full disk, exit code 1).
"""

from __future__ import annotations

import contextlib
import os
import re
import resource
import subprocess
import sys
import tempfile

from .cli_common import EXIT_BAD_INPUT, EXIT_FAILED


class ImageError(ValueError):
    """A plate or map file that cannot be read or written; the message is one line.

    Attributes
    ----------
    exit_code : int
        2, bad input (a missing or unreadable plate, a bad output name).
    """

    exit_code = EXIT_BAD_INPUT


class WriteError(ImageError):
    """Writing failed mid-run (a full disk, an I/O error); nothing was replaced.

    Attributes
    ----------
    exit_code : int
        1, a failure while working: worth running again.
    """

    exit_code = EXIT_FAILED


def same_file(a: str, b: str) -> bool:
    """Whether two paths name one file (or would: the same absolute path).

    Parameters
    ----------
    a, b : str
        File paths; either may not exist yet.

    Returns
    -------
    bool
    """
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.normcase(os.path.realpath(a)) == os.path.normcase(os.path.realpath(b))


_TEMP = re.compile(r"^\.(?P<stem>.+)\.(?P<pid>\d+)\.(?P<tag>tmp|render)(?:\.\w+)?$")


def temp_path(path: str, tag: str = "tmp") -> str:
    """The hidden temporary name beside a path that this process writes it under.

    Parameters
    ----------
    path : str
        The target file.
    tag : str, optional
        "tmp" or "render" (the tags `remove_stale_temps` knows).

    Returns
    -------
    str
        ``<folder>/.<stem>.<pid>.<tag><ext>``.
    """
    folder, base = os.path.split(os.path.abspath(path))
    stem, ext = os.path.splitext(base)
    return os.path.join(folder, f".{stem}.{os.getpid()}.{tag}{ext}")


def pid_alive(pid: int) -> bool:
    """True when process ``pid`` exists on this machine (False for this process's own id is
    not implied: the caller decides what to do with its own files)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def remove_stale_temps(folder: str, stems, live_ok: bool = False) -> list[str]:
    """Delete the temporary files that dead writers (SIGKILL, power loss) left for some outputs.

    Never this process's temporaries, never a live process's unless `live_ok`.

    Parameters
    ----------
    folder : str
    stems : iterable of str
        The outputs' file names without extension.
    live_ok : bool, optional
        The caller holds the lock of these outputs: a live process's temporaries go too.

    Returns
    -------
    list of str
        The paths removed.
    """
    stems = set(stems)
    removed = []
    try:
        entries = os.listdir(folder)
    except OSError:
        return removed
    for entry in entries:
        m = _TEMP.match(entry)
        if not m or m.group("stem") not in stems:
            continue
        pid = int(m.group("pid"))
        if pid == os.getpid() or (not live_ok and pid_alive(pid)):
            continue
        path = os.path.join(folder, entry)
        try:
            os.remove(path)
            removed.append(path)
        except OSError:
            pass
    return removed


@contextlib.contextmanager
def quiet_stderr():
    """Silence what image libraries print on the process's stderr themselves (libpng's
    "libpng error: ..."), so that a failure is the tool's one line, not two."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


# The keeper of held stderr (`held_stderr`): a small process that holds what arrives on its
# stdin until the control pipe says "R" (replay it on its stdout, the real stderr) or "D"
# (drop it). A process that dies inside the block (an abort, the out-of-memory killer) says
# nothing, its end of the control pipe closes, and its last lines are replayed.
_KEEPER = """
import os, select, signal, sys
for s in (signal.SIGINT, signal.SIGTERM):
    signal.signal(s, signal.SIG_IGN)
ctl, held, word, watch = int(sys.argv[1]), [], None, [0, int(sys.argv[1])]
while word is None:
    for fd in select.select(watch, [], [])[0]:
        chunk = os.read(fd, 65536 if fd == 0 else 1)
        if fd == ctl:
            word = chunk  # b"R", b"D", or b"" when the process died
        elif chunk:
            held.append(chunk)
        else:
            watch.remove(0)
os.set_blocking(0, False)  # what was written before the word is in the pipe: take it all
try:
    while chunk := os.read(0, 65536):
        held.append(chunk)
except BlockingIOError:
    pass
if word != b"D":
    sys.stdout.buffer.write(b"".join(held))
"""


def _start_keeper(stderr_fd):
    """(process, data write end, control write end) of a keeper replaying on ``stderr_fd``;
    None where none can start (no Python executable, e.g. a Blender without one)."""
    exe = sys.executable or ""
    if os.name != "posix" or not os.path.basename(exe).lower().startswith("python"):
        return None  # (Windows: the temporary file)
    data_r, data_w = os.pipe()
    ctl_r, ctl_w = os.pipe()
    try:
        keeper = subprocess.Popen(
            [exe, "-I", "-S", "-c", _KEEPER, str(ctl_r)],
            stdin=data_r,
            stdout=stderr_fd,
            stderr=subprocess.DEVNULL,
            pass_fds=(ctl_r,),
            start_new_session=True,  # Ctrl-C at the terminal is the batch's, not the keeper's
        )
    except (OSError, ValueError):
        os.close(data_w)
        os.close(ctl_w)
        return None
    finally:
        os.close(data_r)
        os.close(ctl_r)
    return keeper, data_w, ctl_w


@contextlib.contextmanager
def held_stderr():
    """Hold what is printed on the process's stderr (fd 2) while the block runs.

    Replayed when the block succeeds, dropped when it raises (a failure is the tool's one line),
    replayed when the process dies inside it (an abort under a memory limit). A keeper process
    holds the lines (`_KEEPER`); without one a temporary file, lost if the process dies.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    keeper = _start_keeper(saved)
    held = None
    if keeper is None:
        try:
            held = tempfile.TemporaryFile()
        except OSError:
            os.close(saved)
            yield
            return
    ok = False
    try:
        if keeper is not None:
            os.dup2(keeper[1], 2)
            os.close(keeper[1])
        else:
            os.dup2(held.fileno(), 2)
        yield
        ok = True
    finally:
        os.dup2(saved, 2)  # everything the block wrote is in the keeper's pipe now
        if keeper is not None:
            with contextlib.suppress(OSError):
                os.write(keeper[2], b"R" if ok else b"D")
            os.close(keeper[2])
            keeper[0].wait()  # its replay comes before anything printed after the block
        elif ok:
            held.seek(0)
            data = held.read()
            if data:
                with contextlib.suppress(OSError):
                    os.write(2, data)
        if held is not None:
            held.close()
        os.close(saved)


def openimageio():
    try:
        import OpenImageIO
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImageError("OpenImageIO is not installed (pip install OpenImageIO)") from exc
    return OpenImageIO


def first_line(message: str) -> str:
    lines = [line for line in (message or "").splitlines() if line.strip()]
    return lines[0] if lines else "unknown error"


def verify_image(path: str, width: int, height: int, what: str | None = None) -> None:
    """Read ``path`` back whole; WriteError (one line, naming ``what`` or ``path``) unless it
    is a complete image of ``width`` x ``height``."""
    name = what or path
    oiio = openimageio()
    with quiet_stderr():
        _verify(oiio, path, width, height, name)


def _verify(oiio, path, width, height, name):
    inp = oiio.ImageInput.open(path)
    if inp is None:
        oiio.geterror()
        raise WriteError(f"cannot write {name}: the file written is unreadable (disk full?)")
    try:
        spec = inp.spec()
        if (spec.width, spec.height) != (width, height):
            raise WriteError(
                f"cannot write {name}: the file written is {spec.width}x{spec.height}, "
                f"not {width}x{height}"
            )
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None or inp.has_error:
            raise WriteError(
                f"cannot write {name}: the file written is incomplete (disk full?): "
                f"{first_line(inp.geterror())}"
            )
    finally:
        inp.close()
        oiio.geterror()  # drop what the library kept, so it is not printed at exit


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def commit(temp: str, path: str, width: int, height: int) -> None:
    """Verify a written temporary image, flush it to disk and rename it into place.

    The one way every writer puts an image in place. On any failure `temp` is removed, `path`
    left untouched.

    Parameters
    ----------
    temp : str
        The temporary file written (`temp_path`).
    path : str
        The target.
    width, height : int
        The size the image must have, read back whole.

    Raises
    ------
    WriteError
        One line: the file is unreadable, incomplete, of another size, or cannot be renamed.
    """
    try:
        verify_image(temp, width, height, what=path)
        _fsync(temp)
        os.replace(temp, path)
    except OSError as exc:
        raise WriteError(f"cannot write {path}: {exc.strerror or exc}") from exc
    finally:
        if os.path.exists(temp):
            os.remove(temp)
    try:
        _fsync(os.path.dirname(os.path.abspath(path)) or ".")
    except OSError:
        pass  # some file systems cannot sync a folder; the file itself is on disk


def free_bytes(folder: str) -> int:
    """Bytes this process may still write into ``folder``: the file system's free space,
    and the process's file-size limit (RLIMIT_FSIZE)."""
    try:
        st = os.statvfs(folder)
        free = st.f_bavail * st.f_frsize
    except OSError:
        free = 1 << 62
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return free if soft == resource.RLIM_INFINITY else min(free, soft)


def check_space(path: str, nbytes: int) -> None:
    """WriteError (one line) when fewer than ``nbytes`` can be written beside ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    free = free_bytes(folder)
    if free < nbytes:
        raise WriteError(
            f"cannot write {path}: not enough space in {folder} "
            f"(needs up to {nbytes / 1e6:.1f} MB, {free / 1e6:.1f} MB free)"
        )
