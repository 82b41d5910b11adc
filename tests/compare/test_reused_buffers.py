"""Code paths that reuse buffers or write in place, against the straightforward computation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from simcred.compare import cluster_sums, conditional, transitions
from simcred.compare.cluster_sums import ClusterSums, Entries
from simcred.compare.design import Design, DesignKind, runs_design
from simcred.compare.scratch import std_columns
from simcred.compare.transitions import Transitions, _sorted_columns, adjusted, state_means


def _sets(rng, history, dtype):
    """Two sets of runs (values, time, offsets, codes) of uneven lengths, some too short."""
    parts = []
    for runs in (7, 5):
        lengths = rng.integers(1, 12, runs)
        offsets = np.r_[0, np.cumsum(lengths)]
        values = rng.normal(size=(offsets[-1], 3)).astype(dtype)
        time = np.cumsum(rng.uniform(0.1, 0.5, offsets[-1]))
        coded = np.maximum(lengths - (history - 1), 0)
        codes = rng.integers(0, 4, int(coded.sum()))
        parts.append((values, time, offsets, codes))
    return parts


def _literal(parts, unit_of_run, history, out_j, in_j):
    """Per transition, run by run: (state, unit, covariates, rate), sorted by (state, unit)."""
    rows, run = [], 0
    for values, time, offsets, codes in parts:
        code = 0
        for lo, hi in zip(offsets[:-1], offsets[1:], strict=True):
            for t in range(lo + history - 1, hi):
                if t + 1 < hi:
                    rate = (values[t + 1, out_j] - values[t, out_j]) / (time[t + 1] - time[t])
                    rows.append((codes[code], unit_of_run[run],
                                 np.r_[values[t], values[t + 1, in_j]], rate))
                code += 1
            run += 1
    state, unit = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    order = np.lexsort((unit, state))
    return (state[order], unit[order], np.array([r[2] for r in rows])[order],
            np.array([r[3] for r in rows])[order])


@pytest.mark.parametrize(("history", "inputs", "dtype", "fit_rows"),
                         [(1, [], np.float64, None), (2, ["c"], np.float64, 16),
                          (1, ["a"], np.float32, 16)])
def test_transitions_equal_a_run_by_run_construction(monkeypatch, history, inputs, dtype,
                                                     fit_rows):
    if fit_rows:  # the global fit in row chunks, its residual written in place
        monkeypatch.setattr(transitions, "FIT_ROWS", fit_rows)
    rng = np.random.default_rng(history)
    parts = _sets(rng, history, dtype)
    unit_of_run = rng.permutation(12)
    features = ["a", "b", "c"]
    out_j = [features.index(f) for f in features if f not in inputs]
    in_j = [features.index(f) for f in inputs]
    state, unit, covariates, rate = _literal(parts, unit_of_run, history, out_j, in_j)
    data = transitions.transitions(parts, unit_of_run, features, inputs, history)
    np.testing.assert_array_equal(data.state, state)
    np.testing.assert_array_equal(data.unit, unit)
    np.testing.assert_allclose(data.spread, rate.std(axis=0), rtol=1e-12)
    tol = 1e-9 if dtype == np.float64 else 1e-5  # float32 covariates: their moments' order
    np.testing.assert_allclose(data.residual, adjusted(state, covariates, rate), rtol=tol,
                               atol=tol)
    np.testing.assert_allclose(data.profile, state_means(state, rate - data.level), rtol=tol,
                               atol=tol)


def test_sorted_columns_are_exact_and_column_major():
    rng = np.random.default_rng(5)
    parts = _sets(rng, 1, np.float64)
    where, flat_rows, flat_values = [], [], []
    for values, time, offsets, _ in parts:
        rows = np.concatenate([np.arange(lo, hi - 1) for lo, hi in zip(offsets[:-1], offsets[1:],
                                                                        strict=True)])
        where.append((rows, time[rows + 1] - time[rows]))
        flat_rows.append(np.hstack([values[rows], values[rows + 1][:, [1]]]))
        flat_values.append((values[rows + 1][:, [0, 2]] - values[rows][:, [0, 2]])
                           / where[-1][1][:, None])
    order = rng.permutation(sum(len(r) for r, _ in where))
    covariates, rate = _sorted_columns([p[0] for p in parts], where, order, [0, 2], [1])
    assert covariates.flags.f_contiguous and rate.flags.f_contiguous
    np.testing.assert_array_equal(covariates, np.concatenate(flat_rows)[order])
    np.testing.assert_array_equal(rate, np.concatenate(flat_values)[order])


@pytest.mark.parametrize("rows", [1, 64, 150])
def test_side_mean_gap_equals_per_assignment_means(monkeypatch, rows):
    rng = np.random.default_rng(rows)
    assignments = rng.random((rows, 30)) < 0.4
    assignments[:, 0], assignments[:, 1] = True, False  # both sides never empty
    value = rng.normal(size=30)
    monkeypatch.setattr(conditional, "GAP_ROWS", 16)  # several batches, the last one short
    expected = [abs(value[z].mean() - value[~z].mean()) for z in assignments]
    np.testing.assert_allclose(conditional.side_mean_gap(assignments, value), expected,
                               rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("pairs", [False, True])
def test_dense_visits_give_the_sparse_visits_deviation(monkeypatch, pairs):
    rng = np.random.default_rng(11)
    units_a = 6
    cells = [(s, u) for s in range(5) for u in range(2 * units_a) if rng.random() < 0.6]
    state, unit = (np.repeat([cell[i] for cell in cells], 3) for i in (0, 1))
    data = Transitions(state, unit, rng.normal(size=(len(state), 2)), ("x", "y"),
                       np.ones(2))
    design = Design(DesignKind.PAIRS, "run_id", np.arange(2 * units_a), units_a,
                    tuple(f"u{i}" for i in range(2 * units_a))) if pairs \
        else runs_design(units_a, units_a)
    entries = Entries.of(data, design)
    keep = np.ones(entries.n_states, dtype=bool)
    weights = rng.poisson(1.0, (entries.n_clusters, 40)).astype(np.float64)  # zeros: undrawn
    out = {}
    for share, kind in ((0.0, np.ndarray), (2.0, sp.csr_matrix)):
        monkeypatch.setattr(cluster_sums, "VISITS_DENSE_SHARE", share)
        sums = ClusterSums.of(entries, keep)
        assert isinstance(sums.visits, kind)
        out[kind] = sums.deviation(weights)
    for name, value in out[np.ndarray].items():
        np.testing.assert_array_equal(value, out[sp.csr_matrix][name])


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("rows", [1, 9, 100_003])
def test_std_columns_is_numpys_std_bit_for_bit(order, rows):
    rng = np.random.default_rng(rows)
    values = np.asarray(rng.normal(size=(rows, 3)) * [0.1, 10.0, 1e4] + 7.0, order=order)
    scratch = np.empty_like(values)
    np.testing.assert_array_equal(std_columns(values, scratch), values.std(axis=0))
    np.testing.assert_array_equal(std_columns(values[::2]), values[::2].std(axis=0))  # new temp
    column = np.asfortranarray(values)[:, 1]
    assert std_columns(column, np.asfortranarray(scratch)[:, 1])[0] == column.std()
