"""The response test: does the candidate respond to each situation as the reference does?

H0: in every state, the law of the model's adjusted response (:mod:`simcred.compare.transitions`)
is the same in A and B. Not part of H0: how often states are visited, how long runs are, where
runs start, which exogenous inputs drove them (named tests of their own,
:mod:`simcred.compare.conditional`). Differences *inside* a bin are visible, because the response
is a continuous value, not a successor bin.

**Features.** Each residual gets a little seeded noise, ``RESOLUTION`` times the pooled spread of
its raw response (the comparison's resolution: fit leftovers of a deterministic model, orders of
magnitude below any driver's noise, are not evidence), and is mapped to ``FOURIER`` random
Fourier features ``cos(w r + b)`` of a Gaussian kernel [2] (one kernel per response feature:
quantities in different units never share a distance; bandwidth = pooled median distance).
Each feature value is rounded to ``1 / LEVELS``, so every sum is an integer: the permutation
products are exact and the result does not depend on the summation order.

**Chain statistic** (the verdict). Per state ``s`` and response feature ``j`` the difference of
the two sides' kernel mean embeddings ``d_s,j = μ̂_A,s,j − μ̂_B,s,j`` [1]; pooled over the
states with their pooled share of transitions ``w_s`` and studentised:

    T_j = ‖Σ_s w_s d_s,j‖² / Σ_s w_s² (Q_A,s,j / m_s² + Q_B,s,j / n_s²)

(``m_s``, ``n_s``: the assignment's transitions per side; ``Q_A,s,j``: the sum over A's units of
the squared norm of the unit's sum of centred features in state s — each side's variance from
its own units, :mod:`simcred.compare.unit_variance`). Every term has mean zero under H0 whatever
the state mix, and the studentisation follows the assignment: runs of other lengths, within-run
dependence and traits per run on one side are in that side's variance, which keeps the
permutation null's level where the units are not exchangeable (session 13; the pooled
within-state variance used before did not: 0.090 on runs of 10 vs 100 steps). It aggregates a
difference of one sign over the whole state space (a variance change, a bias); a difference
whose sign changes between states cancels in it.

**Profile statistics.** A delay, a late brake or a gain change the response by an amount that
follows how the model responds in that state — its sign changes with the state's mean response
(braking vs accelerating, rising vs falling command). With ``h_k(s)`` the pooled mean of the
global fit of response feature ``k`` in state ``s`` (label-free), centred and scaled with the
weights ``w_s``, ``T_k,j`` is ``T_j`` with ``w_s h_k(s)`` in place of ``w_s``: the A–B difference
projected on the response profile instead of summed.

**Spread statistics.** ``S_j`` is ``T_j`` computed on ``|r_j|`` (the dithered residual's size,
in units of its pooled spread) instead of its Fourier features: a Levene-type comparison [5] of
the response's spread, state by state, pooled. The kernel's mean embedding at the median
bandwidth sees a change of spread (a noisier model, clipped tails) only weakly. A response whose
adjusted residual is below ``NOISE_FLOOR`` of its raw spread has no noise of its own (a
kinematic identity: only the dither and fit leftovers, whose size differs between places a
deterministic model drives): its spread is not compared.

**Co-movement statistic.** For every pair ``(j, k)`` of responses that both have noise of their
own, ``C_jk`` is ``T_j`` computed on the product ``(r_j / sd_j)(r_k / sd_k)`` of the dithered
residuals: per state the A–B difference of how the two responses move together, pooled. A
reaction delay shows there first: in car following the relative speed's residual given the
state is the leader's change over the step, and a driver who reacts within the step moves its
acceleration with it, a delayed one does not — the marginal law of each response hardly
changes. The largest ``z(C_jk)`` over the pairs is one component of the chain.

**Chain** = Tippett's combination [3] of ``max(z(T_j), z(S_j))`` per feature, the sum of the
profile ``T_k,j`` over ``k`` and ``j`` and the co-movement, each standardised over the
assignments: a change in one feature is not diluted by the features that do not change, and the
profile statistic adds the changes of varying sign. The maximum (not the sum) keeps a change of
level from being diluted by the spread, and one component per feature keeps Tippett's floor low
(with P permutations and K components the smallest chain p-value is about K / (P + 1)). Measured
against the sum of ``T_j`` alone and other variants (calibration.md).

**Per-state statistics** (where it shows): ``T_s,j = m n/(m+n) · ‖d_s,j‖²``, standardised, max-T
family-wise adjusted [4], and *reported only when the chain verdict rejects* (gatekeeping: no
state is called different while the chain says "no difference shown"). A state one side never
visits in an assignment contributes its permutation mean (a state only long runs reach is not a
difference of the response law).

The null comes from the design (:mod:`simcred.compare.design`): units (runs, groups, or pairs
flipped within) are reassigned and every statistic recomputed from per-unit sums, as the
run-level test does with counts (:mod:`simcred.compare.runs`).

References
----------
[1] Gretton et al., A Kernel Two-Sample Test, JMLR 13, 2012.
[2] Rahimi & Recht, Random Features for Large-Scale Kernel Machines, NIPS 2007.
[3] Pesarin & Salmaso, Permutation Tests for Complex Data, Wiley, 2010.
[4] Westfall & Young, Resampling-Based Multiple Testing, Wiley, 1993.
[5] Levene, Robust tests for equality of variances, in Contributions to Probability and
    Statistics, Stanford University Press, 1960.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.paired_runs import tippett
from simcred.compare.run_counts import RunCounts
from simcred.compare.runs import (
    OneSided,
    batch_size,
    exceedance_pvalues,
    row_max,
    standardise,
)
from simcred.compare.scratch import std_columns
from simcred.compare.side_counts import SideCounts, is_paired
from simcred.compare.state_sums import StatePairs, SumTarget, pair_chunks
from simcred.compare.threads import in_threads
from simcred.compare.transitions import Transitions
from simcred.compare.unit_sums import DenseSides
from simcred.compare.unit_variance import UnitSquares

#: The comparison's resolution: residuals get N(0, (RESOLUTION · spread)²) noise, spread = the
#: pooled standard deviation of the raw response.
RESOLUTION = 0.02
#: Random Fourier features of the Gaussian kernel on each response feature's residual.
FOURIER = 16
#: Each feature value is rounded to a multiple of 1 / LEVELS (integer sums, exact products).
LEVELS = 256
#: Responses whose adjusted residual's spread is below this share of the raw response's get no
#: spread statistic (module docs).
NOISE_FLOOR = 0.05
#: Residual pairs used for the median-distance bandwidth.
BANDWIDTH_PAIRS = 4096
@dataclass(frozen=True, slots=True, eq=False)
class ResponseOutcome:
    """Per tested state (``states``) and for the chain.

    ``m``, ``n``: transitions in A and B; ``statistic``: the observed per-state statistic summed
    over features (NaN when a side is empty); ``pvalue``: per-state permutation p-value (its most
    significant feature); ``adjusted``: max-T adjusted; ``in_family``: the state's statistic
    varies over the assignments; ``bandwidth``: per response feature, in its unit.
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
    chain_null: np.ndarray | None = None  # the chain statistic of every assignment (row 0 observed)

    def rejected(self, alpha: float) -> np.ndarray:
        """Per-state verdicts, gatekept by the chain verdict."""
        if self.chain_pvalue > alpha:
            return np.zeros(len(self.states), dtype=bool)
        return self.in_family & (self.adjusted <= alpha)


