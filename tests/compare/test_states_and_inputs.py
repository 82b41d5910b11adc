"""States on discrete data, history and time windows, sample periods, Parquet run labels."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from simcred.cli import run
from simcred.compare import compare
from simcred.compare.discretize import feature_edges
from simcred.compare.encoding import encode, state_space
from simcred.compare.resample import resample, sample_period
from simcred.errors import OptionError
from simcred.traces import TraceSet


def discrete_set(rng, runs=30, steps=25, dt=0.1):
    """lane ∈ {0, 1, 2}, braking ∈ {0, 1}, count ∈ {0..5}: all integer features."""
    out = []
    for _ in range(runs):
        out.append({"t": np.arange(steps) * dt,
                    "lane": rng.integers(0, 3, steps).astype(float),
                    "braking": rng.integers(0, 2, steps).astype(float),
                    "count": rng.integers(0, 6, steps).astype(float)})
    return TraceSet.from_runs(out)


@pytest.mark.parametrize("bins", [2, 3, 6, 10, 50])
def test_discrete_features_have_one_state_per_value_combination(bins):
    rng = np.random.default_rng(bins)
    a, b = discrete_set(rng), discrete_set(rng)
    result = compare(a, b, features="lane,braking", bins=bins, test="bound")
    lanes = min(3, bins) if bins >= 3 else 2
    assert result.space.shape == (lanes, 2)
    if bins >= 3:
        assert result.n_states == 6  # three lanes × a boolean: 6 distinct combinations
        pooled = np.vstack([a.features(["lane", "braking"]), b.features(["lane", "braking"])])
        assert len(np.unique(pooled, axis=0)) == result.n_states
        codes = result.space.encode(pooled)
        assert len(np.unique(codes)) == result.n_states  # every state is reachable


@pytest.mark.parametrize("bins", [3, 4, 6, 10])
def test_every_bin_holds_data_for_tied_and_integer_values(bins):
    rng = np.random.default_rng(0)
    for column in (rng.integers(0, 6, 500).astype(float),
                   np.r_[np.zeros(400), rng.normal(size=100)],   # a spike of ties + continuum
                   np.r_[np.zeros(90), np.ones(10)],             # a rare boolean
                   rng.poisson(1.5, 300).astype(float)):
        edges = feature_edges(column, bins)
        held = np.bincount(np.searchsorted(edges, column, side="right"),
                           minlength=len(edges) + 1)
        assert (held > 0).all(), (bins, edges, held)
        distinct = len(np.unique(column))
        assert len(edges) + 1 == (distinct if distinct <= bins else len(edges) + 1)
        assert len(edges) + 1 <= bins


def test_continuous_data_keeps_the_papers_edges():
    column = np.random.default_rng(1).normal(size=1000)
    expected = np.unique(np.quantile(column, np.arange(1, 10) / 10))
    np.testing.assert_array_equal(feature_edges(column, 10), expected)


def test_history_and_time_window_codes_match_literal():
    rng = np.random.default_rng(3)
    a = TraceSet.from_runs([{"t": np.arange(n) * 0.5, "x": rng.normal(size=n)}
                            for n in (5, 7, 4)])
    values, time, offsets = a.features(["x"]), a.time, a.offsets
    space = state_space([values], [time], [offsets], (3,), ("x",), history=2, time_bins=2)
    assert space.features == ("x[t-1]", "x", "window")
    encoded = encode(space, values, time, offsets, history=2, windowed=True)
    base = np.searchsorted(space.edges[0], values[:, 0], side="right")
    window_edges = space.edges[2]
    expected, lengths = [], []
    for lo, hi in zip(offsets[:-1], offsets[1:], strict=True):
        for t in range(lo + 1, hi):
            w = np.searchsorted(window_edges, time[t] - time[lo], side="right")
            expected.append(np.ravel_multi_index((base[t - 1], base[t], w), space.shape))
        lengths.append(hi - lo - 1)
    np.testing.assert_array_equal(encoded.codes, expected)
    np.testing.assert_array_equal(encoded.offsets, np.r_[0, np.cumsum(lengths)])


def test_bad_history_and_time_bins_are_one_line_errors(capsys, tmp_path):
    rng = np.random.default_rng(4)
    a = discrete_set(rng).write(tmp_path / "a")
    b = discrete_set(rng).write(tmp_path / "b.parquet")
    for args, expected in ((["--history", "0"], "history must be an integer >= 1"),
                           (["--time-bins", "1"], "time-bins must be an integer >= 2"),
                           (["--history", "40"], "needs at least 40"),
                           (["--multiplicity", "fwer", "--test", "bound"], "needs the run-level"),
                           (["--resample", "-1"], "resample period must be a positive number")):
        assert run(["compare", str(a), str(b), "-f", "lane", *args]) == 2, args
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1, err


def test_different_sample_periods_are_refused_or_resampled(capsys, tmp_path):
    rng = np.random.default_rng(5)
    fast = TraceSet.from_runs([{"t": np.arange(41) * 0.1, "x": np.sin(np.arange(41) * 0.1 + p)}
                               for p in rng.uniform(0, 6, 30)], source="fast")
    slow = TraceSet.from_runs([{"t": np.arange(21) * 0.2, "x": np.sin(np.arange(21) * 0.2 + p)}
                               for p in rng.uniform(0, 6, 30)], source="slow")
    assert sample_period(fast) == pytest.approx(0.1) and sample_period(slow) == pytest.approx(0.2)
    with pytest.raises(OptionError, match="sample periods differ: fast 0.1 s, slow 0.2 s"):
        compare(fast, slow, test="bound")
    paths = fast.write(tmp_path / "fast"), slow.write(tmp_path / "slow.parquet")
    assert run(["compare", *map(str, paths)]) == 2
    assert "--resample" in capsys.readouterr().err
    result = compare(fast, slow, resample=0.2, permutations=99, seed=0)
    assert result.options.resample == 0.2 and result.chain is not None


def test_resample_is_linear_interpolation():
    traces = TraceSet.from_runs([{"t": [0.0, 0.3, 1.0], "x": [0.0, 3.0, 10.0]},
                                 {"t": [1.0, 1.5, 2.05], "x": [2.0, 1.0, 0.0]}])
    out = resample(traces, 0.25)
    np.testing.assert_allclose(out.run(0)["t"], [0, 0.25, 0.5, 0.75, 1.0])
    np.testing.assert_allclose(out.run(0)["x"], [0, 2.5, 5.0, 7.5, 10.0])
    np.testing.assert_allclose(out.run(1)["t"], [1.0, 1.25, 1.5, 1.75, 2.0])
    np.testing.assert_allclose(out.run(1)["x"], np.interp(out.run(1)["t"], [1.0, 1.5, 2.05],
                                                          [2.0, 1.0, 0.0]))


def test_parquet_run_labels_round_trip_via_dictionary_codes(tmp_path):
    traces = TraceSet.from_runs([{"t": [0.0, 1.0], "x": [1.0, 2.0]}] * 3,
                                run_ids=["b", "a", "c"])
    path = traces.write(tmp_path / "s.parquet")
    assert pa.types.is_dictionary(pq.read_schema(path).field("run").type)
    assert TraceSet.read(path).equals(traces)
    # a plain string column with interleaved rows, as other tools write it
    table = pa.table({"run": ["r2", "r1", "r2", "r1"], "t": [0.0, 0.0, 1.0, 1.0],
                      "x": [5.0, 1.0, 6.0, 2.0]})
    pq.write_table(table, tmp_path / "plain.parquet")
    read = TraceSet.read(tmp_path / "plain.parquet")
    assert read.run_ids == ("r2", "r1")
    np.testing.assert_array_equal(read.column("x"), [5.0, 6.0, 1.0, 2.0])


def test_units_round_trip_and_mismatch(tmp_path):
    rng = np.random.default_rng(7)
    runs = [{"t": np.arange(10) * 0.1, "gap": rng.normal(20, 2, 10), "v": rng.normal(10, 1, 10)}
            for _ in range(12)]
    a = TraceSet.from_runs(runs[:6], metadata={"units": {"gap": "m", "v": "m/s"}}, source="a")
    b = TraceSet.from_runs(runs[6:], metadata={"units": {"v": "m/s"}}, source="b")
    for path in (tmp_path / "a", tmp_path / "a.parquet"):
        assert TraceSet.read(a.write(path)).units == {"gap": "m", "v": "m/s"}
    result = compare(a, b, features="gap,v", bins=3, permutations=19, seed=0)
    assert result.units == ("m", "m/s")
    assert '"units": [' in result.to_json()
    kmh = TraceSet.from_runs(runs[6:], metadata={"units": {"v": "km/h"}}, source="b")
    with pytest.raises(OptionError, match="unit mismatch for 'v': a has 'm/s', b has 'km/h'"):
        compare(a, kmh, features="gap,v", bins=3, test="bound")
    bad = TraceSet.from_runs(runs[6:], metadata={"units": ["m"]}, source="bad")
    with pytest.raises(ValueError, match="bad: metadata 'units' must map signal names"):
        compare(a, bad, features="gap,v", bins=3, test="bound")
