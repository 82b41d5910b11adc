"""The global fit's first-order influence on the shift (simcred.compare.fit_influence).

Oracles: the exact refit written out — a weighted least-squares fit per replicate, the residuals
rebuilt and the shift summed again — whose derivative in one cluster's weight at the sample is
``−a_c``; the normal equations (``Σ_c a_c = 0``); and the linearised replicates' spread against
the exact refit's on many replicates.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from simcred.compare.cluster_sums import ClusterSums, Entries
from simcred.compare.design import Design, DesignKind, runs_design
from simcred.compare.fit_influence import shift_fit_influence
from simcred.compare.transitions import Basis, Transitions, global_fit


def _paired(units_a: int) -> Design:
    return Design(DesignKind.PAIRS, "run_id", np.arange(2 * units_a), units_a,
                  tuple(f"A:{i}" for i in range(units_a)) + tuple(f"B:{i}" for i in range(units_a)))


def _data(seed: int, units: int, per_unit: int = 40) -> tuple[Transitions, np.ndarray]:
    """The transitions and the response before the fit: two response features whose level
    depends on two covariates, B's shifted; the covariates differ between the sides, so the fit
    takes part of the A–B difference."""
    rng = np.random.default_rng(seed)
    n = units * per_unit
    unit = np.repeat(np.arange(units), per_unit)
    side_b = unit >= units // 2
    x = rng.normal(size=(n, 2)) + 0.4 * side_b[:, None]
    state = (x[:, 0] > 0).astype(np.int64) + 2 * (x[:, 1] > 0.3)
    y = np.column_stack([x[:, 0] - 0.5 * x[:, 1] ** 2, 0.3 * x[:, 0] * x[:, 1]])
    y = y + rng.normal(size=(n, 2)) + rng.normal(size=(units, 2))[unit] + 0.2 * side_b[:, None]
    order = np.lexsort((unit, state))
    x, y = np.asfortranarray(x[order]), np.asfortranarray(y[order])
    state, unit = state[order], unit[order]
    level, fit = global_fit(x, y.copy(order="F"), state, unit >= units // 2)
    return Transitions(state, unit, level, ("p", "q"), level=level, fit=fit), y


def _exact_shift(data: Transitions, y: np.ndarray, design: Design, weights: np.ndarray
                 ) -> np.ndarray:
    """(features,) the shift of the replicate ``weights`` with the global fit refitted by
    weighted least squares (each transition weighted by its cluster's weight)."""
    entries = Entries.of(data, design)
    x = Basis.of(data.fit.rows, cubic=True).design(data.fit.rows)
    cluster = data.unit % design.units_a if entries.pairs else data.unit
    root = np.sqrt(weights[cluster])[:, None]
    fitted = x @ np.linalg.lstsq(x * root, y * root, rcond=None)[0]
    refitted = replace(data, level=np.asfortranarray(y - fitted))
    return ClusterSums.of(Entries.of(refitted, design), entries.entering()).deviation(
        weights[:, None])["shift"][:, 0]


def _fixed_shift(data: Transitions, design: Design, weights: np.ndarray) -> np.ndarray:
    entries = Entries.of(data, design)
    return ClusterSums.of(entries, entries.entering()).deviation(weights[:, None])["shift"][:, 0]


@pytest.mark.parametrize("paired", [True, False])
def test_influence_is_the_derivative_of_the_exact_refit(paired):
    data, y = _data(0, 16)
    design = _paired(8) if paired else runs_design(8, 8)
    entries = Entries.of(data, design)
    a = shift_fit_influence(data, entries, entries.entering())
    eps = 1e-5
    for c in (0, 3, entries.n_clusters - 1):
        weights = np.ones(entries.n_clusters)
        weights[c] += eps
        refit_part = (_exact_shift(data, y, design, weights) - _fixed_shift(data, design, weights))
        np.testing.assert_allclose(refit_part / eps, -a[c], rtol=1e-3, atol=1e-7)


def test_influence_sums_to_zero_and_is_absent_without_covariates():
    data, _ = _data(1, 20)
    design = _paired(10)
    entries = Entries.of(data, design)
    a = shift_fit_influence(data, entries, entries.entering())
    assert np.abs(a).max() > 1e-3  # the fit does take part of the difference here
    np.testing.assert_allclose(a.sum(axis=0), 0.0, atol=1e-10)
    assert shift_fit_influence(replace(data, fit=None), entries,
                               entries.entering()) is None


def test_linearised_replicates_spread_as_the_exact_refit():
    """Over 300 bootstrap replicates the linearised refit's standard deviation is within 5 % of
    the exact refit's, and closer to it than the fixed fit's where those two differ."""
    data, y = _data(2, 60, per_unit=30)
    design = _paired(30)
    entries = Entries.of(data, design)
    a = shift_fit_influence(data, entries, entries.entering())
    weights = design.resamples(300, np.random.default_rng(5))[:30]
    fixed = ClusterSums.of(entries, entries.entering()).deviation(weights)["shift"]
    linear = fixed - a.T @ weights
    exact = np.stack([_exact_shift(data, y, design, w) for w in weights.T], axis=1)
    sd_exact, sd_linear = exact.std(axis=1), linear.std(axis=1)
    np.testing.assert_allclose(sd_linear, sd_exact, rtol=0.05)
    assert (np.abs(sd_linear - sd_exact) <= np.abs(fixed.std(axis=1) - sd_exact)).all()


@pytest.mark.parametrize("chunk", [256, 2**18])
def test_global_fit_keeps_its_gram_and_per_state_side_sums(monkeypatch, chunk):
    """The fit's Gram matrix and per-(state, side) sums of its design rows, summed over row
    chunks, are those of the whole design written out."""
    from simcred.compare import transitions

    monkeypatch.setattr(transitions, "FIT_ROWS", chunk)
    data, y = _data(3, 12)
    x = Basis.of(data.fit.rows, cubic=True).design(data.fit.rows)
    level, fit = global_fit(data.fit.rows, y.copy(order="F"), data.state, data.unit >= 6)
    np.testing.assert_allclose(fit.gram, x.T @ x, rtol=1e-12, atol=1e-9)
    states = np.unique(data.state)
    for s, code in enumerate(states):
        for side in (0, 1):
            rows = (data.state == code) & ((data.unit >= 6) == side)
            np.testing.assert_allclose(fit.column_sums[s, side], x[rows].sum(axis=0),
                                       rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(level, data.level, atol=1e-9)
