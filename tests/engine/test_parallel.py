"""for_blocks: every row once, errors raised once no block runs, and an interrupted caller
leaves nothing of its work running and no thread for the interpreter to wait for."""

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from virtual_reflections import parallel

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def two_threads(monkeypatch):
    monkeypatch.setenv("VR_THREADS", "2")


@pytest.mark.parametrize("rows,min_rows,max_rows", [(10, 1, None), (1000, 16, 7), (5, 1, 1)])
def test_every_row_once(two_threads, rows, min_rows, max_rows):
    seen = np.zeros(rows, dtype=int)
    lock = threading.Lock()

    def block(a, b):
        with lock:
            seen[a:b] += 1

    parallel.for_blocks(block, rows, min_rows=min_rows, max_rows=max_rows)
    assert seen.tolist() == [1] * rows


def test_a_blocks_error_is_raised_once_no_block_runs(two_threads):
    running = []

    def block(a, b):
        running.append(a)
        time.sleep(0.02)
        running.remove(a)
        if a == 0:
            raise ValueError("block 0")

    with pytest.raises(ValueError, match="block 0"):
        parallel.for_blocks(block, 64, min_rows=1, max_rows=4)
    assert running == []


def test_nested_calls_run_in_the_helper_thread(two_threads):
    total = []

    def inner(a, b):
        total.append(b - a)

    def outer(a, b):
        parallel.for_blocks(inner, 40, min_rows=1, max_rows=4)

    parallel.for_blocks(outer, 8, min_rows=1, max_rows=1)
    assert sum(total) == 8 * 40


def test_an_interrupted_caller_leaves_no_block_running(two_threads):
    """Ctrl-C lands in the caller while the helpers work: the blocks running finish, the
    others never start, and the interrupt goes on."""
    running, ran = [], []

    def block(a, b):
        running.append(a)
        time.sleep(0.1)  # 40 blocks on 2 threads: 2 s, the interrupt comes at 0.08 s
        ran.append(a)
        running.remove(a)

    threading.Timer(0.08, os.kill, (os.getpid(), signal.SIGINT)).start()
    with pytest.raises(KeyboardInterrupt):
        parallel.for_blocks(block, 40, min_rows=1, max_rows=1)
    assert running == []
    finished = len(ran)
    assert finished < 40
    time.sleep(0.25)
    assert running == [] and len(ran) == finished  # nothing started after the call ended
    assert all(t.daemon for t in threading.enumerate() if t.name.startswith("vr_"))


def test_a_process_interrupted_in_for_blocks_exits():
    """SIGINT while the first call starts its threads, or while it waits: the process
    ends with KeyboardInterrupt at once, by SIGINT as Python ends on one it does not catch
    (no thread left for the interpreter to wait for)."""
    script = textwrap.dedent(
        """
        import os, signal, sys, threading, time
        sys.path.insert(0, sys.argv[1])
        os.environ["VR_THREADS"] = "4"
        from virtual_reflections import parallel
        def block(a, b):
            time.sleep(0.01)
        threading.Timer(float(sys.argv[2]), os.kill, (os.getpid(), signal.SIGINT)).start()
        while True:
            parallel.for_blocks(block, 64, min_rows=1, max_rows=1)
        """
    )
    for delay in np.geomspace(0.0005, 0.05, 24):  # the old pool hung at exit in ~1 of 20
        try:
            proc = subprocess.run(
                [sys.executable, "-c", script, str(ROOT), f"{delay:.4f}"],
                capture_output=True,
                text=True,
                timeout=30,
            )
        except subprocess.TimeoutExpired:
            pytest.fail(f"interrupted {delay:.4f} s in: the process did not exit")
        assert proc.returncode == -signal.SIGINT and "KeyboardInterrupt" in proc.stderr, (
            proc.stderr[-500:]
        )


def _sum_in_blocks(rows):
    out = np.zeros(rows)
    parallel.for_blocks(
        lambda a, b: out.__setitem__(slice(a, b), 1.0), rows, min_rows=1, max_rows=2
    )
    return out.sum()


# Python 3.12+ warns on any fork of a process with threads: forking one is what this checks.
@pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning")
def test_a_forked_child_starts_its_own_threads(two_threads):
    """The study's and a farm's worker pools fork: the parent's threads do not live on in
    the child, which starts its own (it would wait forever for the parent's)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    assert _sum_in_blocks(64) == 64  # the parent's threads started
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        assert list(pool.map(_sum_in_blocks, [32, 48], timeout=60)) == [32, 48]
