"""What both command lines share: the engine's (cli.py) and the headless batch's (render_shot.py).

Exit codes (docs/failures.md): 0 done; 2 bad input, one line on stderr and nothing written; 1 a
failure while working, one line; 130 Ctrl-C; 143 SIGTERM. Never a traceback for these. A bad
command line is a `UsageError` of one line, raised by `Parser` in place of argparse's usage
block; `error_line` and `stopped` print the one line each ending says.

Nothing but the standard library, and nothing of the engine.
"""

from __future__ import annotations

import argparse
import sys

EXIT_DONE = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM (a farm cancelling the task), raised where the process is, so that its temporary
    files are removed on the way out."""


class UsageError(Exception):
    """Bad command-line input; the message is one line (exit code 2)."""

    exit_code = EXIT_BAD_INPUT


class Parser(argparse.ArgumentParser):
    """An argument parser whose error is one `UsageError` (no usage block, no exit of its own)
    and which knows each option by its whole name only (allow_abbrev=False: `--ou` is no
    `--out`)."""

    def __init__(self, *args, allow_abbrev: bool = False, **kwargs):
        super().__init__(*args, allow_abbrev=allow_abbrev, **kwargs)

    def error(self, message):
        raise UsageError(message)


def first_line(message) -> str:
    """The first line of ``message`` that is not blank ("failed" for none)."""
    lines = [line for line in str(message).splitlines() if line.strip()]
    return lines[0] if lines else "failed"


def error_line(prog: str, message) -> None:
    """Print ``prog: error: <the first line of message>`` on stderr."""
    print(f"{prog}: error: {first_line(message)}", file=sys.stderr, flush=True)


def stopped(prog: str, exc: KeyboardInterrupt) -> int:
    """Say that a signal stopped the run (``prog: terminated`` or ``interrupted``) and return
    its exit code: 143 for `Terminated` (or an exception whose exit_code says 143), else 130."""
    code = EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED
    code = getattr(exc, "exit_code", code)
    word = "terminated" if code == EXIT_TERMINATED else "interrupted"
    print(f"{prog}: {word}", file=sys.stderr, flush=True)
    return code


def words(choices) -> str:
    """A list in words: ("a", "b", "c") -> "a, b or c".

    Parameters
    ----------
    choices : sequence
        One or more values, each written with ``str``.

    Returns
    -------
    str
        The values joined by ", ", the last by " or ".
    """
    choices = [str(c) for c in choices]
    return ", ".join(choices[:-1]) + " or " + choices[-1] if len(choices) > 1 else choices[0]
