"""Exact quantiles of data that is never held at once: a mergeable two-pass order statistic.

The equal-frequency edges of Neurohr et al. 2023 [1], sec. V-A are quantiles of the pooled values
of both trace sets. Out of core (:mod:`simcred.compare.outofcore`) the values arrive partition by
partition, and the edges must be the ones :func:`~simcred.compare.discretize.feature_edges` gives
on the concatenated values, bit for bit. Two passes give exact order statistics ([2], the
"two-pass selection" of distributed quantiles; here the sketch is a deterministic rank sample):

1. Every partition yields a :class:`Sketch`: count, minimum, maximum, its distinct values while
   there are few, and about ``size`` of its sorted values with their ranks, stored as rank
   increments so that sketches merge by concatenation (any order, any grouping: a tree of
   workers merges them as well as one loop). For a value ``x`` the merged sketch bounds
   ``#{v < x}`` from above and ``#{v ≤ x}`` from below (:meth:`Sketch.brackets`), so for every
   wanted rank ``k`` it gives values ``lower ≤ w[k] ≤ upper`` of the sorted pooled data ``w``.
2. Every partition yields a :class:`Tally` of those brackets: how many values lie below
   ``lower``, how many equal ``lower`` and ``upper``, and the few values strictly between.
   Merged (by addition and concatenation), the tallies place ``w[k]`` exactly
   (:meth:`Tally.order_statistics`). Between the bounds lie at most about ``2 N / size`` values
   per bracket for ``N`` values in all (each partition's sampled ranks are at most
   ``n / size`` apart), so pass 2 holds a few per mille of the data, never the data.

:func:`linear_quantiles` then repeats numpy's ``method="linear"`` (virtual index ``(n-1)·q``,
its two-sided lerp) on those order statistics, so ``numpy.quantile`` is reproduced bit for bit;
:class:`EdgePlan` adds the two amendments of ``feature_edges`` (at most ``B`` distinct values:
midpoints; edges whose left bin holds no value: dropped, from per-bin counts of a later pass).

Notes
-----
Deviations: the sign of a zero order statistic (``-0.0`` or ``0.0``) is the one of a value in
the data but not necessarily the one numpy's partition would have picked; the two compare
equal, so bin indices and every count downstream are the same (only a printed edge ``-0.0``
can differ). ``DISTINCT_PROBE`` of ``feature_edges`` is a shortcut that never changes its
result (the probe's distinct values are a subset of the column's), so it is not repeated.

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
[2] Munro & Paterson, Selection and sorting with limited storage, Theoretical Computer Science
    12(3), 1980 (multi-pass selection with a sample of ranks).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

#: Sampled ranks per partition in pass 1; pass 2 holds about 2 N / SKETCH_SIZE values per rank.
SKETCH_SIZE = 4096


@dataclass(frozen=True, slots=True, eq=False)
class Sketch:
    """Pass-1 summary of one column's values (one partition, or any merged group of them).

    ``values[e]`` is a sampled value of some partition; ``below[e]`` the rank gap to the next
    sampled value of that partition (to its end for the last), ``upto[e]`` the rank gap from
    the previous one (its rank + 1 for the first). Then, for every ``x``,
    ``#{v < x} ≤ Σ_{values[e] < x} below[e]`` and ``#{v ≤ x} ≥ Σ_{values[e] ≤ x} upto[e]``.
    ``distinct``: the sorted distinct values if there are at most ``cap`` of them, else None.
    """

    count: int
    minimum: float
    maximum: float
    values: np.ndarray
    below: np.ndarray
    upto: np.ndarray
    distinct: np.ndarray | None
    cap: int

    @classmethod
    def empty(cls, cap: int) -> Sketch:
        none = np.empty(0, dtype=np.int64)
        return cls(0, np.inf, -np.inf, np.empty(0), none, none, np.empty(0), int(cap))

    @classmethod
    def of(cls, values: np.ndarray, *, cap: int, size: int = SKETCH_SIZE) -> Sketch:
        """The sketch of one partition's (finite, float64) values; ``cap``: the most distinct
        values to keep (the number of bins), ``size``: sampled ranks (at least 2)."""
        return cls.of_sorted(np.sort(np.asarray(values, dtype=np.float64), kind="stable"),
                             cap=cap, size=size)

    @classmethod
    def of_sorted(cls, ordered: np.ndarray, *, cap: int, size: int = SKETCH_SIZE) -> Sketch:
        """:meth:`of` on values already sorted (float64)."""
        n = len(ordered)
        if n == 0:
            return cls.empty(cap)
        ranks = np.unique(np.linspace(0, n - 1, min(n, max(size, 2))).astype(np.int64))
        below = np.diff(np.r_[ranks, n])
        upto = np.diff(np.r_[-1, ranks])
        new = np.r_[True, ordered[1:] != ordered[:-1]]
        distinct = ordered[new] if np.count_nonzero(new) <= cap else None
        return cls(n, float(ordered[0]), float(ordered[-1]), ordered[ranks], below, upto,
                   distinct, int(cap))

    def __sizeof__(self) -> int:
        """Bytes held (Dask weighs transfers by it)."""
        return object.__sizeof__(self) + sum(a.nbytes for a in (
            self.values, self.below, self.upto, self.distinct) if a is not None)

    def merge(self, other: Sketch) -> Sketch:
        """The sketch of both groups of values together (commutative and associative)."""
        cap = min(self.cap, other.cap)
        distinct = None
        if self.distinct is not None and other.distinct is not None:
            distinct = np.union1d(self.distinct, other.distinct)
            distinct = distinct if len(distinct) <= cap else None
        return Sketch(self.count + other.count, min(self.minimum, other.minimum),
                      max(self.maximum, other.maximum), np.r_[self.values, other.values],
                      np.r_[self.below, other.below], np.r_[self.upto, other.upto], distinct,
                      cap)

    def brackets(self, ranks: Sequence[int]) -> Brackets:
        """Per 0-based rank ``k`` of the sorted values, ``lower ≤ w[k] ≤ upper``.

        ``lower``: the largest sampled value ``x`` whose bound on ``#{v < x}`` is at most ``k``
        (so at most ``k`` values lie below it); ``upper``: the smallest sampled ``x`` whose bound
        on ``#{v ≤ x}`` is at least ``k + 1``. The minimum and maximum of every partition are
        sampled, so both exist.
        """
        ranks = np.asarray(ranks, dtype=np.int64)
        if len(ranks) and (ranks.min() < 0 or ranks.max() >= self.count):
            raise ValueError(f"ranks must lie in [0, {self.count}), got {ranks.tolist()}")
        order = np.argsort(self.values, kind="stable")
        values = self.values[order]
        less = np.r_[0, np.cumsum(self.below[order])]
        at_most = np.r_[0, np.cumsum(self.upto[order])]
        less_bound = less[np.searchsorted(values, values, side="left")]  # nondecreasing
        at_most_bound = at_most[np.searchsorted(values, values, side="right")]
        lower = values[np.searchsorted(less_bound, ranks, side="right") - 1]
        upper = values[np.searchsorted(at_most_bound, ranks + 1, side="left")]
        return Brackets(ranks, lower, upper)


@dataclass(frozen=True, slots=True, eq=False)
class Brackets:
    """Wanted ranks and, per rank, values known to enclose the order statistic."""

    ranks: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def tally(self, values: np.ndarray) -> Tally:
        """Pass 2 on one partition's values."""
        return self.tally_sorted(np.sort(np.asarray(values, dtype=np.float64), kind="stable"))

    def tally_sorted(self, ordered: np.ndarray) -> Tally:
        """:meth:`tally` on values already sorted (float64)."""
        lo_left = np.searchsorted(ordered, self.lower, side="left")
        lo_right = np.searchsorted(ordered, self.lower, side="right")
        hi_left = np.searchsorted(ordered, self.upper, side="left")
        hi_right = np.searchsorted(ordered, self.upper, side="right")
        wide = self.upper > self.lower
        inside = tuple(ordered[a:b] if w else ordered[:0]
                       for a, b, w in zip(lo_right, hi_left, wide, strict=True))
        return Tally(lo_left.astype(np.int64), (lo_right - lo_left).astype(np.int64),
                     np.where(wide, hi_right - hi_left, 0).astype(np.int64), inside)

    def empty_tally(self) -> Tally:
        zero = np.zeros(len(self.ranks), dtype=np.int64)
        return Tally(zero, zero, zero, tuple(np.empty(0) for _ in self.ranks))


