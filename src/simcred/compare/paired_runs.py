"""The closed-loop part of a paired comparison: in a replay, where the model drives *is* its
response.

In a paired design (:mod:`simcred.compare.design`) both members of a pair face the same scenario
(recorded leader, start state). A model that brakes late or reacts with a delay then drives into
other situations than its partner — a difference the state-conditional response test partly
averages away (its per-state differences change sign between states). Under H0 the two members
of a pair are exchangeable, so any statistic of the pair differences is exactly tested by
flipping pairs [1].

Per run, the summaries of every response feature (mean, standard deviation, 10/50/90 %
quantiles, mean absolute step), standardised by their pooled spread; per pair the difference
``d_p = u_A,p − u_B,p``; the statistic of an assignment with signs ``ε_p`` is
``‖Σ_p ε_p d_p‖² / Σ_p ‖d_p‖²`` (the denominator does not depend on the signs: a sign-flip
test of the mean difference, studentised once).

References
----------
[1] Pesarin & Salmaso, Permutation Tests for Complex Data, Wiley, 2010 (paired designs).
"""

from __future__ import annotations

import numpy as np

QUANTILES = (0.1, 0.5, 0.9)


def run_summaries(values: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(runs, 6 · features) summaries of every run's rows of ``values`` (rows, features); runs of
    one length at a time, one feature at a time as a (runs, steps) array (each run's values
    contiguous: the reductions and the sort run along rows)."""
    lengths = np.diff(offsets)
    n_features = values.shape[1]
    out = np.empty((len(lengths), 6 * n_features))
    for n in np.unique(lengths):
        runs = np.flatnonzero(lengths == n)
        rows = offsets[runs][:, None] + np.arange(n)[None, :]
        for j in range(n_features):
            block = values[:, j][rows]
            step = np.abs(np.diff(block, axis=1)).mean(axis=1) if n > 1 else np.zeros(len(runs))
            mean, spread = block.mean(axis=1), block.std(axis=1)
            block.sort(axis=1)  # quantiles of sorted rows: one sort, no selections
            for k, column in enumerate((mean, spread, *np.quantile(block, QUANTILES, axis=1),
                                        step)):
                out[runs, k * n_features + j] = column
    return out


def paired_statistics(summaries: np.ndarray, units_a: int, assignments: np.ndarray
                      ) -> np.ndarray:
    """(P + 1,) statistics of the assignments (row 0 observed) of a paired design whose units
    ``i`` and ``units_a + i`` form pair ``i``; ``summaries``: one row per unit."""
    scale = summaries.std(axis=0)
    standard = summaries / np.where(scale > 0, scale, 1.0)
    diff = standard[:units_a] - standard[units_a:]
    signs = np.where(assignments[:, :units_a], 1.0, -1.0)  # A-member on side A: +1
    total = (diff**2).sum()
    if total == 0:
        return np.zeros(len(assignments))
    return ((signs @ diff) ** 2).sum(axis=1) / total


def tippett(*nulls: np.ndarray) -> np.ndarray:
    """Statistics whose larger values mean "more extreme", combined by their smallest
    permutation p-value over the same assignments (Tippett's combination [1]): returns
    ``−min_k p_k`` per assignment, larger = more extreme."""
    ranks = []
    for null in nulls:
        order = np.sort(null)
        ranks.append(1.0 - np.searchsorted(order, null, side="left") / len(null))
    return -np.minimum.reduce(ranks)
