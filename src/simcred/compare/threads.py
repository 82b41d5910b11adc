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


def in_threads(work: Callable[[int], T], pieces: Iterable[int]) -> list[T]:
    """``[work(piece) for piece in pieces]``, on :func:`thread_count` threads (in order on one);
    the first exception is raised."""
    pieces = list(pieces)
    threads = min(thread_count(), len(pieces))
    if threads <= 1:
        return [work(piece) for piece in pieces]
    with ThreadPoolExecutor(threads) as pool:
        return list(pool.map(work, pieces))


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
