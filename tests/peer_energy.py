"""Peer baseline: a run-level energy-distance permutation test on per-run summaries.

Every run becomes one row of summaries: for every feature its mean, standard deviation, 10/50/90 %
quantiles and mean absolute first difference (6 numbers per feature). Columns are standardised
by their pooled sd (a constant column is left at 0). The statistic is Székely & Rizzo's energy
two-sample statistic between the A rows and the B rows,

    T = m n / (m + n) · (2/(mn) Σ|x_i - y_j| - 1/m² Σ|x_i - x_k| - 1/n² Σ|y_j - y_l|),

and the p-value is (1 + #{T* >= T}) / (P + 1) over P random reassignments of whole runs (the
pooled distance matrix is computed once; a permutation costs a few index sums). It assumes
exchangeable runs: it knows nothing of pairs, groups, run lengths or exogenous inputs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simcred.traces import TraceSet

SUMMARIES = ("mean", "sd", "q10", "q50", "q90", "mean_abs_diff")


def run_summaries(traces: TraceSet, features: Sequence[str]) -> np.ndarray:
    """(runs, 6 · len(features)) summaries, feature-major (see SUMMARIES)."""
    x = traces.features(list(features))
    out = np.empty((traces.n_runs, len(SUMMARIES) * x.shape[1]))
    lengths = traces.lengths
    for n in np.unique(lengths):  # runs of one length at once: (runs, steps, features)
        idx = np.flatnonzero(lengths == n)
        rows = traces.offsets[idx][:, None] + np.arange(n)[None, :]
        block = x[rows]
        q = np.quantile(block, [0.1, 0.5, 0.9], axis=1)
        stats = np.stack([block.mean(axis=1), block.std(axis=1), q[0], q[1], q[2],
                          np.abs(np.diff(block, axis=1)).mean(axis=1)], axis=2)
        out[idx] = stats.reshape(len(idx), -1)
    return out


def energy_statistic(d: np.ndarray, in_a: np.ndarray) -> np.ndarray:
    """Energy statistic for one or many labelings ``in_a`` ((..., N) booleans) of the pooled
    distance matrix ``d`` (N × N)."""
    z = np.asarray(in_a, dtype=float)
    m = z.sum(axis=-1)
    n = z.shape[-1] - m
    s_aa = np.einsum("...i,ij,...j->...", z, d, z)
    s_a_all = z @ d.sum(axis=1)  # Σ_{i in A} Σ_j d_ij = S_AA + S_AB
    s_ab = s_a_all - s_aa
    s_bb = d.sum() - s_aa - 2 * s_ab
    return m * n / (m + n) * (2 * s_ab / (m * n) - s_aa / m ** 2 - s_bb / n ** 2)


def energy_test(a: TraceSet, b: TraceSet, features: Sequence[str], permutations: int = 199,
                seed: int = 0) -> float:
    """Permutation p-value of the energy statistic between the per-run summaries of a and b."""
    x = np.vstack([run_summaries(a, features), run_summaries(b, features)])
    sd = x.std(axis=0)
    x = (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    d = np.sqrt(np.maximum(((x[:, None, :] - x[None, :, :]) ** 2).sum(axis=2), 0.0))
    labels = np.r_[np.ones(a.n_runs, bool), np.zeros(b.n_runs, bool)]
    observed = energy_statistic(d, labels)
    rng = np.random.default_rng(seed)
    perms = rng.permuted(np.broadcast_to(labels, (permutations, labels.size)), axis=1)
    null = energy_statistic(d, perms)
    tol = 1e-10 * max(abs(float(observed)), 1.0)
    return float((1 + np.sum(null >= observed - tol)) / (permutations + 1))