@dataclass(frozen=True, slots=True, eq=False)
class Tally:
    """Pass-2 counts of :class:`Brackets`: per bracket, values below ``lower``, equal to
    ``lower``, equal to ``upper`` (when ``upper > lower``), and the values strictly between."""

    below: np.ndarray
    at_lower: np.ndarray
    at_upper: np.ndarray
    inside: tuple[np.ndarray, ...]

    def __sizeof__(self) -> int:
        return object.__sizeof__(self) + sum(a.nbytes for a in (
            self.below, self.at_lower, self.at_upper, *self.inside))

    def merge(self, other: Tally) -> Tally:
        return Tally(self.below + other.below, self.at_lower + other.at_lower,
                     self.at_upper + other.at_upper,
                     tuple(np.r_[a, b] for a, b in zip(self.inside, other.inside, strict=True)))

    def order_statistics(self, brackets: Brackets) -> np.ndarray:
        """``w[k]`` for every wanted rank ``k``: exact, from the merged tally of all values."""
        out = np.empty(len(brackets.ranks))
        for i, k in enumerate(brackets.ranks):
            r = int(k - self.below[i])
            inside = self.inside[i]
            if r < 0 or r >= self.at_lower[i] + len(inside) + self.at_upper[i]:
                raise ValueError(f"rank {int(k)} is outside its bracket: the tallies do not "
                                 "cover the sketched values")
            if r < self.at_lower[i]:
                out[i] = brackets.lower[i]
            elif r < self.at_lower[i] + len(inside):
                out[i] = np.partition(inside, r - self.at_lower[i])[r - self.at_lower[i]]
            else:
                out[i] = brackets.upper[i]
        return out


