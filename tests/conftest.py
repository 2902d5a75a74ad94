"""Shared pytest set-up: the repository root on sys.path for the engine, and Ctrl-C
deliverable.

Some tests send SIGINT to the suite itself or to the processes it starts, to check what a
user's Ctrl-C does. A shell starts a background job (`tools/run-tests &`) with SIGINT
ignored, and an ignored signal stays ignored across exec: every child would then ignore
Ctrl-C too, as the add-on's batch means to under `nohup`. So the suite puts Python's own
handler back; its children start with SIGINT at its default, as from a terminal."""

import pathlib
import signal
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
