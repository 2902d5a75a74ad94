"""Split row-wise NumPy work over the machine's cores.

NumPy releases the GIL inside its loops over large arrays, so a few threads each working on
a block of rows run truly in parallel. Work is split only when it is large enough to pay
for the threads.

The threads are the module's own, kept for the process's life. They are daemon threads, so
no thread is ever left for the interpreter to wait for on its way out, and a call that is
interrupted (Ctrl-C, SIGTERM: an exception raised in the calling thread while it waits)
lets the blocks already running finish and drops the rest before the exception goes on:
when `for_blocks` returns or raises, none of its work is running. (A ThreadPoolExecutor
interrupted while it starts a thread leaves a thread the interpreter waits for at exit
forever.)
"""

from __future__ import annotations

import os
import queue
import threading

MIN_ROWS = 65536  # texels: below this, one thread is faster
CHUNK = 32768  # texels per block when working in chunks: temporaries stay small and cached

_tasks: queue.SimpleQueue = queue.SimpleQueue()  # a call's blocks, once per helper thread
_threads: list[threading.Thread] = []
_start_lock = threading.Lock()
_local = threading.local()  # .helper: this thread is one of ours


def workers() -> int:
    """Threads to use: the cores this process may run on, at most 8 (VR_THREADS overrides).

    Returns
    -------
    int
    """
    env = os.environ.get("VR_THREADS")
    if env and env.isdigit() and int(env) > 0:
        return int(env)
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, 8))


class _Blocks:
    """One call's blocks, taken in turn by the threads: how many started and finished, the
    first error, and whether the caller stopped waiting (then no further block starts)."""

    def __init__(self, fn, bounds: list[int]):
        self.fn = fn
        self.bounds = bounds
        self.count = len(bounds) - 1
        self.started = 0
        self.finished = 0
        self.error: BaseException | None = None
        self.stopped = False
        self.lock = threading.Lock()
        self.done = threading.Event()

    def work(self) -> None:
        """Run blocks until none is left to start (a helper thread's turn)."""
        while (i := self._take()) is not None:
            try:
                self.fn(self.bounds[i], self.bounds[i + 1])
            except BaseException as exc:  # handed to the caller, which raises it
                self._finish(exc)
            else:
                self._finish(None)

    def stop(self) -> None:
        """No further block starts; `done` is set once the running ones have finished."""
        with self.lock:
            self.stopped = True
            self._check()

    def wait_out(self) -> None:
        """Stop, and wait for the blocks running now. A second interrupt while waiting
        changes nothing: the first is on its way."""
        while True:
            try:
                self.stop()
                self.done.wait()
                return
            except KeyboardInterrupt:
                continue

    def _take(self) -> int | None:
        with self.lock:
            if self.stopped or self.error is not None or self.started == self.count:
                return None
            self.started += 1
            return self.started - 1

    def _finish(self, error: BaseException | None) -> None:
        with self.lock:
            self.finished += 1
            if self.error is None:
                self.error = error
            self._check()

    def _check(self) -> None:  # under the lock
        ending = self.stopped or self.error is not None or self.started == self.count
        if ending and self.finished == self.started:
            self.done.set()


def _forget_threads() -> None:
    """In a forked child (the study's and a farm's worker pools fork): only the forking
    thread lives on, so start afresh — new threads, queue and lock, when first needed."""
    global _tasks, _start_lock
    _tasks = queue.SimpleQueue()
    _start_lock = threading.Lock()
    _threads.clear()


if hasattr(os, "register_at_fork"):  # POSIX
    os.register_at_fork(after_in_child=_forget_threads)


def _serve(tasks: queue.SimpleQueue) -> None:
    _local.helper = True
    while True:
        tasks.get().work()


def _ensure_threads(n: int) -> None:
    with _start_lock:
        while len(_threads) < n:
            thread = threading.Thread(
                target=_serve, args=(_tasks,), name=f"vr_{len(_threads)}", daemon=True
            )
            thread.start()
            _threads.append(thread)


def for_blocks(fn, rows: int, min_rows: int = MIN_ROWS, max_rows: int | None = None) -> None:
    """Call a function over consecutive blocks of rows, in parallel.

    With `max_rows` the blocks outnumber the threads, which take them in turn: a caller on large
    arrays keeps its temporaries small (neither fresh memory nor out of cache).

    Parameters
    ----------
    fn : callable
        ``fn(start, stop)``, called once per block; the blocks cover range(rows).
    rows : int
    min_rows : int, optional
        The fewest rows a block gets.
    max_rows : int, optional
        The most rows a block gets.

    Raises
    ------
    Exception
        The first error a block raised, once no block runs.
    """
    n = min(workers(), max(1, rows // min_rows))
    count = n if max_rows is None else max(n, -(-rows // max_rows))
    if count == 1:
        fn(0, rows)
        return
    if n == 1 or getattr(_local, "helper", False):  # one thread, or inside a block already
        for i in range(count):
            fn(rows * i // count, rows * (i + 1) // count)
        return
    blocks = _Blocks(fn, [rows * i // count for i in range(count + 1)])
    try:
        _ensure_threads(n)
        for _ in range(n):
            _tasks.put(blocks)
        blocks.done.wait()
    except BaseException:  # Ctrl-C or SIGTERM while waiting: nothing of ours keeps running
        blocks.wait_out()
        raise
    if blocks.error is not None:
        raise blocks.error


def chunks(count: int, size: int = 32768):
    """(start, stop) of consecutive blocks of `size` rows: per-texel work on large maps in
    blocks keeps its temporaries small (cached, not fresh memory)."""
    return ((a, min(a + size, count)) for a in range(0, count, size))