def quantile_ranks(n: int, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """numpy's ``method="linear"`` positions: (previous rank, next rank, gamma) per ``q``."""
    virtual = (n - 1) * np.asarray(q, dtype=np.float64)  # numpy: get_virtual_index of "linear"
    previous = np.floor(virtual)
    following = previous + 1
    above = virtual >= n - 1
    previous[above] = n - 1
    following[above] = n - 1
    gamma = virtual - np.floor(virtual)
    return previous.astype(np.int64), following.astype(np.int64), gamma


def linear_quantiles(previous: np.ndarray, following: np.ndarray, gamma: np.ndarray
                     ) -> np.ndarray:
    """numpy's ``_lerp`` of the order statistics around each virtual index, operation for
    operation (the rounding of ``numpy.quantile`` is reproduced exactly)."""
    diff = following - previous
    out = np.add(previous, diff * gamma)
    np.subtract(following, diff * (1 - gamma), out=out, where=gamma >= 0.5)
    return out


@dataclass(frozen=True, slots=True, eq=False)
class EdgePlan:
    """The edges of one feature in the making (``feature_edges`` without the data).

    From the merged pass-1 :class:`Sketch`: either the final edges (at most ``bins`` distinct
    values: midpoints) or :attr:`brackets` to tally in pass 2; :meth:`candidates` then gives the
    distinct quantiles, and :meth:`final` drops those whose left bin holds no value, from the
    per-bin counts of the data on the candidates (``bincount(searchsorted(candidates, v,
    side="right"))``, summed over partitions).
    """

    bins: int
    count: int
    midpoints: np.ndarray | None
    brackets: Brackets | None
    previous: np.ndarray
    following: np.ndarray
    gamma: np.ndarray

    @classmethod
    def of(cls, sketch: Sketch, bins: int) -> EdgePlan:
        if sketch.count == 0:
            raise ValueError("no values: equal-frequency edges need at least one")
        if sketch.distinct is not None and len(sketch.distinct) <= bins:
            d = sketch.distinct
            none = np.empty(0, dtype=np.int64)
            return cls(bins, sketch.count, (d[:-1] + d[1:]) / 2, None, none, none, np.empty(0))
        previous, following, gamma = quantile_ranks(sketch.count, np.arange(1, bins) / bins)
        ranks = np.unique(np.r_[previous, following])
        return cls(bins, sketch.count, None, sketch.brackets(ranks), previous, following, gamma)

    @property
    def needs_counts(self) -> bool:
        """Whether pass 2 (tallies) and the per-bin counts are needed (not midpoints)."""
        return self.midpoints is None

    def candidates(self, tally: Tally | None) -> np.ndarray:
        """Midpoints, or the distinct quantiles ``unique(numpy.quantile(v, k / B))``."""
        if self.midpoints is not None:
            return self.midpoints
        stats = tally.order_statistics(self.brackets)
        at = dict(zip(self.brackets.ranks.tolist(), stats, strict=True))
        previous = np.array([at[int(k)] for k in self.previous])
        following = np.array([at[int(k)] for k in self.following])
        return np.unique(linear_quantiles(previous, following, self.gamma))

    def final(self, candidates: np.ndarray, held: np.ndarray | None) -> np.ndarray:
        """The edges: candidates whose left bin holds data (``held``: per-bin counts on the
        candidates, ``len(candidates) + 1`` of them; ignored for midpoints)."""
        if self.midpoints is not None:
            return self.midpoints
        return candidates[np.asarray(held)[:-1] > 0]

    def kept(self, candidates: np.ndarray, held: np.ndarray | None) -> np.ndarray:
        """Per candidate, whether :meth:`final` keeps it."""
        if self.midpoints is not None:
            return np.ones(len(candidates), dtype=bool)
        return np.asarray(held)[:-1] > 0


def bin_counts(edges: np.ndarray, values: np.ndarray) -> np.ndarray:
    """How many ``values`` fall into each of the ``len(edges) + 1`` bins."""
    return np.bincount(np.searchsorted(edges, values, side="right"), minlength=len(edges) + 1)


def sorted_bin_counts(edges: np.ndarray, ordered: np.ndarray) -> np.ndarray:
    """:func:`bin_counts` of values already sorted: bin ``k`` holds ``edges[k-1] ≤ v <
    edges[k]``, so the values below ``edges[k]`` are the first ``searchsorted(ordered,
    edges[k], "left")``."""
    below = np.searchsorted(ordered, edges, side="left")
    return np.diff(np.r_[0, below, len(ordered)]).astype(np.int64)


def partitioned_edges(partitions: Sequence[np.ndarray], bins: int,
                      size: int = SKETCH_SIZE) -> np.ndarray:
    """``feature_edges(np.concatenate(partitions), bins)`` in three passes over the partitions,
    never holding more than one of them (plus the sketches and tallies).

    The reference use of :class:`Sketch`, :class:`Tally` and :class:`EdgePlan`; the out-of-core
    comparison interleaves the same passes with its own reading.
    """
    sketch = _merged((Sketch.of(p, cap=bins, size=size) for p in partitions),
                     Sketch.empty(bins))
    plan = EdgePlan.of(sketch, bins)
    if not plan.needs_counts:
        return plan.final(plan.candidates(None), None)
    tally = _merged((plan.brackets.tally(p) for p in partitions), plan.brackets.empty_tally())
    candidates = plan.candidates(tally)
    held = sum((bin_counts(candidates, p) for p in partitions),
               np.zeros(len(candidates) + 1, dtype=np.int64))
    return plan.final(candidates, held)


def exact_median(sketch: Sketch, partitions: Iterable[np.ndarray]) -> float:
    """``numpy.median`` of all values (the mean of the two middle ones for an even count)."""
    return median_from(sketch, lambda brackets: _merged(
        (brackets.tally(p) for p in partitions), brackets.empty_tally()))


def median_from(sketch: Sketch, tallied: Callable[[Brackets], Tally]) -> float:
    """:func:`exact_median`, the second pass given as ``tallied``: the tally of all values in
    the brackets it is given."""
    n = sketch.count
    brackets = sketch.brackets(np.unique([(n - 1) // 2, n // 2]))
    middle = tallied(brackets).order_statistics(brackets)
    return float(np.mean(middle)) if len(middle) == 2 else float(middle[0])


def _merged(parts: Iterable, start):
    out = start
    for part in parts:
        out = out.merge(part)
    return out
