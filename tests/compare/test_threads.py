"""The comparison's threads: the same answer on any number of them, the pieces' results in
order, the first error raised, and the thread count the environment allows."""

from __future__ import annotations

import numpy as np
import pytest

import response_designs as designs
from helpers import ar_set
from simcred.compare import compare, threads
from simcred.errors import OptionError


def test_results_in_order_and_first_error_raised(monkeypatch):
    monkeypatch.setattr(threads, "thread_count", lambda: 3)
    assert threads.in_threads(lambda i: i * i, range(20)) == [i * i for i in range(20)]

    def fail(i: int) -> int:
        if i in (4, 9):
            raise ValueError(f"piece {i}")
        return i

    with pytest.raises(ValueError, match="piece 4"):
        threads.in_threads(fail, range(12))


def test_thread_count_follows_the_environment(monkeypatch):
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "SIMCRED_MAX_THREADS"):
        monkeypatch.delenv(name, raising=False)
    cores = threads.thread_count()
    assert cores >= 1
    monkeypatch.setenv("SIMCRED_MAX_THREADS", "1")
    assert threads.thread_count() == 1
    monkeypatch.setenv("SIMCRED_MAX_THREADS", "0")
    with pytest.raises(OptionError, match="SIMCRED_MAX_THREADS"):
        threads.thread_count()
    monkeypatch.delenv("SIMCRED_MAX_THREADS")
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")  # a Dask worker: one comparison per core
    assert threads.thread_count() == 1


@pytest.mark.parametrize("case", ["paired", "grouped", "inputs", "large"])
def test_the_same_json_on_one_or_several_threads(monkeypatch, case):
    """Every threaded step (per-state sums, reorders, fits, unit variances) gives the bytes of
    the serial run; ``large`` has a global fit of several parts."""
    rng = np.random.default_rng(11)
    if case == "large":
        a, b = ar_set(rng, 1500, 0.5, length=200), ar_set(rng, 1500, 0.45, length=200)
        options = dict(pair_by="run_id", bins=6)
    else:
        d = {"paired": lambda: designs.defect(rng, "delay", runs=20),
             "grouped": lambda: designs.grouped(rng),
             "inputs": lambda: designs.leaders_split(rng)}[case]()
        a, b = d.a, d.b
        options = dict(features=list(d.features), inputs=list(d.inputs), pair_by=d.pair_by,
                       group_by=d.group_by, bins=4)
    written = []
    for count in (1, 3):
        monkeypatch.setattr(threads, "thread_count", lambda count=count: count)
        result = compare(a, b, test="response", permutations=99, seed=2, bootstrap=30,
                         margin=0.5 if case != "large" else None, **options)
        written.append(result.to_json())
    assert written[0] == written[1]
