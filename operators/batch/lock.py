"""Which run owns which outputs of a shot: byte-range locks on one hidden lock file.

Two batch runs writing the same frames into one folder would delete each other's temporary
files and race on the same names. Each run locks, in ``OUT/.<name>.lock``, one byte per
frame it will write (`fcntl.lockf`, POSIX record locks: released by the system when the
process ends, even by SIGKILL, and honoured across machines on NFS). A run whose frames
overlap a live run's is refused with one line naming the owner's process id; runs on
disjoint frames (farm chunks) share the folder. The last run out removes the lock file.

No bpy here.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import struct

SINGLE = 1  # the one-frame mode's outputs (<name>_render.exr, _composite.png/.exr)
FRAME_BASE = 1 << 32  # frame f locks byte FRAME_BASE + f (frames may be negative)


class FolderInUse(ValueError):
    """Another live run owns some of these outputs; the message is one line (exit code 2)."""


def _owner(fd: int, offset: int) -> int | None:
    """The process id holding the lock at ``offset`` (Linux F_GETLK), or None."""
    try:
        query = struct.pack("hhqqi4x", fcntl.F_WRLCK, os.SEEK_SET, offset, 1, 0)
        kind, _, _, _, pid = struct.unpack("hhqqi4x", fcntl.fcntl(fd, fcntl.F_GETLK, query))
    except (OSError, struct.error):
        return None
    return pid if kind != fcntl.F_UNLCK and pid > 0 else None


class OutputLock:
    """The lock of ``frames`` (or the single-frame outputs, ``frames=None``) of shot ``name``
    in ``folder``: `acquire` or FolderInUse, `release` when done (a context manager)."""

    def __init__(self, folder: str, name: str, frames=None):
        self.path = os.path.join(folder, f".{name}.lock")
        self.name = name
        self.offsets = [SINGLE] if frames is None else [FRAME_BASE + f for f in frames]
        self.frames = frames
        self.fd = None

    def acquire(self):
        for _ in range(20):  # another run may remove the file between our open and lock
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            for i, offset in enumerate(self.offsets):
                try:
                    fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, offset)
                except OSError:
                    pid = _owner(fd, offset)
                    os.close(fd)
                    what = (
                        f"frame {self.frames[i]} of {self.name!r}"
                        if self.frames is not None
                        else f"the outputs of {self.name!r}"
                    )
                    owner = f"pid {pid}" if pid else "another machine or process"
                    raise FolderInUse(
                        f"output folder {os.path.dirname(self.path)} is in use: {what} is "
                        f"being rendered by a live run ({owner}; lock {self.path})"
                    ) from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self.fd = fd
                return self
            os.close(fd)
        raise FolderInUse(f"cannot lock {self.path}: it keeps disappearing")

    def release(self):
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            fcntl.lockf(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 0, 0)  # nobody else in it
            os.remove(self.path)
        os.close(self.fd)
        self.fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
