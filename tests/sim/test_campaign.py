"""Campaigns: a run's result depends on (seed, run index, parameters) only."""

import numpy as np
import pytest

from simcred.cli import run
from simcred.seeds import derive_seed
from simcred.sim.campaign import Campaign
from simcred.sim.experiments import simplecar_sweep
from simcred.traces import TraceSet

PARAMS = {"lam": 0.9, "dt": 1.0, "duration": 10.0}


def test_run_is_the_same_alone_and_in_a_batch():
    batch = simplecar_sweep.simulate(range(20), 5, **PARAMS)
    alone = simplecar_sweep.simulate([13], 5, **PARAMS)
    np.testing.assert_array_equal(alone.values, batch.values[batch.offsets[13]:batch.offsets[14]])
    assert alone.run_ids == ("run_00013",)


@pytest.mark.parametrize("chunk_size", [1, 7, 64])
def test_chunking_does_not_change_the_trace_set(chunk_size):
    whole = Campaign(simplecar_sweep.simulate, 40, 3, PARAMS, chunk_size=40).run()
    chunked = Campaign(simplecar_sweep.simulate, 40, 3, PARAMS, chunk_size=chunk_size).run()
    assert chunked.equals(whole) and chunked.digest() == whole.digest()


def test_serial_and_dask_give_byte_identical_trace_sets(tmp_path):
    campaign = Campaign(simplecar_sweep.simulate, 60, 11, PARAMS, chunk_size=8)
    serial = campaign.run()
    distributed = campaign.run(workers=2)
    assert distributed.equals(serial)
    serial.write(tmp_path / "serial.parquet")
    distributed.write(tmp_path / "dask.parquet")
    for name in ("a", "b"):
        (serial if name == "a" else distributed).write(tmp_path / name)
    assert all((tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()
               for f in ("run_00000.csv", "run_00059.csv", "traceset.json"))


def test_different_seeds_and_keys_give_different_campaigns():
    assert len({derive_seed(0, k) for k in range(100)} | {derive_seed(1, 0)}) == 101
    a = Campaign(simplecar_sweep.simulate, 5, 1, PARAMS).run()
    b = Campaign(simplecar_sweep.simulate, 5, 2, PARAMS).run()
    assert not np.array_equal(a.values, b.values)


def test_tau_and_start_follow_the_papers_laws():
    tau, start = simplecar_sweep.draw_runs(range(4000), 0, 0.9)
    assert tau.min() >= 0.89 and tau.max() <= 0.9
    assert abs(start.std() - simplecar_sweep.START_STD) < 0.3
    assert abs(start.mean()) < 0.5


def test_cli_simulate_simplecar_writes_a_trace_set(tmp_path):
    out = tmp_path / "sc.parquet"
    assert run(["--quiet", "simulate", "simplecar", "--lambda", "0.95", "--runs", "12",
                "--dt", "1", "--duration", "5", "--seed", "2", "--out", str(out)]) == 0
    traces = TraceSet.read(out)
    assert traces.n_runs == 12 and traces.signals == ("x", "y", "heading", "v")
    assert traces.metadata["lambda"] == 0.95


def test_cli_simulate_rejects_bad_options(tmp_path, capsys):
    assert run(["simulate", "simplecar", "--dt", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--dt must be in (0, inf), got 0" in capsys.readouterr().err
    assert run(["simulate", "simplecar", "--runs", "0", "--out", str(tmp_path / "x")]) == 2
    assert "runs must be at least 1" in capsys.readouterr().err
