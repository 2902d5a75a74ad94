"""Ctrl-C and SIGTERM around the compiled back end: a handler made by `interrupts.raising`
raises at once, except inside `uninterrupted` (a kernel loading, compiling or running),
where its exception waits for the block to end."""

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from virtual_reflections import interrupts

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def handler():
    previous = signal.signal(
        signal.SIGUSR1, interrupts.raising(lambda signum: KeyboardInterrupt(signum))
    )
    yield
    signal.signal(signal.SIGUSR1, previous)


def test_outside_a_block_the_handler_raises_at_once(handler):
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGUSR1)
        for _ in range(1000):  # the handler runs between two of these bytecodes
            pass


def test_inside_a_block_the_exception_waits_for_its_end(handler):
    done = []
    with pytest.raises(KeyboardInterrupt) as caught:
        with interrupts.uninterrupted():
            with interrupts.uninterrupted():  # nested: raised when the outermost ends
                os.kill(os.getpid(), signal.SIGUSR1)
                for _ in range(1000):
                    pass
                done.append("inner")
            done.append("outer")
    assert done == ["inner", "outer"]
    assert caught.value.args == (signal.SIGUSR1,)
    with interrupts.uninterrupted():  # nothing is left over for the next block
        done.append("next")
    assert done[-1] == "next"


def test_a_kernel_compiling_when_ctrl_c_arrives_finishes_first(tmp_path):
    """The first call of a kernel compiles it (here into an empty cache): a Ctrl-C that lands
    meanwhile is raised when the kernel returns, from `uninterrupted` — llvmlite, interrupted
    between freeing a string and forgetting it, frees it twice and aborts the process."""
    pytest.importorskip("numba")  # requirements/*.txt install it: CI runs this
    script = textwrap.dedent(
        """
        import os, signal, sys, threading, time, traceback
        import numpy as np
        sys.path.insert(0, sys.argv[1])
        from virtual_reflections import backends, interrupts
        kernels = backends.kernels()
        signal.signal(signal.SIGINT, interrupts.raising(lambda signum: KeyboardInterrupt()))
        src = np.ones((64, 64, 3), np.float32)
        dst = np.zeros((32, 32, 3), np.float32)
        threading.Timer(0.1, os.kill, (os.getpid(), signal.SIGINT)).start()
        started = time.perf_counter()
        try:
            backends.run(kernels.halve, src, dst)
        except KeyboardInterrupt as exc:
            where = traceback.extract_tb(exc.__traceback__)[-1]
            print(where.name, os.path.basename(where.filename), time.perf_counter() - started,
                  float(dst.min()))
        """
    )
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), VR_GATHER="numba")
    proc = subprocess.run(
        [sys.executable, "-c", script, str(ROOT)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    name, filename, seconds, smallest = proc.stdout.split()
    assert (name, filename) == ("uninterrupted", "interrupts.py")
    assert float(seconds) > 0.1  # the compile outlasted the signal's arrival
    assert float(smallest) == 1.0  # and the kernel ran to its end
