"""Probe (session 13; docs/calibration.md): the pooled response statistics studentised by a
unit-level, per-side variance instead of the pooled within-state one.

Shipped: ``T_j = ‖Σ_s w_s d_s,j‖² / Σ_s w_s² v_s,j (1/m_s + 1/n_s)``, ``v_s,j`` the pooled
within-state variance of single transitions. Here the denominator of every assignment is
``Σ_s w_s² (Q_A,s,j / m_s² + Q_B,s,j / n_s²)`` with ``Q_A,s,j = Σ_{u ∈ A} ‖X_u,s,j‖²``,
``X_u,s,j`` unit u's sum of features in state s minus its count times the pooled state mean:
the variance of each side's state mean from its own units (a cluster-robust, unpooled
studentisation in the sense of Chung & Romano 2013), which follows the observed design's
unequal run lengths and within-run dependence. Everything else as shipped (the bench's designs
and seeds); dense arithmetic, for the bench's sizes only.

Written against the pooled-variance chain of commit f4a7bf7 (run it there: from session 13 on the
package studentises by units, and ``assignment_statistics`` takes no variances).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=src .venv/bin/python \\
        scripts/response_unit_variance_probe.py --designs lengths_markov --reps 400
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as rb  # noqa: E402

import simcred.compare.response as response  # noqa: E402

SHIPPED = response.assignment_statistics


def unit_variance_statistics(sums, assignments, n_features, variances, profile=None,
                             dims=response.FOURIER):
    per_state, _, m_obs, n_obs = SHIPPED(sums, assignments, n_features, variances, profile,
                                         dims)
    matrix = sums.matrix.toarray() if hasattr(sums.matrix, "toarray") else sums.matrix
    width = 1 + n_features * dims
    blocks, units = len(sums.blocks), matrix.shape[1]
    s = np.asarray(matrix, dtype=np.float64).reshape(blocks, width, units)
    count = s[:, 0, :]
    feat = s[:, 1:, :].reshape(blocks, n_features, dims, units) / response.LEVELS
    total_count = count.sum(axis=1)
    share = total_count / max(total_count.sum(), 1.0)
    mu = feat.sum(axis=3) / np.maximum(total_count, 1.0)[:, None, None]
    x = feat - count[:, None, None, :] * mu[..., None]
    q = (x**2).sum(axis=2)  # (blocks, features, units)
    a = assignments.astype(np.float64).T  # (units, P + 1)
    m = count @ a
    n = total_count[:, None] - m
    sa = feat @ a  # (blocks, features, dims, P + 1)
    sb = feat.sum(axis=3)[..., None] - sa
    qa = q @ a
    qb = q.sum(axis=2)[..., None] - qa
    empty = (m < 1) | (n < 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = sa / m[:, None, None, :] - sb / n[:, None, None, :]
        var = qa / m[:, None, :] ** 2 + qb / n[:, None, :] ** 2
    diff[np.broadcast_to(empty[:, None, None, :], diff.shape)] = 0.0
    var[np.broadcast_to(empty[:, None, :], var.shape)] = 0.0
    weights = response.contrasts(share, profile) * share
    pooled = (np.einsum("kb,bjdp->kjdp", weights, diff) ** 2).sum(axis=2)
    spread = np.einsum("kb,bjp->kjp", weights**2, var)
    with np.errstate(invalid="ignore", divide="ignore"):
        studentised = (pooled / spread).reshape(len(weights) * n_features, -1).T
    return per_state, studentised, m_obs, n_obs


def whitened_profile_statistics(sums, assignments, n_features, variances, profile=None,
                                dims=response.FOURIER):
    """The shipped statistics, but the profile contrasts of each feature as one quadratic form
    whitened by their covariance under each assignment
    (``C_kl = Σ_s c_k,s c_l,s v_s (1/m_s + 1/n_s)``): the contrasts' correlation depends on the
    design (which side holds which states), and a sum of their z's does not see it."""
    per_state, studentised, m_obs, n_obs = SHIPPED(sums, assignments, n_features, variances,
                                                   profile, dims)
    if studentised.shape[1] <= n_features:
        return per_state, studentised, m_obs, n_obs
    matrix = sums.matrix.toarray() if hasattr(sums.matrix, "toarray") else sums.matrix
    width = 1 + n_features * dims
    blocks = len(sums.blocks)
    s = np.asarray(matrix, dtype=np.float64).reshape(blocks, width, -1)
    count = s[:, 0, :]
    feat = s[:, 1:, :].reshape(blocks, n_features, dims, -1) / response.LEVELS
    total_count = count.sum(axis=1)
    share = total_count / max(total_count.sum(), 1.0)
    a = assignments.astype(np.float64).T
    m = count @ a
    n = total_count[:, None] - m
    sa = feat @ a
    sb = feat.sum(axis=3)[..., None] - sa
    empty = (m < 1) | (n < 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = sa / m[:, None, None, :] - sb / n[:, None, None, :]
        inverse = np.where(empty, 0.0, 1.0 / m + 1.0 / n)
    diff[np.broadcast_to(empty[:, None, None, :], diff.shape)] = 0.0
    weights = (response.contrasts(share, profile) * share)[1:]  # the profile contrasts
    u = np.einsum("kb,bjdp->jpkd", weights, diff)  # (features, P + 1, K, dims)
    cov = np.einsum("kb,lb,bj,bp->jpkl", weights, weights, variances, inverse)
    k = len(weights)
    cov += 1e-12 * np.trace(cov, axis1=2, axis2=3)[..., None, None] * np.eye(k)
    solved = np.linalg.solve(cov, u)  # (features, P + 1, K, dims)
    form = (u * solved).sum(axis=(2, 3)).T  # (P + 1, features)
    out = studentised.copy()
    out[:, n_features:] = 0.0
    out[:, n_features:2 * n_features] = form
    return per_state, out, m_obs, n_obs


VARIANTS = {"unit": unit_variance_statistics, "whiten": whitened_profile_statistics}


def one(args):
    name, rep, permutations, variant = args
    response.assignment_statistics = VARIANTS.get(variant, SHIPPED)
    rb.SETTINGS.update(alpha=0.05, permutations=permutations)
    rng, seed = rb.seeds(name, rep)
    return name, rep, variant, rb.response(rb.DESIGNS[name](rng), seed)


def main(run=one, default_variants: str = "shipped,unit") -> None:
    """Rejection rates of ``variants`` (``run``: one replication) on the bench's designs."""
    p = argparse.ArgumentParser()
    p.add_argument("--designs", required=True)
    p.add_argument("--reps", type=int, default=200)
    p.add_argument("--first-rep", type=int, default=0)
    p.add_argument("--permutations", type=int, default=999)
    p.add_argument("--variants", default=default_variants)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--out", type=Path)
    a = p.parse_args()
    names = rb.select(a.designs, list(rb.DESIGNS), rb.ALIASES)
    variants = a.variants.split(",")
    work = [(n, r, a.permutations, v) for n in names
            for r in range(a.first_rep, a.first_rep + a.reps) for v in variants]
    with ProcessPoolExecutor(a.jobs) as pool:
        rows = list(pool.map(run, work, chunksize=4))
    table = {}
    for n in names:
        for v in variants:
            ps = [r[3] for r in rows if r[0] == n and r[2] == v]
            k = int(sum(x <= 0.05 for x in ps))
            table[f"{n}/{v}"] = [k, len(ps), k / len(ps), rb.wilson(k, len(ps))]
            print(n, v, k, len(ps), round(k / len(ps), 3), flush=True)
    if a.out:
        a.out.write_text(json.dumps({"args": {k: str(v) for k, v in vars(a).items()},
                                     "table": table, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
