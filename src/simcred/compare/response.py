"""The response test: does the candidate respond to each situation as the reference does?

H0: in every state, the law of the model's adjusted response (:mod:`simcred.compare.transitions`)
is the same in A and B. Not part of H0: how often states are visited, how long runs are, where
runs start, which exogenous inputs drove them (those are tested separately, by name:
:func:`occupancy_tests`). Differences *inside* a bin are visible, because the response is a
continuous value, not a successor bin.

Per state ``s`` the statistic compares the kernel mean embeddings of the two sides' residuals [1]:
``T_s = m n / (m + n) · ‖μ̂_A − μ̂_B‖²`` with ``μ̂`` the mean of random Fourier features
``φ(r) = cos(w r + b)`` of an additive Gaussian kernel [2] (one kernel per response feature,
``FOURIER`` features each, drawn once per comparison from the seed; bandwidth: the pooled median
distance, :func:`fourier_features`). Each feature value is rounded to ``1 / LEVELS`` so that all
sums are integers: the permutation products are exact in float32/float64 BLAS and the result does
not depend on the summation order (byte-identical outputs).

The null comes from the design (:mod:`simcred.compare.design`): units (runs, groups, or pairs
flipped within) are reassigned and every state's statistic recomputed from per-unit sums, exactly
as the run-level test does with counts (:mod:`simcred.compare.runs`). A state one side never
visits in an assignment contributes its permutation mean (no evidence; a state only long runs
reach is no difference of the response law). Chain verdict: the sum of the per-state statistics
standardised over the permutations [3]. Per-state verdicts: max-T family-wise [4], *reported only
when the chain verdict rejects* (a gatekeeping step: no state is called different while the chain
says "no difference shown", and the family-wise error stays ≤ α).

References
----------
[1] Gretton et al., A Kernel Two-Sample Test, JMLR 13, 2012.
[2] Rahimi & Recht, Random Features for Large-Scale Kernel Machines, NIPS 2007.
[3] Pesarin & Salmaso, Permutation Tests for Complex Data, Wiley, 2010.
[4] Westfall & Young, Resampling-Based Multiple Testing, Wiley, 1993.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.runs import (
    OneSided,
    RunCounts,
    SideCounts,
    exceedance_pvalues,
    row_max,
    standardise,
)
from simcred.compare.transitions import Transitions

#: The comparison's resolution: residuals get N(0, (RESOLUTION · spread)²) noise, spread = the
#: pooled standard deviation of the raw response (see response_test).
RESOLUTION = 0.02
#: Random Fourier features of the Gaussian kernel on the residuals.
FOURIER = 16
#: Each feature value is rounded to a multiple of 1 / LEVELS (integer sums, exact products).
LEVELS = 256
#: Residual pairs used for the median-distance bandwidth.
BANDWIDTH_PAIRS = 4096
#: Elements of one dense (columns × batch) block of a permutation batch.
BATCH_BUDGET = 2**22


@dataclass(frozen=True, slots=True, eq=False)
class ResponseOutcome:
    """Per tested state (``states``) and for the chain.

    ``m``, ``n``: transitions in A and B; ``statistic``: the observed ``T_s`` (NaN when a side is
    empty); ``pvalue``: per-state permutation p-value; ``adjusted``: max-T adjusted;
    ``in_family``: the state's statistic varies over the assignments.
    """

    states: np.ndarray
    m: np.ndarray
    n: np.ndarray
    statistic: np.ndarray
    pvalue: np.ndarray
    adjusted: np.ndarray
    in_family: np.ndarray
    chain_statistic: float
    chain_pvalue: float
    permutations: int
    bandwidth: tuple[float, ...]

    def rejected(self, alpha: float) -> np.ndarray:
        """Per-state verdicts, gatekept by the chain verdict."""
        if self.chain_pvalue > alpha:
            return np.zeros(len(self.states), dtype=bool)
        return self.in_family & (self.adjusted <= alpha)


def fourier_features(residual: np.ndarray, rng: np.random.Generator
                     ) -> tuple[np.ndarray, tuple[float, ...]]:
    """(n, 1 + J · FOURIER) integer-valued columns ``[1, round(LEVELS · φ_j(r_j)) …]`` and the
    bandwidth of every response feature.

    An additive kernel ``Σ_j k_j(r_j, r'_j)``: one Gaussian kernel per response feature, on the
    residual standardised by its pooled standard deviation, bandwidth = median distance of
    ``BANDWIDTH_PAIRS`` random residual pairs (the median heuristic). Features in different
    units never enter one distance, and a difference in one feature is not diluted by the
    spread of another.
    """
    n, n_features = residual.shape
    out = np.empty((n, 1 + n_features * FOURIER))
    out[:, 0] = 1.0
    sigmas = []
    i, j = rng.integers(0, n, (2, BANDWIDTH_PAIRS))
    for k in range(n_features):
        scale = residual[:, k].std()
        z = residual[:, k] / (scale if scale > 0 else 1.0)
        sigma = float(np.median(np.abs(z[i] - z[j])))
        sigma = sigma if sigma > 0 else 1.0
        w = rng.normal(0.0, 1.0 / sigma, FOURIER)
        b = rng.uniform(0.0, 2 * np.pi, FOURIER)
        columns = slice(1 + k * FOURIER, 1 + (k + 1) * FOURIER)
        out[:, columns] = np.rint(LEVELS * np.sqrt(2.0) * np.cos(z[:, None] * w + b))
        sigmas.append(sigma * (scale if scale > 0 else 1.0))
    return out, tuple(sigmas)


def unit_sums(data: Transitions, columns: np.ndarray, n_units: int) -> RunCounts:
    """Per state a block of ``columns.shape[1]`` rows, per unit the column sums over its
    transitions in that state: a sparse (blocks · width) × units matrix."""
    width = columns.shape[1]
    new = np.r_[True, (np.diff(data.state) != 0) | (np.diff(data.unit) != 0)]
    pair = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    pair_state, pair_unit = data.state[first], data.unit[first]
    block_start = np.r_[True, np.diff(pair_state) != 0]
    block_of_pair = np.cumsum(block_start) - 1
    sums = np.stack([np.bincount(pair, weights=columns[:, k], minlength=len(first))
                     for k in range(width)])
    rows = (block_of_pair * width)[None, :] + np.arange(width)[:, None]
    matrix = sp.csr_matrix((sums.ravel(), (rows.ravel(), np.tile(pair_unit, width))),
                           shape=(int(block_of_pair[-1] + 1) * width, n_units))
    blocks = pair_state[block_start]
    return RunCounts(matrix, blocks, np.arange(len(blocks) + 1) * width,
                     np.zeros(len(blocks) * width, dtype=np.int64))


STATE_RANK = 16


def response_test(data: Transitions, n_units: int, assignments: np.ndarray,
                  rng: np.random.Generator, vectors=None) -> ResponseOutcome:
    """The response test of every state and of the chain (module docs).

    ``assignments``: (P + 1, units) bool, row 0 the observed one (:meth:`Design.assignments`);
    ``rng``: the source of the Fourier features and the bandwidth pairs.

    The family is every (state, response feature): each is standardised over the assignments
    on its own, so a feature whose response varies a lot between units (a per-run constant
    speed) adds one standardised term, not its raw spread. A state's verdict is that of its
    most significant feature.
    """
    dither = RESOLUTION * data.spread if data.spread is not None else 0.0
    features, sigma = fourier_features(
        data.residual + dither * rng.normal(size=data.residual.shape), rng)
    sums = unit_sums(data, features, n_units)
    n_features = len(data.response)
    totals = np.bincount(np.searchsorted(sums.blocks, data.state), minlength=len(sums.blocks))
    basis = state_basis(vectors(sums.blocks), totals / totals.sum(), STATE_RANK) \
        if CHAIN == "smooth" and vectors is not None else None
    stats, pooled, m, n = assignment_statistics(sums, assignments, n_features,
                                                state_variances(data.state, features), basis)
    z, in_family = standardise(stats, OneSided.NEUTRAL)
    weight = np.repeat(np.sqrt((m + n).astype(float)), n_features)
    chain = _chain(z[:, in_family], standardise(pooled, OneSided.NEUTRAL)[0],
                   weight[in_family])
    adjusted = exceedance_pvalues(row_max(z[:, in_family])[:, None], z[0])
    adjusted[~in_family] = 1.0
    per_state = (len(sums.blocks), n_features)
    return ResponseOutcome(
        states=sums.blocks, m=m, n=n, statistic=stats[0].reshape(per_state).sum(axis=1),
        pvalue=exceedance_pvalues(z, z[0]).reshape(per_state).min(axis=1),
        adjusted=adjusted.reshape(per_state).min(axis=1),
        in_family=in_family.reshape(per_state).any(axis=1), chain_statistic=float(chain[0]),
        chain_pvalue=float(exceedance_pvalues(chain[:, None], chain[:1])[0]),
        permutations=len(assignments) - 1, bandwidth=sigma)


CHAIN = "pooled"


def _chain(z_states: np.ndarray, z_pooled: np.ndarray, weight) -> np.ndarray:
    if CHAIN == "states":
        return z_states.sum(axis=1)
    if CHAIN == "weighted":
        return z_states @ weight
    if CHAIN == "weighted_n":
        return z_states @ weight**2
    if CHAIN in ("pooled", "smooth"):
        return z_pooled.sum(axis=1)
    ranks = [_pvalue_of_each_row(c) for c in (z_states.sum(axis=1), z_pooled.sum(axis=1))]
    return -np.minimum(*ranks)


def _pvalue_of_each_row(values: np.ndarray) -> np.ndarray:
    """Permutation p-value of every row against all rows (Tippett's combination needs them)."""
    order = np.sort(values)
    return 1.0 - np.searchsorted(order, values, side="left") / len(values)


def state_variances(state: np.ndarray, features: np.ndarray) -> np.ndarray:
    """(blocks, features) pooled within-state variance ``E‖φ_j‖² − ‖Eφ_j‖²`` of the Fourier
    features of every response feature (``state`` sorted, blocks in order; label-free)."""
    bounds = np.r_[0, np.flatnonzero(np.diff(state)) + 1, len(state)]
    phi = features[:, 1:] / LEVELS
    mean = np.add.reduceat(phi, bounds[:-1], axis=0) / np.diff(bounds)[:, None]
    square = np.add.reduceat(phi**2, bounds[:-1], axis=0) / np.diff(bounds)[:, None]
    variance = (square - mean**2).reshape(len(mean), -1, FOURIER).sum(axis=2)
    return np.maximum(variance, 0.0)


def state_basis(vectors: np.ndarray, weights: np.ndarray, rank: int) -> np.ndarray:
    """(blocks, rank) factor ``U √Λ`` of the Gaussian kernel matrix between the states' bin-index
    vectors (bandwidth: the weighted median distance between states), top ``rank`` eigenpairs."""
    distance = np.sqrt(((vectors[:, None, :] - vectors[None, :, :]) ** 2).sum(axis=2))
    pair_weight = np.outer(weights, weights)
    order = np.argsort(distance, axis=None)
    cumulative = np.cumsum(pair_weight.ravel()[order])
    sigma = float(distance.ravel()[order][np.searchsorted(cumulative, cumulative[-1] / 2)])
    sigma = sigma if sigma > 0 else 1.0
    kernel = np.exp(-distance**2 / (2 * sigma**2))
    values, vectors_ = np.linalg.eigh(kernel)
    top = np.argsort(values)[::-1][:rank]
    return vectors_[:, top] * np.sqrt(np.maximum(values[top], 0.0))


def assignment_statistics(sums: RunCounts, assignments: np.ndarray, n_features: int,
                          variances: np.ndarray | None = None, basis: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Statistics of every assignment: (P + 1, blocks · features) per-state ``T_s,j``,
    (P + 1, features) pooled ``T_j`` (studentised by ``variances``, (blocks, features)), and the
    observed m, n per block."""
    product = SideCounts(sums)
    width = 1 + n_features * FOURIER
    totals = np.asarray(sums.matrix.sum(axis=1)).ravel()
    n_blocks = len(sums.blocks)
    share = totals[0::width] / max(totals[0::width].sum(), 1.0)
    out = np.empty((len(assignments), n_blocks, n_features))
    basis = np.ones((n_blocks, 1)) if basis is None else basis
    pooled = np.zeros((basis.shape[1], n_features * FOURIER, len(assignments)))
    spread = np.zeros((n_features, len(assignments)))
    variances = np.ones((n_blocks, n_features)) if variances is None else variances
    diagonal = (basis**2).sum(axis=1)
    batch = int(np.clip(BATCH_BUDGET // max(*sums.matrix.shape, 1), 8, 1024))
    for first, last, lo, hi in product.chunks:
        rows = product.rows(lo, hi)
        for start in range(0, len(assignments), batch):
            side_a = product.product(rows, assignments[start:start + batch])
            side_a = side_a.reshape(last - first, width, -1)
            value, diff, inverse = _statistic(
                side_a, totals[lo:hi].reshape(last - first, width), n_features)
            out[start:start + batch, first:last] = value.transpose(2, 0, 1)
            pooled[:, :, start:start + batch] += np.einsum(
                "sq,s,sdb->qdb", basis[first:last], share[first:last], diff)
            spread[:, start:start + batch] += np.einsum(
                "s,sj,sb->jb", diagonal[first:last] * share[first:last] ** 2,
                variances[first:last], inverse)
    observed = sums.matrix[0::width] @ assignments[0].astype(np.float64) if n_blocks \
        else np.zeros(0)
    total = totals[0::width]
    with np.errstate(invalid="ignore", divide="ignore"):
        pooled_stat = ((pooled.reshape(len(basis.T), n_features, FOURIER, -1) ** 2)
                       .sum(axis=(0, 2)) / LEVELS**2 / spread).T
    return (out.reshape(len(assignments), -1), pooled_stat, observed.astype(np.int64),
            (total - observed).astype(np.int64))


def _statistic(side_a: np.ndarray, totals: np.ndarray, n_features: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """``m n / (m + n) · ‖μ_A,j − μ_B,j‖²`` per block, feature and assignment
    (blocks, features, batch), ``μ_A − μ_B`` (blocks, features · FOURIER, batch) and
    ``1/m + 1/n`` (blocks, batch); both 0 where a side is empty."""
    m = side_a[:, 0, :]
    n = totals[:, :1] - m
    empty = (m < 1) | (n < 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_a = side_a[:, 1:, :] / m[:, None, :]
        mean_b = (totals[:, 1:, None] - side_a[:, 1:, :]) / n[:, None, :]
        diff = mean_a - mean_b
        per_feature = (diff**2).reshape(len(m), n_features, FOURIER, -1).sum(axis=2)
        value = (m * n / (m + n))[:, None, :] * per_feature / LEVELS**2
    value[np.broadcast_to(empty[:, None, :], value.shape)] = np.nan
    diff[np.broadcast_to(empty[:, None, :], diff.shape)] = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        inverse = np.where(empty, 0.0, 1.0 / m + 1.0 / n)
    return value, diff, inverse
