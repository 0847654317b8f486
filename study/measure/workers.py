"""A case's column work spread over the host's cores: one thread pool per process.

The columns of a case (:mod:`study.measure.batched`, the rows of :func:`study.measure.case.run_case`) are numpy and
scipy over whole frames: reductions, ``uniform_filter``, FFTs and partitions, which release the GIL, so threads run
them side by side. Only numpy work is handed to the pool: Dr.Jit (FLIP on the GPU, the outcome classes) stays on the
caller's thread. Every task computes what it would compute alone (no shared random state: the resampling draws
from generators of their own seeds; the memo of :func:`study.stats.region.kept` is locked), so the values do not
depend on how many threads run them.

Threads: ``$STUDY_THREADS`` (a sweep worker's share of the cores, :func:`study.harness.runner._limit_threads`),
else half the cores (at least 2), at most :data:`MOST`; 1 runs every task inline, on the caller's thread. Half:
the case's own thread (renders, traces, Dr.Jit's launches) shares the cores and the GIL with the pool. On one H100
host (16 cores; reports/performance/determinism-gpu.txt) fig4 at 256² on a warm render cache took 30.0 s with 8
threads, 34.1 s with 16 and 46.6 s with 1. What a pool task submits runs
inline, and a task waits only on tasks submitted before it: the queue is first in, first out, so those have
started, and the pool never waits on itself."""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

#: The most threads one process gives its columns.
MOST = 16

_pool: ThreadPoolExecutor | None = None
_lock = threading.Lock()


def threads() -> int:
    """How many threads the columns use in this process."""
    n = int(os.environ.get("STUDY_THREADS") or 0) or max(2, (os.cpu_count() or 1) // 2)
    return max(1, min(n, MOST))


def _get() -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(threads(), thread_name_prefix="study-columns")
        return _pool


def here(fn, /, *args, **kwargs) -> Future:
    """``fn(*args, **kwargs)`` on this thread, as a finished future (its exception kept for ``result()``)."""
    done: Future = Future()
    try:
        done.set_result(fn(*args, **kwargs))
    except BaseException as err:  # noqa: BLE001 - handed to whoever asks for the result
        done.set_exception(err)
    return done


def submit(fn, /, *args, **kwargs) -> Future:
    """``fn(*args, **kwargs)`` on the pool (:func:`here`, with one thread or from inside a pool task)."""
    if threads() == 1 or threading.current_thread().name.startswith("study-columns"):
        return here(fn, *args, **kwargs)
    return _get().submit(fn, *args, **kwargs)