@dataclass(frozen=True, slots=True, eq=False)
class KernelSums:
    """Per (state, unit) sums of ``[1, features]`` (a RunCounts of blocks of width
    ``1 + J · FOURIER``), the bandwidths; the same for the residuals' second moments ``[1,
    |r_j|, products of the noisy pairs]`` (:class:`_Moments`), None where no response has
    noise of its own (``noisy``: per response, None without a spread; ``pairs``: the noisy
    pairs, :func:`noisy_pairs`)."""

    counts: RunCounts
    bandwidth: tuple[float, ...]
    moments: RunCounts | None
    noisy: np.ndarray | None = None
    pairs: tuple[tuple[int, int], ...] = ()


class _FourierMap:
    """The seeded feature map: per response feature a bandwidth, frequencies and phases."""

    def __init__(self, residual: np.ndarray, rng: np.random.Generator,
                 scratch: np.ndarray | None = None) -> None:
        n, n_features = residual.shape
        i, j = rng.integers(0, n, (2, BANDWIDTH_PAIRS))
        self.scale, self.w, self.b, self.bandwidth = [], [], [], []
        for k in range(n_features):
            column = residual[:, k]
            scale = float(std_columns(column, None if scratch is None else scratch[:, k])[0]) \
                or 1.0
            sigma = float(np.median(np.abs(column[i] / scale - column[j] / scale))) or 1.0
            self.scale.append(scale)
            self.w.append(rng.normal(0.0, 1.0 / sigma, FOURIER).astype(np.float32))
            self.b.append(rng.uniform(0.0, 2 * np.pi, FOURIER).astype(np.float32))
            self.bandwidth.append(sigma * scale)

    def __call__(self, residual: np.ndarray, dtype: type = np.float64) -> list[np.ndarray]:
        """Per response feature, the (rows, FOURIER) integer-valued features of a chunk of
        residuals, as ``dtype`` (integers of at most 363: exact in single precision too). The
        angle and its cosine are single precision (3-4x faster than double; the value is rounded
        to 1 / LEVELS of √2 anyway: about 3 in 100,000 land one level apart)."""
        out = []
        for k, (scale, w, b) in enumerate(zip(self.scale, self.w, self.b, strict=True)):
            block = np.multiply((residual[:, k] / scale).astype(np.float32)[:, None], w)
            block += b
            np.cos(block, out=block)
            block *= np.float32(LEVELS * np.sqrt(2.0))
            np.rint(block, out=block)
            out.append(block.astype(dtype, copy=False))
        return out


