"""Distance matrix (serial = worker processes, stopped pairs) and the figures."""

import json

import numpy as np
import pytest

from helpers import ar_set
from simcred.compare import compare, matrix
from simcred.errors import TraceSetError
from simcred.report.figures import _project, distance_heatmap, state_map
from simcred.traces import TraceSet


@pytest.fixture(scope="module")
def three_sets():
    rng = np.random.default_rng(5)
    return [ar_set(rng, runs=60, phi=phi, source=f"s{i}") for i, phi in
            enumerate((0.7, 0.7, -0.7))]


def test_matrix_entries_equal_pairwise_compare(three_sets):
    result = matrix(three_sets, features=["x", "y"], bins=4, test="permutation",
                    permutations=99, seed=8)
    for (i, j), comparison in zip(result.pairs, result.comparisons, strict=True):
        direct = compare(three_sets[i], three_sets[j], features=["x", "y"], bins=4,
                         test="permutation", permutations=99, seed=8)
        assert comparison.to_json() == direct.to_json()
        assert result.distances[i, j] == result.distances[j, i] == direct.distance
    assert np.all(np.diag(result.distances) == 0)


def test_matrix_is_identical_on_worker_processes(three_sets):
    options = dict(features=["x", "y"], bins=4, test="permutation", permutations=99, seed=3)
    serial = matrix(three_sets, **options)
    parallel = matrix(three_sets, workers=2, **options)
    assert serial.to_json() == parallel.to_json()


def test_matrix_of_files_is_identical_for_every_worker_count(three_sets, tmp_path,
                                                              monkeypatch):
    """The run-level matrix of files is byte-identical in-process and on 1 or 2 workers, and on
    workers the client never reads a file (the workers read their own sets)."""
    from simcred.engine import DaskEngine

    paths = []
    for k, traces in enumerate(three_sets):
        paths.append(tmp_path / f"s{k}.parquet")
        traces.write(paths[-1])
    options = dict(features=["x", "y"], bins=4, permutations=49, seed=3)
    serial = matrix(paths, **options).to_json()

    def no_reading_here(*_args, **_kwargs):
        raise AssertionError("the client read a trace set")

    monkeypatch.setattr(TraceSet, "read", classmethod(no_reading_here))
    (tmp_path / "broken.parquet").write_text("not parquet")
    for workers in (1, 2):
        runner = DaskEngine(workers=workers)
        try:
            assert matrix(paths, runner=runner, **options).to_json() == serial
            with pytest.raises(TraceSetError, match="broken.parquet: unreadable Parquet"):
                matrix([*paths, tmp_path / "broken.parquet"], runner=runner, **options)
        finally:
            runner.close()


def test_stopped_pairs_are_null_and_empty(tmp_path):
    rng = np.random.default_rng(2)
    a, b = (ar_set(rng, runs=200, phi=0.5) for _ in range(2))
    far = TraceSet.from_runs([{**a.run(i), "x": a.run(i)["x"] + 50} for i in range(200)])
    result = matrix([a, b, far], names=["a", "b", "far"], features=["x", "y"], bins=4,
                    test="bound")
    assert np.isnan(result.distances[0, 2]) and np.isnan(result.distances[2, 1])
    doc = json.loads(result.to_json())
    assert doc["distances"][0][2] is None
    assert result.to_csv().splitlines()[1].endswith(",")
    assert distance_heatmap(result, tmp_path / "m.png").stat().st_size > 5_000


def test_projection_sums_counts_and_flags_any_rejection():
    status = np.zeros((2, 3, 2), dtype=np.int8)
    status[0, 1, 0], status[0, 1, 1] = 1, 2     # kept + rejected -> rejected
    status[1, 2, 1] = 3                         # untestable only
    status[1, 0, 0] = 1
    m = np.arange(12).reshape(2, 3, 2)
    grid = _project({"status": status, "m": m, "n": 2 * m}, (0, 1))
    assert grid["status"].tolist() == [[0, 2, 0], [1, 0, 3]]
    np.testing.assert_array_equal(grid["m"], m.sum(axis=2))
    swapped = _project({"status": status, "m": m, "n": 2 * m}, (1, 0))
    np.testing.assert_array_equal(swapped["m"], m.sum(axis=2).T)


@pytest.mark.parametrize("features", [["x"], ["x", "y"], ["x", "y", "z"]])
def test_state_map_draws_one_two_and_three_features(features, tmp_path):
    rng = np.random.default_rng(1)
    runs = [{"t": np.arange(20.0), "x": rng.normal(size=20), "y": rng.normal(size=20),
             "z": rng.normal(size=20)} for _ in range(30)]
    a = TraceSet.from_runs(runs[:15])
    b = TraceSet.from_runs(runs[15:])
    result = compare(a, b, features=features, bins=3)
    assert state_map(result, tmp_path / "map.png").stat().st_size > 10_000
