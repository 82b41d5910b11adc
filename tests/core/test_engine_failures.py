"""Distributed runs that fail cleanly: unreachable scheduler, a dying worker, a raising task."""

from __future__ import annotations

import os
import re
import signal
import threading
import time

import pytest

from simcred.engine import EngineError, engine
from simcred.errors import SimcredError


def slow_square(i: int) -> int:
    time.sleep(0.2)
    return i * i


def bad_run(i: int) -> int:
    if i == 3:
        raise SimcredError(f"run {i}: bad input")
    return i


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1", "not an address", "tcp://[::1"])
def test_unreachable_scheduler_is_one_line_within_the_timeout(address):
    start = time.perf_counter()
    expected = f"--scheduler {re.escape(address)}: no Dask scheduler"
    with pytest.raises(EngineError, match=expected) as info, engine(scheduler=address):
        pass
    assert "\n" not in str(info.value)
    assert time.perf_counter() - start < 30  # bounded (the connect timeout is 5 s)


@pytest.mark.slow
def test_a_worker_killed_mid_campaign_changes_no_result():
    items = list(range(24))
    with engine(workers=2) as runner:
        pids = runner.client.run(os.getpid)

        def kill_one() -> None:
            time.sleep(1.0)
            os.kill(next(iter(pids.values())), signal.SIGKILL)

        killer = threading.Thread(target=kill_one)
        killer.start()
        results = runner.map(slow_square, items)
        killer.join()
        assert runner.client.run(os.getpid) != pids  # the nanny started a new worker
    assert results == [i * i for i in items]


@pytest.mark.slow
def test_a_raising_task_reaches_the_caller_as_its_own_error():
    with engine(workers=2) as runner, pytest.raises(SimcredError, match="run 3: bad input"):
        runner.map(bad_run, list(range(6)))
