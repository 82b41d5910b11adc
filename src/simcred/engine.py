"""Where work runs: in-process, or on local worker processes, in a deterministic order.

Results never depend on where they were computed: every task derives its randomness from its own
``SeedSequence`` stream, and results come back in task order.
"""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")
#: Wraps an iterable of ``total`` items, e.g. in a progress bar.
Progress = Callable[[Iterable[T], int], Iterable[T]]

_shared: dict[str, Any] = {}


def shared(key: str) -> Any:
    """A value given to every worker once, through :func:`map_tasks`'s ``shared``."""
    return _shared[key]


def _install(values: dict[str, Any]) -> None:
    _shared.clear()
    _shared.update(values)


def map_tasks(
    task: Callable[[T], R],
    items: Sequence[T],
    *,
    workers: int | None = None,
    shared_values: dict[str, Any] | None = None,
    progress: Progress | None = None,
) -> list[R]:
    """``[task(item) for item in items]``, serially or on ``workers`` local processes.

    ``shared_values`` are installed once per worker (inherited without copying where the platform
    forks) and read by the task with :func:`shared`; large inputs go there, not into ``items``.
    """
    values = shared_values or {}
    if not workers or workers <= 1 or len(items) <= 1:
        _install(values)
        results: Iterable[R] = map(task, items)
        return list(progress(results, len(items)) if progress else results)
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context(method),
                             initializer=_install, initargs=(values,)) as pool:
        results = pool.map(task, items)
        return list(progress(results, len(items)) if progress else results)
