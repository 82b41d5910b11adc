"""Many pairs of trace sets compared from small messages: each set sorted once, and a pair's
edges and counts computed where its sets are.

A distance matrix (:mod:`simcred.compare.pairwise`) compares every set with every other. The
run-level comparison of a pair (Neurohr et al. 2023 [1], sec. V-A) needs the equal-frequency
edges of the two sets' pooled values and, per run, the counts of (state, successor) pairs on
those edges. Both split by set, exactly:

* the edges by the two-pass order statistic of :mod:`simcred.compare.quantiles`: a
  :class:`~simcred.compare.quantiles.Sketch` per set (once), a
  :class:`~simcred.compare.quantiles.Tally` per set and pair; on a column sorted once both are
  binary searches, not passes over the data;
* the counts by set: the pooled (columns × runs) matrix is the two sets' matrices side by side
  (:func:`~simcred.compare.run_counts.joined_counts`), counted on the candidate edges and
  relabelled to the final ones as the out-of-core comparison does. A row's bin on a pair's
  edges is read from a table over the sorted order at the row's rank (kept with the set), so
  a side costs a gather per feature and a radix sort of 16-bit keys, not a search per row.

So a set is sorted and sketched once, on the worker that holds it; per pair only sketches,
tallies and the per-run count matrices travel (a few MB instead of two sets), and the pair's
test combines them. The result is the :class:`~simcred.compare.result.Comparison` of
:func:`~simcred.compare.process.compare_prepared`, byte for byte in JSON (tested), with the
out-of-core comparison's one caveat: an edge that is a zero order statistic may print as
``0.0`` where numpy's partition picked ``-0.0`` (every count is the same).

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.discretize import StateSpace, _check_size
from simcred.compare.encoding import code_dtype
from simcred.compare.process import Prepared
from simcred.compare.quantiles import EdgePlan, Sketch, Tally, sorted_bin_counts
from simcred.compare.result import Comparison, ComparisonOptions, InputInfo
from simcred.compare.run_counts import (
    RunCounts,
    count_dtype,
    joined_counts,
    keyed_counts,
    relabelled_keys,
)
from simcred.compare.run_level import counts_comparison
from simcred.compare.runs import AssignmentDraw

Tallies = tuple[Tally | None, ...]


def supports(options: ComparisonOptions) -> bool:
    """Whether a pair with ``options`` can be compared from its sets' parts (the run-level
    test on a first-order chain of the features as they are)."""
    return (options.test == "runs" and options.history == 1 and options.time_bins is None
            and options.resample is None and not options.inputs and options.pair_by is None
            and options.group_by is None and not options.margin)


@dataclass(frozen=True, slots=True, eq=False)
class SortedSet:
    """A prepared set with every feature's values also sorted, each row's rank in that order,
    and the sorted values' sketches."""

    prepared: Prepared
    ordered: tuple[np.ndarray, ...]
    ranks: tuple[np.ndarray, ...]
    sketches: tuple[Sketch, ...]

    @classmethod
    def of(cls, prepared: Prepared, bins: Sequence[int]) -> SortedSet:
        values = prepared.values
        index = np.int32 if len(values) < 2**31 else np.int64
        ordered, ranks = [], []
        for j in range(values.shape[1]):
            column = np.ascontiguousarray(values[:, j])
            order = np.argsort(column)  # ties in any order: they share every bin
            ordered.append(column[order])
            rank = np.empty(len(order), dtype=index)
            rank[order] = np.arange(len(order), dtype=index)
            ranks.append(rank)
        return cls(prepared, tuple(ordered), tuple(ranks),
                   tuple(Sketch.of_sorted(o, cap=b) for o, b in zip(ordered, bins, strict=True)))

    def __sizeof__(self) -> int:
        return object.__sizeof__(self) + self.prepared.__sizeof__() \
            + sum(a.nbytes for a in (*self.ordered, *self.ranks))

    def codes(self, candidates: Sequence[np.ndarray]) -> np.ndarray:
        """The rows' state codes on the grid of ``candidates`` (per feature, a value's bin is
        the number of edges at or below it: :func:`~simcred.compare.encoding.encode`'s codes),
        each bin read from a table over the sorted order at the row's rank: no search per row,
        and 2 bytes a row where the grid has at most 2**16 cells."""
        n_states = grid_states(candidates)
        dtype = np.uint16 if n_states <= 2**16 else code_dtype(n_states)
        codes = np.zeros(len(self.prepared.values), dtype=dtype)
        for c, o, rank in zip(candidates, self.ordered, self.ranks, strict=True):
            below = np.searchsorted(o, c, side="left")  # values under each edge
            by_rank = np.repeat(np.arange(len(c) + 1, dtype=dtype),
                                np.diff(np.r_[0, below, len(o)]))
            codes *= dtype(len(c) + 1)
            codes += by_rank[rank]
        return codes


def grid_states(candidates: Sequence[np.ndarray]) -> int:
    """Cells of the grid whose edges per feature are ``candidates``."""
    return int(np.prod([len(c) + 1 for c in candidates], dtype=np.int64))