def noisy_responses(data: Transitions, scratch: np.ndarray | None = None
                    ) -> np.ndarray | None:
    """Per response feature, whether its adjusted residual has noise of its own (at least
    ``NOISE_FLOOR`` of the raw response's spread, module docs); None without that spread.
    ``scratch``: a buffer of the residual's shape for the standard deviation's temporary."""
    if data.spread is None:
        return None
    return std_columns(data.residual, scratch) >= NOISE_FLOOR * data.spread


def kernel_sums(data: Transitions, n_units: int, rng: np.random.Generator) -> KernelSums:
    """Dithered residuals → Fourier features (and second moments, :class:`_Moments`, where a
    response has noise of its own) → per-(state, unit) sums, state by state and chunk by chunk
    in one pass (the feature matrix of all transitions never exists). The features are
    integers, so every sum here is exact (in any order): pair sums are one sparse product per
    chunk, written straight into the unit matrix (:class:`SumTarget`)."""
    spread = data.spread if data.spread is not None else np.zeros(data.residual.shape[1])
    residual = np.asfortranarray(data.residual + RESOLUTION * spread
                                 * rng.normal(size=data.residual.shape))  # columns contiguous
    scratch = np.empty_like(residual)  # every standard deviation's squared deviations
    feature_map = _FourierMap(residual, rng, scratch)
    noisy = noisy_responses(data, scratch)
    pairs = StatePairs.of(data)
    n_blocks, n_features = len(pairs.blocks), residual.shape[1]
    peak = 2 * int(np.ceil(LEVELS * np.sqrt(2.0))) * int(np.diff(pairs.starts).max(initial=0))
    kernel = SumTarget(pairs, 1 + n_features * FOURIER, n_units, peak)
    moments, moment_map = None, None
    if noisy is not None and noisy.any():
        moment_map = _Moments.of(residual, noisy, scratch)
        moments = SumTarget(pairs, 1 + moment_map.width, n_units, None)
    first_pair = np.r_[0, np.cumsum(np.bincount(pairs.block, minlength=n_blocks))]

    def block_sums(b: int) -> None:
        p0, p1 = int(first_pair[b]), int(first_pair[b + 1])
        count = np.diff(pairs.starts[p0:p1 + 1]).astype(np.float64)[:, None]
        for target in (kernel, moments) if moments is not None else (kernel,):
            target.put(b, 0, p0, p1, count)
        for first, last in pair_chunks(pairs.starts, p0, p1):
            lo, hi = pairs.starts[first], pairs.starts[last]
            ends = pairs.starts[first:last + 1] - lo
            indicator = sp.csr_matrix((np.ones(hi - lo, dtype=kernel.dtype), np.arange(hi - lo),
                                       ends), shape=(last - first, hi - lo))  # pair × transition
            for k, phi in enumerate(feature_map(residual[lo:hi], kernel.dtype)):
                kernel.put(b, 1 + k * FOURIER, first, last, indicator @ phi)
            if moments is not None:
                values = moment_map(residual[lo:hi])
                moments.put(b, 1, first, last, indicator.astype(np.float64, copy=False) @ values)

    in_threads(block_sums, range(n_blocks))
    return KernelSums(kernel.counts(), tuple(feature_map.bandwidth),
                      None if moments is None else moments.counts(), noisy,
                      () if moment_map is None else moment_map.pairs)


