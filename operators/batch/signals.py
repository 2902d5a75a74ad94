"""Ctrl-C and SIGTERM in the headless batch: the run stops where it is, with its exit code.

A signal raises `Interrupted` (a KeyboardInterrupt: 130 for Ctrl-C, 143 for SIGTERM) while
`stop_on_signals` is on; a signal that arrives during a render is caught by Blender's render,
so the batch's render steps call `raise_if_signalled` after it. render_shot.py turns
`Interrupted` into one line and the exit code; the frames already written stay whole.
"""

import contextlib
import gc
import signal
import sys

from ...virtual_reflections.interrupts import hold_interrupts, raising


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (exit code 130) or SIGTERM (143): the run stops where it is, its temporary
    files are removed on the way out, finished frames stay."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum
        self.exit_code = 143 if signum == signal.SIGTERM else 130


_signalled = []  # signals received while a run is on


def _interrupted(signum):
    _signalled.append(signum)
    return Interrupted(signum)


# raised where the run is, or when a compiled kernel the signal arrived in returns
_on_signal = raising(_interrupted)


def raise_if_signalled():
    """A signal that arrived during a render: Blender's render catches the exception the
    handler raised (and prints it), so raise it again here."""
    if _signalled:
        # Blender printed the exception the handler raised in the render engine and keeps it
        # (sys.last_*), with the engine's frame: let the engine go now, while stderr is held.
        for name in ("last_exc", "last_type", "last_value", "last_traceback"):
            if hasattr(sys, name):
                setattr(sys, name, None)
        gc.collect()
        raise Interrupted(_signalled[-1])


@contextlib.contextmanager
def stop_on_signals():
    """Ctrl-C and SIGTERM raise Interrupted while the block runs (main thread only)."""
    _signalled.clear()
    previous = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is not signal.SIG_IGN:  # nohup's stays ignored
                previous[sig] = signal.signal(sig, _on_signal)
    except ValueError:  # not the main thread
        pass
    hook = sys.unraisablehook
    sys.unraisablehook = hold_interrupts(hook, [])  # recorded in _signalled already
    try:
        yield
    finally:  # what arrived during the block is its own, not a later run's in this process
        _signalled.clear()
        sys.unraisablehook = hook
        for sig, handler in previous.items():
            if handler is not None:  # None: a handler set outside Python (Blender's)
                signal.signal(sig, handler)
