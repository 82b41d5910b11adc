"""Independent pieces of one comparison on the process's cores, in threads.

Only for work whose result does not depend on the order the pieces finish in (each piece writes
its own part of an output; integer-valued sums), and whose heavy steps release the GIL (numpy's
ufuncs, scipy's sparse products, ``np.take``). The number of threads is the cores this process
may use, at most ``SIMCRED_MAX_THREADS`` (:mod:`simcred.limits`), and 1 where the environment
caps the numerical libraries at one thread (simcred's Dask workers: one comparison per core
already).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any, TypeVar

import numpy as np

from simcred.limits import LIMITS

T = TypeVar("T")


def thread_count() -> int:
    """Cores this process may use, at most ``SIMCRED_MAX_THREADS``; 1 where ``OMP_NUM_THREADS``
    or ``OPENBLAS_NUM_THREADS`` is 1."""
    if any(os.environ.get(name) == "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")):
        return 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else \
        (os.cpu_count() or 1)
    return min(cores, LIMITS["threads"].value)


#: Tasks per thread that :func:`in_threads` cuts the pieces into (consecutive runs of pieces:
#: thousands of small states cost one task each otherwise).
TASKS_PER_THREAD = 16


def in_threads(work: Callable[[int], T], pieces: Iterable[int]) -> list[T]:
    """``[work(piece) for piece in pieces]``, on :func:`thread_count` threads (in order on one),
    as at most :data:`TASKS_PER_THREAD` tasks a thread of consecutive pieces; the first
    exception is raised."""
    pieces = list(pieces)
    threads = min(thread_count(), len(pieces))
    if threads <= 1:
        return [work(piece) for piece in pieces]
    cuts = np.linspace(0, len(pieces), min(len(pieces), TASKS_PER_THREAD * threads) + 1)
    runs = [pieces[int(lo):int(hi)] for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]
    with ThreadPoolExecutor(threads) as pool:
        done = list(pool.map(lambda run: [work(piece) for piece in run], runs))
    return [result for run in done for result in run]


@contextmanager
def beside(work: Callable[..., T], *args: Any) -> Iterator[Future]:
    """``work(*args)`` in a second thread while the ``with`` block runs (on one thread: before
    the block); the block reads it with ``.result()``."""
    if thread_count() <= 1:
        done: Future = Future()
        done.set_result(work(*args))
        yield done
        return
    with ThreadPoolExecutor(1) as pool:
        yield pool.submit(work, *args)