@dataclass(frozen=True, slots=True, eq=False)
class PairPlan:
    """A pair's edges in the making, from its two sets' sketches: per feature the
    :class:`~simcred.compare.quantiles.EdgePlan` and the pooled (minimum, maximum)."""

    plans: tuple[EdgePlan, ...]
    bounds: tuple[tuple[float, float], ...]

    @classmethod
    def of(cls, a: Sequence[Sketch], b: Sequence[Sketch], bins: Sequence[int]) -> PairPlan:
        merged = [x.merge(y) for x, y in zip(a, b, strict=True)]
        return cls(tuple(EdgePlan.of(s, n) for s, n in zip(merged, bins, strict=True)),
                   tuple((float(s.minimum), float(s.maximum)) for s in merged))

    def tallies(self, side: SortedSet) -> Tallies:
        """One set's tallies of the brackets (None where the plan needs none)."""
        return tuple(p.brackets.tally_sorted(o) if p.needs_counts else None
                     for p, o in zip(self.plans, side.ordered, strict=True))

    def candidates(self, a: Tallies, b: Tallies) -> tuple[np.ndarray, ...]:
        """Per feature the distinct pooled quantiles (or midpoints), exactly."""
        return tuple(p.candidates(None if x is None else x.merge(y))
                     for p, x, y in zip(self.plans, a, b, strict=True))


@dataclass(frozen=True, slots=True, eq=False)
class PairSide:
    """One set's part of a pair: its per-run counts on the pair's candidate grid (``matrix``:
    columns × runs, ``columns``: their pair keys), per feature its values per candidate bin,
    and what the pair's test needs of the plan (both sides carry the same)."""

    counts: np.ndarray  # the matrix's CSR arrays in the smallest integer types (it travels)
    runs: np.ndarray
    indptr: np.ndarray
    n_runs: int
    columns: np.ndarray
    held: tuple[np.ndarray, ...]
    info: InputInfo
    candidates: tuple[np.ndarray, ...]
    bounds: tuple[tuple[float, float], ...]
    quantiles: tuple[bool, ...]  # per feature: candidates are quantiles (else midpoints)

    @classmethod
    def compact(cls, matrix: sp.csr_matrix, *rest) -> PairSide:
        counts = matrix.data.astype(np.min_scalar_type(int(matrix.data.max(initial=0))))
        runs = matrix.indices.astype(np.min_scalar_type(max(matrix.shape[1] - 1, 0)))
        return cls(counts, runs, matrix.indptr, matrix.shape[1], *rest)

    def __sizeof__(self) -> int:
        """Bytes held (Dask weighs transfers by it)."""
        return object.__sizeof__(self) + sum(a.nbytes for a in (
            self.counts, self.runs, self.indptr, self.columns, *self.held, *self.candidates))

    @property
    def matrix(self) -> sp.csr_matrix:
        """The (columns × runs) counts as counted (in :func:`~simcred.compare.run_counts.
        count_dtype`), int32 run indices."""
        return sp.csr_matrix((self.counts.astype(count_dtype(self.counts)),
                              self.runs.astype(np.int32),
                              self.indptr), shape=(len(self.indptr) - 1, self.n_runs))


def pair_side(side: SortedSet, plan: PairPlan, a: Tallies, b: Tallies) -> PairSide:
    """One set's counts on the pair's candidate edges (from both sets' tallies)."""
    candidates = plan.candidates(a, b)
    p = side.prepared
    matrix, columns = keyed_counts([(side.codes(candidates), p.offsets)],
                                   grid_states(candidates))
    held = tuple(sorted_bin_counts(c, o) for c, o in zip(candidates, side.ordered, strict=True))
    return PairSide.compact(matrix, columns, held, p.info, candidates, plan.bounds,
                              tuple(p.needs_counts for p in plan.plans))


def pair_comparison(a: PairSide, b: PairSide, options: ComparisonOptions,
                    draw: AssignmentDraw | None = None) -> Comparison:
    """The run-level comparison of the pair from its two sides: quantile edges whose left bin
    holds no value of either set dropped (``feature_edges``), keys relabelled to the rest;
    ``draw``: the test's permutations drawn before, where they fit (``counts_comparison``)."""
    kept = [(x + y)[:-1] > 0 if q else np.ones(len(c), dtype=bool)
            for c, x, y, q in zip(a.candidates, a.held, b.held, a.quantiles, strict=True)]
    space = StateSpace(options.features, tuple(c[k] for c, k in zip(a.candidates, kept,
                                                                       strict=True)),
                       a.bounds)
    _check_size(space)
    matrix, keys = joined_counts([(a.matrix, a.columns), (b.matrix, b.columns)])
    keys = relabelled_keys(keys, tuple(len(c) + 1 for c in a.candidates), kept, space.shape)
    counts = RunCounts.from_matrix(matrix, keys, space.n_states)
    return counts_comparison(counts, a.n_runs, space, options, (a.info, b.info), draw)


def compare_sorted(a: SortedSet, b: SortedSet, options: ComparisonOptions,
                   draw: AssignmentDraw | None = None) -> Comparison:
    """All steps of one pair in one place (in-process)."""
    plan = PairPlan.of(a.sketches, b.sketches, options.bins)
    tallies = plan.tallies(a), plan.tallies(b)
    return pair_comparison(pair_side(a, plan, *tallies), pair_side(b, plan, *tallies), options,
                           draw)
