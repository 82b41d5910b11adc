"""Equal-frequency binning on pooled values, and the state space it induces.

Neurohr et al. 2023 [1], sec. V-A and Fig. 3: every feature is cut at the quantiles k/B of the
pooled values of both trace sets; a state is the vector of bin indices of all features.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from simcred.errors import OptionError

#: Values looked at first when checking whether a feature has at most B distinct values.
DISTINCT_PROBE = 4096
#: Values binned at a time when counting the pooled values per bin.
CHUNK = 2**20
#: Largest state space: pair codes ``from * |S| + to`` must fit into int64.
MAX_STATES = 2**31


@dataclass(frozen=True, slots=True, eq=False)
class StateSpace:
    """The grid of states: per feature, the bin edges (duplicates removed) and the data range.

    A value ``v`` of feature ``j`` falls into bin ``searchsorted(edges[j], v, side="right")``, so
    feature ``j`` has ``len(edges[j]) + 1`` bins and ``|S| = prod(len(edges[j]) + 1)``.
    ``bounds`` (pooled minimum and maximum per feature) only serve to draw the outer bins.
    """

    features: tuple[str, ...]
    edges: tuple[np.ndarray, ...]
    bounds: tuple[tuple[float, float], ...]

    @classmethod
    def equal_frequency(
        cls, pooled: np.ndarray, bins: Sequence[int], features: Sequence[str]
    ) -> StateSpace:
        """Edges ``numpy.quantile(pooled[:, j], k / B)`` for ``k = 1 .. B-1``, duplicates removed.

        >>> s = StateSpace.equal_frequency(np.arange(10.0)[:, None], [2], ["x"])
        >>> s.edges[0].tolist(), s.shape
        ([4.5], (2,))
        """
        return cls.pooled((pooled,), bins, features)

    @classmethod
    def pooled(
        cls, parts: Sequence[np.ndarray], bins: Sequence[int], features: Sequence[str]
    ) -> StateSpace:
        """:meth:`equal_frequency` of ``numpy.vstack(parts)``, one pooled column at a time (the
        column is the quantile's scratch copy, so no stacked copy of all features is made)."""
        edges, bounds = [], []
        for j, n_bins in enumerate(bins):
            column = None  # the last feature's column goes before this one's is made
            column = np.concatenate([part[:, j] for part in parts])
            bounds.append((float(column.min()), float(column.max())))
            edges.append(feature_edges(column, n_bins, scratch=True))
        space = cls(tuple(features), tuple(edges), tuple(bounds))
        _check_size(space)
        return space

    def with_extra(self, name: str, edges: np.ndarray, bounds: tuple[float, float]
                   ) -> StateSpace:
        """This grid with one more feature appended (e.g. the time window)."""
        return StateSpace((*self.features, name), (*self.edges, edges), (*self.bounds, bounds))

    def lagged(self, history: int) -> StateSpace:
        """The grid of ``history`` consecutive states: every feature once per lag, oldest first.

        Feature ``x`` at lag ``i`` steps back is named ``x[t-i]`` (``x`` for ``i = 0``).
        """
        if history == 1:
            return self
        names = tuple(f if lag == 0 else f"{f}[t-{lag}]"
                      for lag in range(history - 1, -1, -1) for f in self.features)
        space = StateSpace(names, self.edges * history, self.bounds * history)
        _check_size(space)
        return space

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of bins per feature."""
        return tuple(len(e) + 1 for e in self.edges)

    @property
    def n_states(self) -> int:
        """``|S|``, the size of the common state space (denominator of [1] eq. (6))."""
        return int(np.prod(self.shape, dtype=np.int64))

    def bin_indices(self, values: np.ndarray) -> np.ndarray:
        """``(rows, features)`` bin indices of ``(rows, features)`` values."""
        return np.stack(
            [np.searchsorted(e, values[:, j], side="right") for j, e in enumerate(self.edges)],
            axis=1,
        )

    def encode(self, values: np.ndarray) -> np.ndarray:
        """One int64 code per row (``ravel_multi_index`` of the bin indices)."""
        return np.ravel_multi_index(tuple(self.bin_indices(values).T), self.shape).astype(np.int64)

    def decode(self, codes: np.ndarray) -> np.ndarray:
        """``(len(codes), features)`` int array of bin indices."""
        return np.stack(np.unravel_index(np.asarray(codes, dtype=np.int64), self.shape), axis=1)

    def vectors(self, codes: np.ndarray) -> np.ndarray:
        """States as float vectors of bin indices: the points the MMD kernels act on."""
        return self.decode(codes).astype(np.float64)


def _check_size(space: StateSpace) -> None:
    if space.n_states > MAX_STATES:
        raise OptionError(f"state space of {space.n_states} states is too large "
                          f"(at most {MAX_STATES}); use fewer features, bins or history")


def feature_edges(column: np.ndarray, n_bins: int, scratch: bool = False) -> np.ndarray:
    """Bin edges of one feature: equal-frequency, with every bin holding pooled data.

    ``numpy.quantile(column, k / B)``, ``k = 1 .. B-1``, duplicates removed ([1] sec. V-A). Two
    amendments for tied and discrete data, neither of which changes anything on continuous data
    (no ties, more distinct values than bins):

    * at most ``B`` distinct values: one bin per value, edges at the midpoints between
      consecutive values (three lanes are three bins, a boolean is two);
    * otherwise, an edge whose bin to its left holds no pooled value is dropped (a quantile equal
      to the minimum, or two quantiles straddling a gap between tied values, would leave a bin
      that no data can reach).

    >>> feature_edges(np.array([0.0, 0, 0, 0, 1, 2, 2]), 10).tolist()
    [0.5, 1.5]
    >>> feature_edges(np.arange(10.0), 2).tolist()
    [4.5]

    ``scratch``: ``column`` may be reordered (it is a copy made for this call).
    """
    if len(np.unique(column[:DISTINCT_PROBE])) <= n_bins:  # cheap exit for continuous data
        distinct = np.unique(column)
        if len(distinct) <= n_bins:
            return (distinct[:-1] + distinct[1:]) / 2
    edges = np.unique(np.quantile(column, np.arange(1, n_bins) / n_bins,
                                  overwrite_input=scratch))
    held = np.zeros(len(edges) + 1, dtype=np.int64)
    for lo in range(0, len(column), CHUNK):  # in chunks: no bin index per value at once
        held += np.bincount(np.searchsorted(edges, column[lo:lo + CHUNK], side="right"),
                            minlength=len(edges) + 1)
    return edges[held[:-1] > 0]
