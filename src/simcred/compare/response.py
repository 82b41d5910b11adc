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

    T_j = ‖Σ_s w_s d_s,j‖² / Σ_s w_s² v_s,j (1/m_s + 1/n_s)

(``v_s,j``: pooled within-state variance of the features, label-free; ``m_s``, ``n_s``: the
assignment's transitions per side). Every term has mean zero under H0 whatever the state mix, and
the studentisation keeps the null's scale when the two sides' runs have different lengths (the
issue-11 lesson). It aggregates a difference of one sign over the whole state space (a variance
change, a bias); a difference whose sign changes between states cancels in it.

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

**Chain** = Tippett's combination [3] of ``max(z(T_j), z(S_j))`` per feature and the sum of the
profile ``T_k,j`` over ``k`` and ``j``, each standardised over the assignments: a change in one
feature is not diluted by the features that do not change, and the profile statistic adds the
changes of varying sign. The maximum (not the sum) keeps a change of level from being diluted
by the spread, and one component per feature keeps Tippett's floor low (with P permutations
and K components the smallest chain p-value is about K / (P + 1)). Measured against the sum
of ``T_j`` alone and other variants (calibration.md).

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

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.paired_runs import tippett
from simcred.compare.run_counts import RunCounts
from simcred.compare.runs import OneSided, exceedance_pvalues, row_max, standardise
from simcred.compare.side_counts import SideCounts, is_paired
from simcred.compare.transitions import Transitions
from simcred.compare.unit_sums import DENSE_SHARE, DenseSides

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
#: Elements of one dense (columns × batch) block of a permutation batch.
BATCH_BUDGET = 2**22
#: Transitions per chunk when the features are computed and summed.
CHUNK = 2**16


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
    ``1 + J · FOURIER``), per state the pooled feature variance ``v_s,j``, the bandwidths; the
    same for the residuals' sizes ``[1, |r_j|]`` (:func:`size_values`), None where no response
    has noise of its own (``noisy``: per response, None without a spread)."""

    counts: RunCounts
    variances: np.ndarray
    bandwidth: tuple[float, ...]
    sizes: RunCounts | None
    size_variances: np.ndarray | None
    noisy: np.ndarray | None = None


@dataclass(frozen=True, slots=True, eq=False)
class _Pairs:
    """Runs of equal (state, unit) in the sorted transitions."""

    starts: np.ndarray  # first transition of every (state, unit) pair, and the total at the end
    state: np.ndarray
    unit: np.ndarray
    block: np.ndarray  # block (distinct state) of every pair
    blocks: np.ndarray  # state code of every block

    @classmethod
    def of(cls, data: Transitions) -> _Pairs:
        new = np.r_[True, (np.diff(data.state) != 0) | (np.diff(data.unit) != 0)]
        first = np.flatnonzero(new)
        state = data.state[first]
        block_start = np.r_[True, np.diff(state) != 0]
        return cls(np.r_[first, len(data.state)], state, data.unit[first],
                   np.cumsum(block_start) - 1, state[block_start])


class _FourierMap:
    """The seeded feature map: per response feature a bandwidth, frequencies and phases."""

    def __init__(self, residual: np.ndarray, rng: np.random.Generator) -> None:
        n, n_features = residual.shape
        i, j = rng.integers(0, n, (2, BANDWIDTH_PAIRS))
        self.scale, self.w, self.b, self.bandwidth = [], [], [], []
        for k in range(n_features):
            scale = float(residual[:, k].std()) or 1.0
            z = residual[:, k] / scale
            sigma = float(np.median(np.abs(z[i] - z[j]))) or 1.0
            self.scale.append(scale)
            self.w.append(rng.normal(0.0, 1.0 / sigma, FOURIER))
            self.b.append(rng.uniform(0.0, 2 * np.pi, FOURIER))
            self.bandwidth.append(sigma * scale)

    def __call__(self, residual: np.ndarray) -> list[np.ndarray]:
        """Per response feature, the (rows, FOURIER) integer-valued features of a chunk of
        residuals."""
        out = []
        for k, (scale, w, b) in enumerate(zip(self.scale, self.w, self.b, strict=True)):
            block = np.multiply((residual[:, k] / scale)[:, None], w)
            block += b
            np.cos(block, out=block)
            block *= LEVELS * np.sqrt(2.0)
            np.rint(block, out=block)
            out.append(block)
        return out


def noisy_responses(data: Transitions) -> np.ndarray | None:
    """Per response feature, whether its adjusted residual has noise of its own (at least
    ``NOISE_FLOOR`` of the raw response's spread, module docs); None without that spread."""
    if data.spread is None:
        return None
    return data.residual.std(axis=0) >= NOISE_FLOOR * data.spread


def kernel_sums(data: Transitions, n_units: int, rng: np.random.Generator) -> KernelSums:
    """Dithered residuals → Fourier features (and sizes ``|r_j|``, :func:`size_values`, where a
    response has noise of its own) → per-(state, unit) sums, state by state and chunk by chunk
    in one pass (the feature matrix of all transitions never exists). The features are
    integers, so every sum here is exact (in any order): pair sums are one sparse product per
    chunk, written straight into the unit matrix (:class:`_Target`)."""
    spread = data.spread if data.spread is not None else np.zeros(data.residual.shape[1])
    residual = data.residual + RESOLUTION * spread * rng.normal(size=data.residual.shape)
    feature_map = _FourierMap(residual, rng)
    noisy = noisy_responses(data)
    pairs = _Pairs.of(data)
    n_blocks, n_features = len(pairs.blocks), residual.shape[1]
    peak = 2 * int(np.ceil(LEVELS * np.sqrt(2.0))) * int(np.diff(pairs.starts).max(initial=0))
    kernel = _Target(pairs, 1 + n_features * FOURIER, n_units, peak)
    sizes, scale = None, None
    if noisy is not None and noisy.any():
        scale = np.abs(residual).std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        sizes = _Target(pairs, 1 + n_features, n_units, None)
    first_pair = np.r_[0, np.cumsum(np.bincount(pairs.block, minlength=n_blocks))]
    for b in range(n_blocks):
        p0, p1 = int(first_pair[b]), int(first_pair[b + 1])
        count = np.diff(pairs.starts[p0:p1 + 1]).astype(np.float64)[:, None]
        for target in (kernel, sizes) if sizes is not None else (kernel,):
            target.put(b, 0, p0, p1, count)
        for first, last in _chunks(pairs.starts, p0, p1):
            lo, hi = pairs.starts[first], pairs.starts[last]
            ends = pairs.starts[first:last + 1] - lo
            indicator = sp.csr_matrix((np.ones(hi - lo), np.arange(hi - lo), ends),
                                      shape=(last - first, hi - lo))  # pair × transition
            for k, phi in enumerate(feature_map(residual[lo:hi])):
                kernel.put(b, 1 + k * FOURIER, first, last, indicator @ phi, phi)
            if sizes is not None:
                values = size_values(residual[lo:hi], scale)
                sizes.put(b, 1, first, last, indicator @ values, values)
    count = kernel.totals[:, :1]
    variance = kernel.squares / count - (kernel.totals[:, 1:] / count) ** 2
    variances = np.maximum(variance.reshape(n_blocks, -1, FOURIER).sum(axis=2), 0.0) / LEVELS**2
    size_variances = None
    if sizes is not None:
        mean = sizes.totals[:, 1:] / count
        size_variances = np.maximum((sizes.squares / count - mean**2) / LEVELS**2, 0.0)
    return KernelSums(kernel.counts(), variances, tuple(feature_map.bandwidth),
                      None if sizes is None else sizes.counts(), size_variances, noisy)


def size_values(residual: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``|r_j|`` in units of its pooled standard deviation ``scale`` (of all transitions'),
    rounded to 1 / LEVELS: integers, so their sums are exact."""
    return np.rint(LEVELS * np.abs(residual) / scale)


def _chunks(starts: np.ndarray, p0: int, p1: int):
    """(first, last) pair ranges of pairs p0:p1 of about ``CHUNK`` transitions each."""
    first = p0
    while first < p1:
        last = int(np.searchsorted(starts, starts[first] + CHUNK, side="right"))
        last = min(max(last - 1, first + 1), p1)
        yield first, last
        first = last


class _Target:
    """The (blocks · width) × units matrix of per-(state, unit) sums being written: dense
    where at least ``DENSE_SHARE`` of the positions hold a value (float32 where ``peak``
    bounds every entry and every difference of two entries below 2**24: exact), else the
    CSR arrays of :class:`_Layout`; and per block the column sums and sums of squares over
    the transitions."""

    def __init__(self, pairs: _Pairs, width: int, n_units: int, peak: int | None) -> None:
        n_blocks = len(pairs.blocks)
        self.pairs, self.width, self.n_units = pairs, width, n_units
        self.totals = np.zeros((n_blocks, width))
        self.squares = np.zeros((n_blocks, width - 1))
        self.layout, self.matrix = None, None
        if len(pairs.unit) >= DENSE_SHARE * n_units * n_blocks:
            dtype = np.float32 if peak is not None and peak < 2**24 else np.float64
            self.matrix = np.zeros((n_blocks * width, n_units), dtype)
        else:
            self.layout = _Layout(pairs, width, n_units)

    def put(self, b: int, column: int, first: int, last: int, sums: np.ndarray,
            values: np.ndarray | None = None) -> None:
        """Pair sums (pairs first:last of block b, k) at columns column:column + k; ``values``:
        the transitions' values they sum (for the squares; None for the count column)."""
        k = sums.shape[1]
        if self.matrix is not None:
            row = b * self.width + column
            self.matrix[row:row + k, self.pairs.unit[first:last]] = sums.T
        else:
            p0 = self.layout.first[b]
            self.layout.view(b)[column:column + k, first - p0:last - p0] = sums.T
        self.totals[b, column:column + k] += sums.sum(axis=0)
        if values is not None:
            self.squares[b, column - 1:column - 1 + k] += np.einsum("ij,ij->j", values, values)

    def counts(self) -> RunCounts:
        if self.layout is not None:
            return self.layout.counts()
        n_blocks = len(self.pairs.blocks)
        return RunCounts(self.matrix, self.pairs.blocks, np.arange(n_blocks + 1) * self.width,
                         np.zeros(n_blocks * self.width, dtype=np.int64))


class _Layout:
    """The CSR arrays of the (blocks · width) × units matrix of per-pair sums: block ``b``'s
    entries are one (width, pairs of b) array, row by row, each row's units ascending."""

    def __init__(self, pairs: _Pairs, width: int, n_units: int) -> None:
        n_blocks = len(pairs.blocks)
        per_block = np.bincount(pairs.block, minlength=n_blocks)
        self.first = np.r_[0, np.cumsum(per_block)]
        nnz = len(pairs.unit) * width
        index = np.int32 if max(nnz, n_units) < 2**31 else np.int64
        self.data = np.empty(nnz)
        self.indices = np.empty(nnz, dtype=index)
        self.indptr = np.r_[0, np.cumsum(np.repeat(per_block, width))].astype(index)
        self.pairs, self.width, self.n_units = pairs, width, n_units
        for b in range(n_blocks):
            self._segment(self.indices, b)[:] = pairs.unit[self.first[b]:self.first[b + 1]]

    def _segment(self, array: np.ndarray, b: int) -> np.ndarray:
        lo, hi = self.first[b] * self.width, self.first[b + 1] * self.width
        return array[lo:hi].reshape(self.width, -1)

    def view(self, b: int) -> np.ndarray:
        """(width, pairs of block b): the writable entries of block ``b``."""
        return self._segment(self.data, b)

    def counts(self) -> RunCounts:
        n_blocks = len(self.pairs.blocks)
        matrix = sp.csr_matrix((self.data, self.indices, self.indptr),
                               shape=(n_blocks * self.width, self.n_units))
        return RunCounts(matrix, self.pairs.blocks, np.arange(n_blocks + 1) * self.width,
                         np.zeros(n_blocks * self.width, dtype=np.int64))


def unit_sums(data: Transitions, columns: np.ndarray, n_units: int) -> RunCounts:
    """Per state a block of ``columns.shape[1]`` rows, per unit the column sums over its
    transitions in that state: a sparse (blocks · width) × units matrix."""
    pairs = _Pairs.of(data)
    sums = np.add.reduceat(columns, pairs.starts[:-1], axis=0)
    layout = _Layout(pairs, columns.shape[1], n_units)
    for b in range(len(pairs.blocks)):
        layout.view(b)[:] = sums[layout.first[b]:layout.first[b + 1]].T
    return layout.counts()


def response_test(data: Transitions, n_units: int, assignments: np.ndarray,
                  rng: np.random.Generator) -> ResponseOutcome:
    """The response test of the chain and of every state (module docs).

    ``assignments``: (P + 1, units) bool, row 0 the observed one (:meth:`Design.assignments`);
    ``rng``: the source of the dither, the Fourier features and the bandwidth pairs.
    """
    kernel = kernel_sums(data, n_units, rng)
    n_features = len(data.response)
    stats, pooled, m, n = assignment_statistics(kernel.counts, assignments, n_features,
                                                kernel.variances, data.profile)
    z, in_family = standardise(stats, OneSided.NEUTRAL)
    chain = chain_statistic(standardise(pooled, OneSided.NEUTRAL)[0], n_features,
                            spread_statistics(kernel, data, assignments))
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


def spread_statistics(kernel: KernelSums, data: Transitions, assignments: np.ndarray
                      ) -> np.ndarray | None:
    """(P + 1, features) standardised spread statistics ``S_j``, 0 for a response below the
    noise floor; None when no response has noise of its own (module docs; ``kernel`` holds
    the size sums only then, :func:`kernel_sums`)."""
    noisy = kernel.noisy
    if noisy is None or not noisy.any():
        return None
    _, pooled, _, _ = assignment_statistics(kernel.sizes, assignments, len(data.response),
                                            kernel.size_variances, dims=1)
    return standardise(pooled, OneSided.NEUTRAL)[0] * noisy


def chain_statistic(z: np.ndarray, n_features: int, spread: np.ndarray | None = None
                    ) -> np.ndarray:
    """The chain statistic of every assignment from the standardised pooled statistics
    (P + 1, K · features) and spread statistics (P + 1, features): Tippett's combination of
    each feature's ``max(T_j, S_j)`` (``T_j`` where ``S_j`` is 0: no noise of its own) and the
    sum of the profile statistics (module docs); larger = more extreme."""
    level = [z[:, j] if spread is None or not spread[:, j].any()
             else np.maximum(z[:, j], spread[:, j]) for j in range(n_features)]
    if z.shape[1] == n_features:
        return tippett(*level)
    return tippett(*level, z[:, n_features:].sum(axis=1))


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
                          variances: np.ndarray, profile: np.ndarray | None = None,
                          dims: int = FOURIER
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Statistics of every assignment: (P + 1, blocks · features) per-state ``T_s,j``,
    (P + 1, K · features) pooled studentised ``T_k,j`` (k = 0: ``T_j``; then one block of
    features per profile contrast, :func:`contrasts`), and the observed m, n per block.
    ``dims``: columns per response feature in ``sums`` (``FOURIER``; 1 for the sizes)."""
    sides = DenseSides if isinstance(sums.matrix, np.ndarray) else SideCounts
    product = sides(sums, paired=is_paired(assignments))
    width = 1 + n_features * dims
    totals = np.asarray(sums.matrix.sum(axis=1, dtype=np.float64)).ravel()
    share = totals[0::width] / max(totals[0::width].sum(), 1.0)
    weights = contrasts(share, profile) * share  # (K, blocks)
    per_state = np.empty((len(assignments), len(sums.blocks), n_features))
    pooled = np.zeros((len(weights), n_features * dims, len(assignments)))
    spread = np.zeros((len(weights), n_features, len(assignments)))
    batch = int(np.clip(BATCH_BUDGET // max(*sums.matrix.shape, 1), 8, 1024))
    for first, last, lo, hi in product.chunks:
        rows = product.rows(lo, hi)
        for start in range(0, len(assignments), batch):
            side_a = product.product(rows, assignments[start:start + batch])
            value, diff, inverse = _statistic(side_a.reshape(last - first, width, -1),
                                              totals[lo:hi].reshape(last - first, width),
                                              n_features, dims)
            here, weight = slice(start, start + batch), weights[:, first:last]
            per_state[here, first:last] = value.transpose(2, 0, 1)
            pooled[:, :, here] += np.einsum("ks,sdb->kdb", weight, diff)
            spread[:, :, here] += np.einsum("ks,sj,sb->kjb", weight**2, variances[first:last],
                                            inverse)
    observed = sums.matrix[0::width] @ assignments[0].astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        studentised = ((pooled.reshape(len(weights), n_features, dims, -1) ** 2).sum(axis=2)
                       / LEVELS**2 / spread).reshape(len(weights) * n_features, -1).T
    return (per_state.reshape(len(assignments), -1), studentised,
            observed.astype(np.int64), (totals[0::width] - observed).astype(np.int64))


def _statistic(side_a: np.ndarray, totals: np.ndarray, n_features: int, dims: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per block and assignment: ``m n / (m + n) · ‖μ_A,j − μ_B,j‖²`` (blocks, features, batch),
    ``μ_A − μ_B`` (blocks, features · dims, batch) and ``1/m + 1/n`` (blocks, batch); the
    last two 0 and the first NaN where a side is empty."""
    m = side_a[:, 0, :]
    n = totals[:, :1] - m
    empty = (m < 1) | (n < 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = side_a[:, 1:, :] / m[:, None, :] \
            - (totals[:, 1:, None] - side_a[:, 1:, :]) / n[:, None, :]
        per_feature = (diff**2).reshape(len(m), n_features, dims, -1).sum(axis=2)
        value = (m * n / (m + n))[:, None, :] * per_feature / LEVELS**2
        inverse = np.where(empty, 0.0, 1.0 / m + 1.0 / n)
    value[np.broadcast_to(empty[:, None, :], value.shape)] = np.nan
    diff[np.broadcast_to(empty[:, None, :], diff.shape)] = 0.0
    return value, diff, inverse
