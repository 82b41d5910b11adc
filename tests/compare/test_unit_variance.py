"""Each side's variance from its own units (simcred.compare.unit_variance): a literal per-unit
computation, the sparse and the dense layout agree, and the sums are exact in any order."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from simcred.compare.response import FOURIER, kernel_sums
from simcred.compare.run_counts import RunCounts
from simcred.compare.transitions import Transitions
from simcred.compare.unit_variance import TOTAL, UnitSquares


def _data(seed: int, units: int = 9, per_unit: int = 14, n_states: int = 4) -> Transitions:
    rng = np.random.default_rng(seed)
    n = units * per_unit
    state = rng.integers(0, n_states, n)
    unit = np.repeat(np.arange(units), per_unit)
    order = np.lexsort((unit, state))
    residual = rng.normal(size=(n, 2)) * [1.0, 3.0]
    return Transitions(state[order], unit[order], residual[order], ("x", "y"),
                       np.array([1.0, 3.0]))


def _literal(matrix: np.ndarray, n_features: int, dims: int, assignment: np.ndarray
             ) -> np.ndarray:
    """(blocks, features): Σ_{u ∈ A} ‖S_u − c_u μ‖², unit by unit."""
    width = 1 + n_features * dims
    out = np.zeros((matrix.shape[0] // width, n_features))
    for b in range(out.shape[0]):
        block = matrix[b * width:(b + 1) * width].astype(np.float64)
        count, values = block[0], block[1:]
        mean = values.sum(axis=1) / count.sum()
        for u in np.flatnonzero(assignment):
            x = values[:, u] - count[u] * mean
            out[b] += (x.reshape(n_features, dims) ** 2).sum(axis=1)
    return out


@pytest.mark.parametrize("layout", ["as built", "dense", "csr without zeros"])
def test_side_squares_equal_a_literal_per_unit_computation(layout):
    """40 units visiting 3 of 12 states each: built as CSR (SumLayout: every row of a block
    holds the block's units); the same as a dense array and as a CSR without stored zeros."""
    kernel = kernel_sums(_data(1, units=40, per_unit=3, n_states=12), 40,
                         np.random.default_rng(2))
    matrix = kernel.counts.matrix
    assert sp.issparse(matrix)
    dense = matrix.toarray()
    other = {"as built": matrix, "dense": dense, "csr without zeros": sp.csr_matrix(dense)}
    counts = RunCounts(other[layout], kernel.counts.blocks, kernel.counts.bounds,
                       kernel.counts.successors)
    squares = UnitSquares.of(counts, 2, FOURIER)
    assignments = np.random.default_rng(3).random((5, 40)) < 0.5
    side_a, side_b = squares.sides(assignments, kernel.counts.blocks)(
        0, len(kernel.counts.blocks), slice(None))
    for row, assignment in enumerate(assignments):
        assert side_a[:, :, row] == pytest.approx(_literal(dense, 2, FOURIER, assignment),
                                                  rel=1e-9, abs=1e-6)
        assert side_b[:, :, row] == pytest.approx(_literal(dense, 2, FOURIER, ~assignment),
                                                  rel=1e-9, abs=1e-6)


def test_sums_are_exact_integers_in_any_order():
    kernel = kernel_sums(_data(4), 9, np.random.default_rng(5))
    squares = UnitSquares.of(kernel.counts, 2, FOURIER)
    matrix = squares.matrix.toarray() if hasattr(squares.matrix, "toarray") else squares.matrix
    assert np.array_equal(matrix, np.rint(matrix))
    assert matrix.reshape(-1, 2, 9).sum(axis=(0, 2)).max() < TOTAL + matrix.size  # rounding
    forward = np.add.reduce(matrix, axis=1)
    backward = np.add.reduce(matrix[:, ::-1], axis=1)
    assert np.array_equal(forward, backward)


def test_a_unit_alone_in_a_state_adds_nothing():
    """A state only one unit visits: its centred sum is 0 (its mean is the pooled mean), so it
    adds no variance; the moments' sums (one column per value, dims 1) work the same."""
    data = _data(6)
    state = data.state.copy()
    state[data.unit == 0] = 9  # unit 0 alone in state 9
    order = np.lexsort((data.unit, state))
    alone = Transitions(state[order], data.unit[order], data.residual[order], data.response,
                        data.spread)
    kernel = kernel_sums(alone, 9, np.random.default_rng(7))
    last = len(kernel.counts.blocks)
    assert kernel.counts.blocks[-1] == 9
    kernel_squares = UnitSquares.of(kernel.counts, 2, FOURIER)
    assert kernel_squares.totals[-1] == pytest.approx(0.0, abs=1e-6)
    assert np.all(kernel_squares.totals[:-1] > 0)
    width = kernel.moments.matrix.shape[0] // last
    moment_squares = UnitSquares.of(kernel.moments, width - 1, 1)
    assert moment_squares.totals.shape == (last, width - 1)
    assert moment_squares.totals[-1] == pytest.approx(0.0, abs=1e-6)
