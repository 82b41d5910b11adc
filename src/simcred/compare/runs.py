"""Run-level permutation inference: whole runs are reassigned between the two sets.

The per-transition tests of Neurohr et al. 2023 [1] (sec. IV-B) treat every transition as an
independent sample. Transitions of one run are not independent (self-loops at small sample
periods, per-run traits, history and time phase outside the features), which makes those tests
reject far more often than their nominal level on same-model data. Here the null distribution comes
from permuting the *run labels*: under H0 (both sets are exchangeable samples of runs of one
process) every assignment of the pooled runs to a set of size ``n_A`` is equally likely, whatever
the dependence within a run [2].

Everything is computed from counts. ``R`` is the sparse (columns × runs) matrix of how often run
``r`` shows the pair (state s, successor u); column block 0 is the start distribution (successor =
a run's first state), block ``b ≥ 1`` the successors of one start state. For a batch of permutations
given as a 0/1 matrix ``Z`` (runs × batch, ``n_A`` ones per column) the A-side counts of every
state, successor and permutation are the one sparse product ``R @ Z``; the B side is the total
minus that. The per-state MMD is the one of [1] with one fixed bandwidth per state (the median of
the pooled sample's pairwise distances, which no permutation changes), so a state's kernel matrix
is fixed and each permutation costs one application of it.

The per-state *test statistic* is the MMD scaled by its sample sizes, ``T_s = √(m n / (m + n)) ·
MMD_b`` (``m n / (m + n) · MMD²_u`` for the unbiased estimator), recomputed for every permutation
with that permutation's ``m`` and ``n``. The null spread of the plain MMD shrinks like
``√(1/m + 1/n)``; when the two sets' runs have different lengths the observed split has far more
extreme ``m``/``n`` than the permutations, and the plain MMD would reject a same-process pair for
that alone. The scaled statistic's null distribution does not depend on ``m``, ``n`` to first
order. The reported per-state ``statistic`` stays the plain MMD of the observed split.

A state that one set never leaves (one-sided) gets, in every permutation where a side is empty,
the largest two-sided value of that state's statistic over all P + 1 assignments (``EVIDENCE``):
at least as extreme as any two-sided split, and a function of the multiset of assignments only,
so the test stays exact; or its permutation mean (``NEUTRAL``).

Chain level [3]: each state's statistics over the permutations (observed included) are standardised
by their mean and standard deviation over those permutations; the chain statistic is the sum (or
the maximum) of the standardised statistics over all states, the start distribution included; its
p-value is ``(1 + #{T*_chain ≥ T_chain}) / (P + 1)`` [4]. Per-state verdicts are family-wise
controlled by the single-step max-T adjustment [5] or FDR-controlled by Benjamini–Hochberg [6].

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
[2] Good, Permutation, Parametric, and Bootstrap Tests of Hypotheses, 3rd ed., Springer, 2005.
[3] Pesarin & Salmaso, Permutation Tests for Complex Data, Wiley, 2010 (nonparametric
    combination).
[4] Phipson & Smyth, Permutation P-values Should Never Be Zero, SAGMB 9, 2010.
[5] Westfall & Young, Resampling-Based Multiple Testing, Wiley, 1993.
[6] Benjamini & Hochberg, Controlling the False Discovery Rate, JRSS B 57, 1995.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from simcred.compare.kernels import Kernel, KernelOperator, pooled_bandwidth
from simcred.compare.mmd import Estimator, kernel_statistics
from simcred.compare.run_counts import RunCounts, matvec, row_sums
from simcred.compare.side_counts import SideCounts

#: Elements of one dense (columns × batch) or (runs × batch) array of a permutation batch.
BATCH_BUDGET = 2**22
#: Absolute/relative tolerance when counting permuted statistics ≥ the observed one.
TIE_TOL = 1e-9
#: ``dᵀKd`` below this is rounding noise of an exact 0 (|error| ≲ 4·eps) and is set to 0 before
#: the square root, so that permutations with proportional counts tie with each other exactly.
QUADRATIC_FLOOR = 1e-13


class Multiplicity(StrEnum):
    FWER = "fwer"
    FDR = "fdr"
    NONE = "none"


class ChainStatistic(StrEnum):
    SUM = "sum"
    MAX = "max"


class OneSided(StrEnum):
    """What a state contributes to a permutation in which one set has no transition from it."""

    EVIDENCE = "evidence"  # the state's largest two-sided value: a one-sided state differs
    NEUTRAL = "neutral"  # its permutation mean: no evidence either way


@dataclass(frozen=True, slots=True)
class RunTestSpec:
    """Settings of the run-level test."""

    kernel: Kernel
    estimator: Estimator
    permutations: int
    alpha: float
    multiplicity: Multiplicity = Multiplicity.FWER
    chain: ChainStatistic = ChainStatistic.SUM
    one_sided: OneSided = OneSided.EVIDENCE


@dataclass(frozen=True, slots=True, eq=False)
class RunLevelOutcome:
    """Observed per-state quantities (one entry per block, block 0 = start) and the chain verdict.

    ``m``/``n``: transitions (start block: runs) in A and B. ``statistic``: observed MMD, not
    scaled (NaN when one side is empty); ``scaled``: the test statistic ``√(mn/(m+n))·MMD_b``
    (unbiased: ``mn/(m+n)·MMD²_u``). ``pvalue``: per-state run-permutation p-value;
    ``adjusted``: after the multiplicity adjustment (FWER: max-T adjusted p; FDR: BH-adjusted p;
    none: = ``pvalue``).
    ``in_family``: the state's statistic varies over the permutations (others cannot reject).
    """

    blocks: np.ndarray
    m: np.ndarray
    n: np.ndarray
    statistic: np.ndarray
    scaled: np.ndarray
    bandwidth: np.ndarray
    pvalue: np.ndarray
    adjusted: np.ndarray
    in_family: np.ndarray
    chain_statistic: float
    chain_pvalue: float
    permutations: int

    def rejected(self, alpha: float) -> np.ndarray:
        return self.in_family & (self.adjusted <= alpha)


def run_level_test(counts: RunCounts, in_a: np.ndarray, grid_of, spec: RunTestSpec,
                   n_bins: tuple[int, ...], rng: np.random.Generator | None,
                   null: np.ndarray | None = None,
                   draw: AssignmentDraw | None = None) -> RunLevelOutcome:
    """Run-permutation test of every state and of the chain ([1] sec. IV-A, R1 and R2).

    Parameters
    ----------
    counts : RunCounts
        Per-run pair counts of the pooled runs.
    in_a : ndarray of bool, shape (runs,)
        The observed assignment: True for the runs of set A.
    grid_of : callable
        Maps state codes to their integer bin-index vectors (``StateSpace.decode``).
    spec : RunTestSpec
    n_bins : tuple of int
        Bins per coordinate of a state vector (scale of the linear kernel).
    rng : numpy.random.Generator or None
        Source of the permutations (``spec.permutations`` of them).
    null : ndarray of bool, shape (P, runs), optional
        Given assignments to use as the null instead of random ones (e.g. every split: an exact
        enumeration); ``rng`` and ``spec.permutations`` are then ignored.
    draw : AssignmentDraw, optional
        The assignments ``rng`` would give, drawn before for tests of this size: used where they
        fit (:meth:`AssignmentDraw.fits`), else drawn here.
    """
    in_a = np.asarray(in_a, dtype=bool)
    states = StateModels.build(counts, grid_of, spec, n_bins)
    if null is None and draw is not None and draw.fits(in_a, spec.permutations,
                                                       counts.matrix.shape[0]):
        assignments = draw.assignments
    elif null is None:
        assignments = PackedAssignments.random(in_a, spec.permutations, counts.matrix.shape[0],
                                               rng)
    else:
        assignments = np.vstack([in_a[None, :], np.asarray(null, dtype=bool)])
    stats = assignment_statistics(counts, states, assignments, spec.estimator,
                                  batch_size(*counts.matrix.shape))
    z, in_family = standardise(stats, spec.one_sided)
    chain = z[:, in_family].sum(axis=1) if spec.chain is ChainStatistic.SUM \
        else row_max(z[:, in_family])
    pvalue = exceedance_pvalues(z, z[0])
    if spec.multiplicity is Multiplicity.FWER:
        adjusted = exceedance_pvalues(row_max(z[:, in_family])[:, None], z[0])
    else:
        adjusted = pvalue.copy()
    adjusted[~in_family] = 1.0
    if spec.multiplicity is Multiplicity.FDR:
        adjusted = benjamini_hochberg(adjusted, in_family)
    observed_a = matvec(counts.matrix, in_a)
    m = np.add.reduceat(observed_a, counts.bounds[:-1])
    n = states.totals - m
    return RunLevelOutcome(
        blocks=counts.blocks, m=m.astype(np.int64), n=n.astype(np.int64),
        statistic=stats[0] / _size_factor(m, n, spec.estimator), scaled=stats[0],
        bandwidth=states.bandwidths, pvalue=pvalue, adjusted=adjusted, in_family=in_family,
        chain_statistic=float(chain[0]), chain_pvalue=float(exceedance_pvalues(
            chain[:, None], np.array([chain[0]]))[0]),
        permutations=len(assignments) - 1)


def exceedance_pvalues(null: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """``(1 + #{i ≥ 1 : null[i, j] ≥ observed[j]}) / rows`` ([4]); row 0 is the observed one.

    ``null`` has shape (P + 1, k) with k = 1 (one null for all, as in max-T) or k = len(observed).
    Ties within ``TIE_TOL`` (absolute and relative) count as exceedances.
    """
    tolerance = TIE_TOL * np.maximum(1.0, np.abs(observed))
    hits = (null[1:] >= observed[None, :] - tolerance).sum(axis=0)
    return (1.0 + hits) / len(null)


def benjamini_hochberg(pvalues: np.ndarray, family: np.ndarray) -> np.ndarray:
    """BH-adjusted p-values ([6]) over the entries in ``family``; 1 elsewhere."""
    out = np.ones_like(pvalues)
    p = pvalues[family]
    if len(p) == 0:
        return out
    order = np.argsort(p, kind="stable")
    ranked = p[order] * len(p) / np.arange(1, len(p) + 1)
    adjusted = np.minimum(np.minimum.accumulate(ranked[::-1])[::-1], 1.0)
    result = np.empty_like(p)
    result[order] = adjusted
    out[family] = result
    return out


def row_max(z: np.ndarray) -> np.ndarray:
    return z.max(axis=1) if z.shape[1] else np.zeros(len(z))


@dataclass(frozen=True, slots=True, eq=False)
class StateModels:
    """Per block: kernel operator, pooled bandwidth and totals."""

    operators: tuple[KernelOperator, ...]
    bandwidths: np.ndarray
    totals: np.ndarray
    column_totals: np.ndarray

    @classmethod
    def build(cls, counts: RunCounts, grid_of, spec: RunTestSpec, n_bins) -> StateModels:
        column_totals = row_sums(counts.matrix)
        operators, bandwidths = [], []
        for lo, hi in zip(counts.bounds[:-1], counts.bounds[1:], strict=True):
            grid = grid_of(counts.successors[lo:hi])
            sigma = pooled_bandwidth(grid, column_totals[lo:hi], spec.kernel) \
                if spec.kernel.has_bandwidth else None
            operators.append(KernelOperator(grid, spec.kernel, sigma, n_bins))
            bandwidths.append(np.nan if sigma is None else sigma)
        totals = np.add.reduceat(column_totals, counts.bounds[:-1])
        return cls(tuple(operators), np.array(bandwidths), totals, column_totals)


def batch_size(*dimensions: int) -> int:
    """Assignments per batch: depends only on the data's dimensions."""
    return int(np.clip(BATCH_BUDGET // max(*dimensions, 1), 8, 1024))


def random_assignments(in_a: np.ndarray, permutations: int, n_cols: int,
                       rng: np.random.Generator) -> np.ndarray:
    """(P + 1, runs) bool assignments; row 0 is ``in_a``, the others uniform permutations of it.

    Drawn in batches whose size depends only on the data's dimensions, each batch one
    ``Generator.permuted`` call.
    """
    assignments = np.empty((permutations + 1, len(in_a)), dtype=bool)
    for start, rows in _assignment_batches(in_a, permutations, n_cols, rng):
        assignments[start:start + len(rows)] = rows
    return assignments


def _assignment_batches(in_a: np.ndarray, permutations: int, n_cols: int,
                        rng: np.random.Generator):
    """(first row, bool rows) of :func:`random_assignments`, batch by batch."""
    total, n_runs = permutations + 1, len(in_a)
    batch = batch_size(n_cols, n_runs)
    pattern = np.sort(in_a)[::-1].copy()  # n_A ones, then zeros
    for start in range(0, total, batch):
        size = min(batch, total - start)
        rows = rng.permuted(np.broadcast_to(pattern, (size, n_runs)), axis=1)
        if start == 0:
            rows[0] = in_a
        yield start, rows


@dataclass(frozen=True, slots=True, eq=False)
class PackedAssignments:
    """(k, runs) bool assignments held as bits (``numpy.packbits`` along the runs: one eighth
    of the bytes); a slice of rows unpacks to the bool rows (``assignments[start:stop]``)."""

    bits: np.ndarray
    n_runs: int

    @classmethod
    def pack(cls, assignments: np.ndarray) -> PackedAssignments:
        assignments = np.asarray(assignments, dtype=bool)
        return cls(np.packbits(assignments, axis=1), assignments.shape[1])

    @classmethod
    def random(cls, in_a: np.ndarray, permutations: int, n_cols: int,
               rng: np.random.Generator) -> PackedAssignments:
        """:func:`random_assignments`, the same rows, packed batch by batch (the bool rows of
        all permutations are never held at once).
        """
        bits = np.empty((permutations + 1, (len(in_a) + 7) // 8), dtype=np.uint8)
        for start, rows in _assignment_batches(in_a, permutations, n_cols, rng):
            bits[start:start + len(rows)] = np.packbits(rows, axis=1)
        return cls(bits, len(in_a))

    def __len__(self) -> int:
        return len(self.bits)

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.bits), self.n_runs

    def __getitem__(self, rows: slice) -> np.ndarray:
        return np.unpackbits(self.bits[rows], axis=1, count=self.n_runs).view(bool)


@dataclass(frozen=True, slots=True, eq=False)
class AssignmentDraw:
    """The assignments a run-level test of ``n_runs`` runs, the first ``n_a`` in A, draws from
    a generator in a given state, drawn once for every test of that size (a distance matrix's
    pairs share a seed): :meth:`fits` says whether a test's own draw would be these rows."""

    n_a: int
    permutations: int
    batch: int
    assignments: PackedAssignments

    @classmethod
    def of(cls, n_a: int, n_runs: int, permutations: int,
           rng: np.random.Generator) -> AssignmentDraw:
        """The draw of a test whose count matrix has at most ``n_runs`` columns."""
        in_a = np.arange(n_runs) < n_a
        return cls(n_a, permutations, batch_size(n_runs),
                   PackedAssignments.random(in_a, permutations, 0, rng))

    def fits(self, in_a: np.ndarray, permutations: int, n_cols: int) -> bool:
        """Whether :meth:`PackedAssignments.random` of this test (a generator in the draw's
        state) gives these rows: the same observed split, permutations and batches (numpy's
        ``permuted`` shuffles row after row, so other batches would give the same rows too,
        but that is numpy's implementation, not its promise)."""
        n_a = int(in_a.sum())
        return (permutations == self.permutations and len(in_a) == self.assignments.n_runs
                and n_a == self.n_a and bool(in_a[:n_a].all())
                and batch_size(n_cols, len(in_a)) == self.batch)


def assignment_statistics(counts: RunCounts, states: StateModels,
                          assignment: np.ndarray | PackedAssignments, estimator: Estimator,
                          batch: int = 256) -> np.ndarray:
    """(k, blocks) size-scaled statistics of k assignments of runs to A (bool, (k, runs), or
    packed)."""
    product = SideCounts(counts)
    out = np.empty((len(assignment), len(counts.blocks)))
    for first, last, lo, hi in product.chunks:
        rows = None  # the last chunk's dense rows go before this one's are made
        rows = product.rows(lo, hi)
        for start in range(0, len(assignment), batch):
            side_a = product.product(rows, assignment[start:start + batch])
            for b in range(first, last):
                u0, u1 = counts.bounds[b] - lo, counts.bounds[b + 1] - lo
                out[start:start + batch, b] = _statistic(
                    side_a[u0:u1], states.column_totals[lo + u0:lo + u1], states.operators[b],
                    estimator)
    return out


def _statistic(a: np.ndarray, totals: np.ndarray, kernel: KernelOperator,
               estimator: Estimator) -> np.ndarray:
    """Scaled MMD of A-side counts ``a`` (U, batch) against the rest of ``totals`` (U,), per column.

    Biased: ``√(mn/(m+n)) · MMD_b``, ``MMD_b = √(dᵀ K d)``, ``d = a/m − (t − a)/n`` ([1] sec.
    IV-B). Unbiased: ``mn/(m+n) · MMD²_u`` ([2] of mmd.py, eq. 3). NaN where a side has too few
    samples.
    """
    m = a.sum(axis=0)
    n = totals.sum() - m
    small = (m < estimator.min_samples) | (n < estimator.min_samples)
    with np.errstate(invalid="ignore", divide="ignore"):  # empty sides: NaN below
        value = kernel_statistics(kernel, a, totals[:, None] - a, estimator, QUADRATIC_FLOOR)
        value *= _size_factor(m, n, estimator)
    value[small] = np.nan
    return value


def _size_factor(m: np.ndarray, n: np.ndarray, estimator: Estimator) -> np.ndarray:
    """``√(mn/(m+n))`` (biased MMD) or ``mn/(m+n)`` (unbiased MMD²): the statistic's null scale."""
    with np.errstate(invalid="ignore", divide="ignore"):
        harmonic = m * n / (m + n)
    return np.sqrt(harmonic) if estimator is Estimator.BIASED else harmonic


def standardise(stats: np.ndarray, one_sided: OneSided) -> tuple[np.ndarray, np.ndarray]:
    """Standardised statistics (P + 1, blocks) and the family of states that vary.

    One-sided entries (NaN) become, for ``EVIDENCE``, the state's largest two-sided value over
    all P + 1 rows or, for ``NEUTRAL``, the state's mean over the two-sided rows (z = 0). Both,
    like the mean and standard deviation, are over all P + 1 rows, the observed one included
    ([3]): functions of the set of assignments, not of which one is observed, so the test stays
    exact.
    """
    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns: never two-sided
        filled = np.where(np.isnan(stats), np.nanmax(stats, axis=0), stats) \
            if one_sided is OneSided.EVIDENCE else stats
        mean = np.nanmean(filled, axis=0) if one_sided is OneSided.NEUTRAL \
            else filled.mean(axis=0)
        sd = np.nanstd(filled, axis=0) if one_sided is OneSided.NEUTRAL else filled.std(axis=0)
    scale = np.maximum(np.abs(mean), 1.0)
    in_family = np.isfinite(sd) & (sd > TIE_TOL * scale)
    z = np.zeros_like(filled)
    z[:, in_family] = (filled[:, in_family] - mean[in_family]) / sd[in_family]
    z[np.isnan(z)] = 0.0
    return z, in_family
