"""Ctrl-C and SIGTERM around the compiled back end.

A Python signal handler raises its exception between two bytecodes of the main thread,
wherever that thread is. Numba and llvmlite are not safe against that: an interrupt that
lands in llvmlite between freeing a string and forgetting it frees it twice, and the process
aborts on its way out. So while a kernel loads, compiles or runs in the main thread
(`uninterrupted`), a handler made by `raising` keeps its exception, and the block raises it
when it ends; anywhere else the handler raises at once.

An interrupt raised inside a callback from C (Numba caches a kernel through one) cannot be
passed on by Python, which prints it as unraisable: `hold_interrupts` keeps it to be raised
when the work returns, and `silent` is the hook for the way out once one line has said why
the run ended.
"""

from __future__ import annotations

import contextlib
import threading

_depth = [0]  # nested `uninterrupted` blocks in the main thread
_deferred: list[BaseException] = []  # what the handlers kept meanwhile


def _main() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def uninterrupted():
    """Hold the exceptions of `raising` handlers until the block ends (main thread; in any
    other thread no handler runs, and this does nothing)."""
    if not _main():
        yield
        return
    _depth[0] += 1
    try:
        yield
    finally:
        _depth[0] -= 1
        if not _depth[0] and _deferred:
            exc = _deferred[-1]
            _deferred.clear()
            raise exc


def raising(make):
    """A signal handler that raises an exception at once, or when its `uninterrupted` block ends.

    Parameters
    ----------
    make : callable
        ``make(signum)`` returns the exception to raise.

    Returns
    -------
    callable
        A handler for `signal.signal`.
    """

    def handler(signum, frame):
        exc = make(signum)
        if _depth[0]:
            _deferred.append(exc)
            return
        raise exc

    return handler


def hold_interrupts(hook, held: list):
    """A `sys.unraisablehook` that keeps the interrupts Python cannot pass on, to raise them later.

    An interrupt raised in a callback from C (Numba caches a kernel it compiled through one) is
    kept, to be raised again when the work returns.

    Parameters
    ----------
    hook : callable
        The hook every other unraisable error is handed to.
    held : list
        Where the interrupts are kept.

    Returns
    -------
    callable
    """

    def unraisable(info):
        if isinstance(info.exc_value, KeyboardInterrupt):
            held.append(info.exc_value)
        else:
            hook(info)

    return unraisable


def silent(info) -> None:
    """The unraisablehook after an interrupt: the process ends where the work stopped, and
    what that work leaves half made (a kernel being compiled) may fail in its destructor on
    the way out; nothing of it is printed, the one line said why the run ended."""