@dataclass(frozen=True, slots=True)
class _Moments:
    """The second-moment values of the dithered residuals, rounded to 1 / LEVELS (integers, so
    their sums are exact): per response ``|r_j|`` in units of its pooled standard deviation
    (``size_scale``, over all transitions), then per noisy pair ``(j, k)`` the product
    ``(r_j / sd_j)(r_k / sd_k)`` (``sd``: the residuals' pooled standard deviations)."""

    size_scale: np.ndarray
    sd: np.ndarray
    pairs: tuple[tuple[int, int], ...]

    @classmethod
    def of(cls, residual: np.ndarray, noisy: np.ndarray, scratch: np.ndarray | None = None
           ) -> _Moments:
        size = np.abs(residual)
        size_scale = std_columns(size, scratch)
        sd = std_columns(residual, size)  # |r| is done with: its buffer takes the deviations
        return cls(np.where(size_scale > 0, size_scale, 1.0), np.where(sd > 0, sd, 1.0),
                   noisy_pairs(noisy))

    @property
    def width(self) -> int:
        return len(self.sd) + len(self.pairs)

    def __call__(self, residual: np.ndarray) -> np.ndarray:
        z = residual / self.sd
        products = [z[:, j] * z[:, k] for j, k in self.pairs]
        return np.rint(LEVELS * np.column_stack([np.abs(residual) / self.size_scale, *products]))


def noisy_pairs(noisy: np.ndarray) -> tuple[tuple[int, int], ...]:
    """Every pair ``(j, k)``, ``j < k``, of response features that both have noise of their
    own."""
    return tuple(itertools.combinations(np.flatnonzero(noisy).tolist(), 2))


def response_test(data: Transitions, n_units: int, assignments: np.ndarray,
                  rng: np.random.Generator) -> ResponseOutcome:
    """The response test of the chain and of every state (module docs).

    ``assignments``: (P + 1, units) bool, row 0 the observed one (:meth:`Design.assignments`);
    ``rng``: the source of the dither, the Fourier features and the bandwidth pairs.
    """
    kernel = kernel_sums(data, n_units, rng)
    n_features = len(data.response)
    stats, pooled, m, n = assignment_statistics(kernel.counts, assignments, n_features,
                                                data.profile)
    z, in_family = standardise(stats, OneSided.NEUTRAL)
    chain = chain_statistic(standardise(pooled, OneSided.NEUTRAL)[0], n_features,
                            *moment_statistics(kernel, n_features, assignments))
    adjusted = exceedance_pvalues(row_max(z[:, in_family])[:, None], z[0])
    adjusted[~in_family] = 1.0
    per_state = (len(kernel.counts.blocks), n_features)
    return ResponseOutcome(
        states=kernel.counts.blocks, m=m, n=n,
        statistic=stats[0].reshape(per_state).sum(axis=1),
        pvalue=exceedance_pvalues(z, z[0]).reshape(per_state).min(axis=1),
        adjusted=adjusted.reshape(per_state).min(axis=1),
        in_family=in_family.reshape(per_state).any(axis=1), chain_statistic=float(chain[0]),
        chain_pvalue=float(exceedance_pvalues(chain[:, None], chain[:1])[0]),
        permutations=len(assignments) - 1, bandwidth=kernel.bandwidth, chain_null=chain)


