"""Where work runs: in-process, or on Dask (a local cluster or an existing scheduler).

Results never depend on where they were computed: every task derives its randomness from its own
``SeedSequence`` stream, and results come back in task order.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from types import MappingProxyType
from typing import Any, TypeVar

from simcred.errors import OptionError, SimcredError
from simcred.limits import check_count

T = TypeVar("T")
R = TypeVar("R")
#: Wraps an iterable of ``total`` items, e.g. in a progress bar.
Progress = Callable[[Iterable[T], int], Iterable[T]]

#: The ``shared_values`` of the :meth:`Engine.map` call whose task is running. A context
#: variable, set around each task and reset after it: a ``map`` inside a task (nested) sees its
#: own values and gives the outer task its values back (a module-level dict was overwritten).
_SHARED: ContextVar[Mapping[str, Any]] = ContextVar("simcred_shared", default=MappingProxyType({}))


def shared(key: str) -> Any:
    """A value given to every task of the running :meth:`Engine.map` call through
    ``shared_values``."""
    try:
        return _SHARED.get()[key]
    except KeyError:
        raise KeyError(f"no shared value {key!r} in this map call") from None


def _run_task(item: Any, task: Callable, values: Mapping[str, Any]) -> Any:
    token = _SHARED.set(MappingProxyType(dict(values)))  # references: values are not copied
    try:
        return task(item)
    finally:
        _SHARED.reset(token)


class Engine:
    """In-process execution; :class:`DaskEngine` distributes the same calls."""

    #: Whether tasks run in other processes (then results held where they were computed save
    #: transfers; in-process they would only add up in memory).
    distributed = False

    def map(self, task: Callable[[T], R], items: Sequence[T], *,
            shared_values: dict[str, Any] | None = None,
            progress: Progress | None = None,
            on_result: Callable[[int, R], None] | None = None,
            near: Sequence[Any] | None = None) -> list[R]:
        """``[task(item) for item in items]``; ``shared_values`` are read with :func:`shared`;
        ``on_result(index, result)`` is called as each task finishes (in any order); ``near``:
        as :meth:`keep` takes it."""
        values = shared_values or {}
        results = []
        for index in (progress(range(len(items)), len(items)) if progress else range(len(items))):
            results.append(_run_task(items[index], task, values))
            if on_result is not None:
                on_result(index, results[-1])
        return results

    def keep(self, task: Callable[[T], R], items: Sequence[T],
             near: Sequence[Any] | None = None) -> list[Any]:
        """``task(item)`` for every item, each result left where it was computed.

        Returns handles: placed in the items of a later :meth:`map` (alone or inside a tuple), a
        handle stands for its result. In-process a handle is the result itself; on Dask it is a
        future, so a result is computed once, on one worker, and travels only to the workers
        whose tasks hold its handle (not to every worker, as ``shared_values`` do).

        ``near[k]``: a handle, or a tuple of handles, where item ``k`` should run (next to its
        large inputs, which then do not move): on Dask on a worker that holds one of them, the
        items spread evenly over those workers; a preference that a dead worker's absence
        overrides. The handles must stand for results that exist or will (they are waited for).
        """
        return [_run_task(item, task, {}) for item in items]

    def put(self, values: Sequence[Any]) -> list[Any]:
        """Handles of ``values``, as :meth:`keep` returns (on Dask: each value sent to one
        worker, round robin)."""
        return list(values)

    def fetch(self, handles: Sequence[Any]) -> list[Any]:
        """The results that :meth:`keep` handles stand for, here."""
        return list(handles)

    def holders(self, handles: Sequence[Any]) -> list[str | None]:
        """Per handle the worker that holds its result (the first by name where several do),
        waiting for it; None in-process."""
        return [None] * len(handles)

    def close(self) -> None:
        pass


#: Environment of local Dask workers: one BLAS thread each, as Dask's default, but without its
#: MALLOC_TRIM_THRESHOLD_=65536, which makes our many short-lived numpy temporaries 1.5x slower.
WORKER_ENVIRON = {"OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1}


class DaskEngine(Engine):
    """Tasks on Dask: a ``LocalCluster`` of ``workers`` processes, or the scheduler at an address.

    Large shared inputs are scattered once to every worker, not shipped with each task.
    """

    distributed = True

    def __init__(self, workers: int | None = None, scheduler: str | None = None) -> None:
        import dask
        from dask.distributed import Client, LocalCluster

        self._cluster = None
        if scheduler is not None:
            self.client = _connect(Client, scheduler)
        else:
            with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENVIRON,
                                  "distributed.scheduler.work-stealing": False}):
                self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                             processes=True, dashboard_address=None)
            self.client = Client(self._cluster)

    def map(self, task, items, *, shared_values=None, progress=None, on_result=None,
            near=None):
        from dask.distributed import as_completed

        [values] = self.client.scatter([shared_values or {}], broadcast=True, hash=False)
        futures = self._submit(task, items, values, near)
        position = {future.key: index for index, future in enumerate(futures)}
        done = as_completed(futures)
        with _worker_deaths():
            for future in (progress(done, len(futures)) if progress else done):
                if on_result is not None:
                    on_result(position[future.key], future.result())
            return self.client.gather(futures)

    def keep(self, task, items, near=None):
        # not waited for: a later map's tasks start as soon as their handles' results exist,
        # and a failed task's error is raised where its result (or a task using it) is fetched
        return self._submit(task, items, {}, near)

    def _submit(self, task, items, values, near):
        keys = _keys(task, len(items))
        if near is None:
            return self.client.map(_run_task, items, task=task, values=values, key=keys)
        return [self.client.submit(_run_task, item, task=task, values=values, key=key,
                                   workers=where, allow_other_workers=True)
                for item, key, where in zip(items, keys, self._placements(near), strict=True)]

    def _placements(self, near):
        """Per item one worker holding one of its handles (None: none holds them), the
        fewest items first. Dask's own placement weighs a large input's transfer against
        queues of tasks whose durations it does not know yet, and its work stealing moves
        them after: both copied sets to most workers (measured, docs/benchmarks.md)."""
        groups = [h if isinstance(h, tuple) else (h,) for h in near]
        holders = self._who_has(list({h.key: h for g in groups for h in g}.values()))
        options = [sorted({w for h in g for w in holders.get(h.key, ())}) for g in groups]
        chosen = balanced(options)
        return [None if w is None else [w] for w in chosen]

    def put(self, values):
        return self.client.scatter(list(values), hash=False)

    def fetch(self, handles):
        with _worker_deaths():
            return self.client.gather(list(handles))

    def holders(self, handles):
        held = self._who_has(list(handles))
        return [min(held.get(h.key, ()), default=None) for h in handles]

    def _who_has(self, handles: list) -> dict:
        """``{key: workers holding it}`` of ``handles``, once their results exist."""
        from dask.distributed import wait

        wait(handles)
        return self.client.who_has(handles)

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


class Checkpointed(Engine):
    """Another engine whose finished tasks are kept in a store, so a rerun recomputes only the
    missing ones (``simcred ... --resume``).

    The ``k``-th :meth:`map` call of a job keeps task ``i``'s result (pickled) under the key
    ``map<k>-<i>``: a job that makes the same calls in the same order (the same command with the
    same options and inputs, which the store's manifest enforces) finds its finished tasks again.
    Results are the same objects an uninterrupted run computes, so the outputs are byte for byte
    the same. The store is a :class:`simcred.outputs.Checkpoint` in the job's own partial output
    (pickles: resume only outputs you made).
    """

    def __init__(self, runner: Engine, store: Any) -> None:
        self.runner, self.store = runner, store
        self.calls = self.done = self.total = 0

    @property
    def distributed(self) -> bool:
        return self.runner.distributed

    def map(self, task, items, *, shared_values=None, progress=None, on_result=None,
            near=None):
        import pickle

        keys = [f"map{self.calls:03d}-{i:06d}" for i in range(len(items))]
        self.calls += 1
        results = {i: pickle.loads(self.store.load(key))  # noqa: S301 (our own checkpoint)
                   for i, key in enumerate(keys) if key in self.store}
        missing = [i for i in range(len(items)) if i not in results]
        self.total, self.done = len(items), len(results)

        def save(j: int, result: Any) -> None:
            self.store.save(keys[missing[j]], pickle.dumps(result, protocol=5))
            self.done += 1
            if on_result is not None:
                on_result(missing[j], result)

        computed = self.runner.map(task, [items[i] for i in missing], shared_values=shared_values,
                                   progress=progress, on_result=save,
                                   near=None if near is None else [near[i] for i in missing])
        results.update(zip(missing, computed, strict=True))
        return [results[i] for i in range(len(items))]

    def keep(self, task, items, near=None):
        return self.runner.keep(task, items, near)  # handles are not kept across runs

    def put(self, values):
        return self.runner.put(values)

    def fetch(self, handles):
        return self.runner.fetch(handles)

    def holders(self, handles):
        return self.runner.holders(handles)

    def close(self) -> None:
        self.runner.close()


def _keys(task: Callable, n: int) -> list[str]:
    """Unique task keys named after the task's function (``_compare_pair-<token>-<i>``), so
    Dask's dashboard and task stream say what runs."""
    import uuid

    token = uuid.uuid4().hex
    return [f"{getattr(task, '__qualname__', 'task')}-{token}-{i}" for i in range(n)]


def balanced(options: Sequence[Sequence[str]]) -> list[str | None]:
    """One of its options per item (None where it has none), the counts per option as even as
    moves of one item at a time make them: greedy, then any item moved to a less loaded option
    while that lowers the spread (each move lowers the sum of squared counts, so it ends)."""
    load: dict[str, int] = {}
    chosen: list[str | None] = []
    for opts in options:
        best = min(opts, key=lambda w: load.get(w, 0)) if opts else None
        if best is not None:
            load[best] = load.get(best, 0) + 1
        chosen.append(best)
    moved = True
    while moved:
        moved = False
        for k, opts in enumerate(options):
            if not opts:
                continue
            best = min(opts, key=lambda w: load.get(w, 0))
            if load.get(best, 0) + 1 < load[chosen[k]]:
                load[chosen[k]] -= 1
                load[best] = load.get(best, 0) + 1
                chosen[k], moved = best, True
    return chosen


@contextmanager
def _worker_deaths() -> Iterator[None]:
    """Dask's ``KilledWorker`` (a task's workers kept dying) as one :class:`EngineError` line."""
    try:
        yield
    except Exception as exc:
        if type(exc).__name__ != "KilledWorker":
            raise
        raise EngineError(f"Dask workers died {ALLOWED_FAILURES + 1} times running one task "
                          f"({exc}); the task may need more memory than a worker has") from None


class EngineError(SimcredError):
    """The distributed run cannot go on (no scheduler there, workers keep dying)."""


#: Seconds to wait for a scheduler at ``--scheduler`` before giving up with one line.
CONNECT_TIMEOUT_S = 3
#: Dask's ``distributed.scheduler.allowed-failures``: a task whose worker died is run again on
#: another worker this often (so one dying worker costs time, not results) before giving up.
ALLOWED_FAILURES = 3


def _connect(client_class: type, scheduler: str) -> Any:
    """A client of the scheduler at ``scheduler``, or one line saying why there is none.

    The address is parsed, and a TCP scheduler's port probed with a plain socket, before Dask
    starts its event loop: a malformed or unreachable address then costs no Dask machinery.
    """
    import dask

    _probe(scheduler)
    try:
        with dask.config.set({"distributed.comm.timeouts.connect": f"{CONNECT_TIMEOUT_S}s"}):
            return client_class(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise _unreachable(scheduler, exc) from None


def _probe(scheduler: str) -> None:
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        protocol, location = parse_address(scheduler)
        if protocol not in ("tcp", "tls"):
            return
        host, port = parse_host_port(location)
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S).close()
    except (OSError, ValueError, TypeError) as exc:
        raise _unreachable(scheduler, exc) from None


def _unreachable(scheduler: str, exc: BaseException) -> EngineError:
    reason = " ".join(str(exc).split()) or type(exc).__name__
    return EngineError(f"--scheduler {scheduler}: no Dask scheduler reachable ({reason[:200]})")


@contextmanager
def engine(workers: int | None = None, scheduler: str | None = None) -> Iterator[Engine]:
    """In-process without ``workers`` or ``scheduler``; else Dask, closed on exit."""
    if workers is not None:
        check_count(workers, "workers", "--workers")
    if workers is not None and scheduler is not None:
        raise OptionError("give either workers (a local Dask cluster) or a scheduler address")
    runner = Engine() if workers is None and scheduler is None else DaskEngine(workers, scheduler)
    try:
        yield runner
    finally:
        runner.close()
