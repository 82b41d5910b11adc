"""Markov-chain counts: start states and transitions of a trace set, as sorted codes with counts.

Neurohr et al. 2023 [1], sec. IV-A: two time-homogeneous chains are equal iff their start
distributions (R1) and their transition matrices (R2) are equal. Both are estimated here by
counting; transitions are pooled over all time steps and runs (assumption A2, time-homogeneity).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class ChainCounts:
    """Counts of one trace set on a state space of ``n_states`` states.

    ``start_states``/``start_counts``: distinct first states of the runs and how often each occurs.
    ``transitions``/``transition_counts``: distinct pair codes ``from * n_states + to`` (sorted)
    and their counts.
    """

    n_states: int
    start_states: np.ndarray
    start_counts: np.ndarray
    transitions: np.ndarray
    transition_counts: np.ndarray

    @classmethod
    def from_codes(cls, codes: np.ndarray, offsets: np.ndarray, n_states: int) -> ChainCounts:
        """Count start states and within-run transitions of state ``codes`` split by ``offsets``."""
        starts, start_counts = np.unique(codes[offsets[:-1]], return_counts=True)
        valid = np.ones(len(codes) - 1, dtype=bool)
        valid[offsets[1:-1] - 1] = False  # no transition from a run's last step to the next run
        pairs = codes[:-1][valid] * np.int64(n_states) + codes[1:][valid]
        transitions, counts = np.unique(pairs, return_counts=True)
        return cls(n_states, starts, start_counts, transitions, counts)


def aligned(
    codes_a: np.ndarray, counts_a: np.ndarray, codes_b: np.ndarray, counts_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Union of two sorted code sets with both count vectors aligned to it (zeros where absent)."""
    union = np.union1d(codes_a, codes_b)
    ca = np.zeros(len(union), dtype=np.int64)
    cb = np.zeros(len(union), dtype=np.int64)
    ca[np.searchsorted(union, codes_a)] = counts_a
    cb[np.searchsorted(union, codes_b)] = counts_b
    return union, ca, cb


@dataclass(frozen=True, slots=True)
class SuccessorCounts:
    """For one start state: its distinct successors and how often each follows it in A and B."""

    state: int
    successors: np.ndarray
    counts_a: np.ndarray
    counts_b: np.ndarray

    @property
    def m(self) -> int:
        return int(self.counts_a.sum())

    @property
    def n(self) -> int:
        return int(self.counts_b.sum())


def successor_counts(a: ChainCounts, b: ChainCounts) -> Iterator[SuccessorCounts]:
    """Per start state seen in A or B (ascending code), the aligned successor counts."""
    pairs, ca, cb = aligned(a.transitions, a.transition_counts, b.transitions, b.transition_counts)
    origin = pairs // a.n_states
    bounds = np.flatnonzero(np.diff(origin)) + 1
    for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, len(pairs)], strict=True):
        yield SuccessorCounts(int(origin[lo]), pairs[lo:hi] % a.n_states, ca[lo:hi], cb[lo:hi])