def moment_statistics(kernel: KernelSums, n_features: int, assignments: np.ndarray
                      ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(P + 1, features) standardised spread statistics ``S_j`` (0 for a response below the
    noise floor) and (P + 1,) the largest standardised co-movement statistic ``C_jk`` over the
    noisy pairs; each None where there is none (module docs; ``kernel`` holds the moment sums
    only where a response has noise of its own, :func:`kernel_sums`)."""
    if kernel.moments is None:
        return None, None
    _, pooled, _, _ = assignment_statistics(kernel.moments, assignments,
                                            n_features + len(kernel.pairs), dims=1)
    z = standardise(pooled, OneSided.NEUTRAL)[0]
    comovement = z[:, n_features:].max(axis=1) if kernel.pairs else None
    return z[:, :n_features] * kernel.noisy, comovement


def chain_statistic(z: np.ndarray, n_features: int, spread: np.ndarray | None = None,
                    comovement: np.ndarray | None = None) -> np.ndarray:
    """The chain statistic of every assignment from the standardised pooled statistics
    (P + 1, K · features), spread statistics (P + 1, features) and co-movement statistic
    (P + 1,): Tippett's combination of each feature's ``max(T_j, S_j)`` (``T_j`` where ``S_j`` is
    0: no noise of its own), the sum of the profile statistics and the co-movement (module
    docs); larger = more extreme."""
    level = [z[:, j] if spread is None or not spread[:, j].any()
             else np.maximum(z[:, j], spread[:, j]) for j in range(n_features)]
    if z.shape[1] > n_features:
        level.append(z[:, n_features:].sum(axis=1))
    if comovement is not None:
        level.append(comovement)
    return tippett(*level)


def contrasts(share: np.ndarray, profile: np.ndarray | None) -> np.ndarray:
    """(K, blocks) state weights of the pooled statistics: 1, then each column of ``profile``
    centred and scaled with the weights ``share`` (a column constant over the states is left
    out)."""
    rows = [np.ones(len(share))]
    for column in () if profile is None else profile.T:
        centred = column - share @ column
        scale = np.sqrt(share @ centred**2)
        if scale > 1e-12 * max(np.abs(column).max(), 1e-300):
            rows.append(centred / scale)
    return np.array(rows)


def assignment_statistics(sums: RunCounts, assignments: np.ndarray, n_features: int,
                          profile: np.ndarray | None = None, dims: int = FOURIER
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Statistics of every assignment: (P + 1, blocks · features) per-state ``T_s,j``,
    (P + 1, K · features) pooled studentised ``T_k,j`` (k = 0: ``T_j``; then one block of
    features per profile contrast, :func:`contrasts`; each side's variance from its units,
    :mod:`simcred.compare.unit_variance`), and the observed m, n per block.
    ``dims``: columns per response feature in ``sums`` (``FOURIER``; 1 for the moments)."""
    sides = DenseSides if isinstance(sums.matrix, np.ndarray) else SideCounts
    product = sides(sums, paired=is_paired(assignments))
    squares = UnitSquares.of(sums, n_features, dims).sides(assignments, sums.blocks)
    width = 1 + n_features * dims
    totals = np.asarray(sums.matrix.sum(axis=1, dtype=np.float64)).ravel()
    share = totals[0::width] / max(totals[0::width].sum(), 1.0)
    weights = contrasts(share, profile) * share  # (K, blocks)
    out = _AssignmentSums(product, squares, assignments, totals, weights, n_features, dims,
                          batch_size(*sums.matrix.shape))
    for first, last, lo, hi in product.chunks:
        out.add_chunk(first, last, lo, hi)
    per_state, pooled, spread = out.per_state, out.pooled, out.spread
    observed = sums.matrix[0::width] @ assignments[0].astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        studentised = ((pooled.reshape(len(weights), n_features, dims, -1) ** 2).sum(axis=2)
                       / spread).reshape(len(weights) * n_features, -1).T
    return (per_state.reshape(len(assignments), -1), studentised,
            observed.astype(np.int64), (totals[0::width] - observed).astype(np.int64))


class _AssignmentSums:
    """The per-state statistics of every assignment and the pooled sums of their differences
    and variances, filled chunk of states by chunk; within a chunk the batches of assignments
    run in threads (each batch its own columns: the same sums in the same order)."""

    def __init__(self, product, squares, assignments: np.ndarray, totals: np.ndarray,
                 weights: np.ndarray, n_features: int, dims: int, batch: int) -> None:
        self.product, self.squares, self.assignments = product, squares, assignments
        self.totals, self.weights, self.batch = totals, weights, batch
        self.n_features, self.dims, self.width = n_features, dims, 1 + n_features * dims
        n_blocks = len(totals) // self.width
        self.per_state = np.empty((len(assignments), n_blocks, n_features))
        self.pooled = np.zeros((len(weights), n_features * dims, len(assignments)))
        self.spread = np.zeros((len(weights), n_features, len(assignments)))

    def add_chunk(self, first: int, last: int, lo: int, hi: int) -> None:
        rows = self.product.rows(lo, hi)
        in_threads(lambda start: self._add_batch(rows, first, last, lo, hi, start),
                   range(0, len(self.assignments), self.batch))

    def _add_batch(self, rows, first: int, last: int, lo: int, hi: int, start: int) -> None:
        here, width = slice(start, start + self.batch), self.width
        side_a = self.product.product(rows, self.assignments[here])
        value, diff, m, n = _statistic(side_a.reshape(last - first, width, -1),
                                       self.totals[lo:hi].reshape(last - first, width),
                                       self.n_features, self.dims)
        square_a, square_b = self.squares(first, last, here)
        with np.errstate(invalid="ignore", divide="ignore"):
            variance = np.where(((m < 1) | (n < 1))[:, None, :], 0.0,
                                square_a / m[:, None, :]**2 + square_b / n[:, None, :]**2)
        weight = self.weights[:, first:last]
        self.per_state[here, first:last] = value.transpose(2, 0, 1)
        self.pooled[:, :, here] += np.einsum("ks,sdb->kdb", weight, diff)
        self.spread[:, :, here] += np.einsum("ks,sjb->kjb", weight**2, variance)


def _statistic(side_a: np.ndarray, totals: np.ndarray, n_features: int, dims: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per block and assignment: ``m n / (m + n) · ‖μ_A,j − μ_B,j‖²`` (blocks, features, batch),
    ``μ_A − μ_B`` (blocks, features · dims, batch), m and n (blocks, batch); the difference 0
    and the first NaN where a side is empty."""
    m = side_a[:, 0, :]
    n = totals[:, :1] - m
    empty = (m < 1) | (n < 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = side_a[:, 1:, :] / m[:, None, :] \
            - (totals[:, 1:, None] - side_a[:, 1:, :]) / n[:, None, :]
        per_feature = (diff**2).reshape(len(m), n_features, dims, -1).sum(axis=2)
        value = (m * n / (m + n))[:, None, :] * per_feature / LEVELS**2
    value[np.broadcast_to(empty[:, None, :], value.shape)] = np.nan
    diff[np.broadcast_to(empty[:, None, :], diff.shape)] = 0.0
    return value, diff, m, n
