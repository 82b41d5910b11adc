"""Probe (session 13, a negative result; docs/calibration.md): efficient
(Cochran-Mantel-Haenszel) state weights 1/(1/m_s + 1/n_s) per assignment instead of the pooled
share w_s in the pooled response statistics (every other part of the shipped test unchanged; the
bench's designs and seeds).

Written against the pooled-variance chain of commit f4a7bf7 (run it there: from session 13 on the
package studentises by units, and ``assignment_statistics`` takes no variances).

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=src .venv/bin/python scripts/response_cmh_probe.py \
        --designs lengths_markov,lengths,leaders_split --reps 400 --out cmh.json
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as rb  # noqa: E402

import simcred.compare.response as response  # noqa: E402
from simcred.compare.side_counts import SideCounts, is_paired  # noqa: E402
from simcred.compare.unit_sums import DenseSides  # noqa: E402

SHIPPED = response.assignment_statistics


def cmh_statistics(sums, assignments, n_features, variances, profile=None,
                   dims=response.FOURIER):
    sides = DenseSides if isinstance(sums.matrix, np.ndarray) else SideCounts
    product = sides(sums, paired=is_paired(assignments))
    width = 1 + n_features * dims
    totals = np.asarray(sums.matrix.sum(axis=1, dtype=np.float64)).ravel()
    share = totals[0::width] / max(totals[0::width].sum(), 1.0)
    contrast = response.contrasts(share, profile)  # (K, blocks)
    per_state = np.empty((len(assignments), len(sums.blocks), n_features))
    pooled = np.zeros((len(contrast), n_features * dims, len(assignments)))
    spread = np.zeros((len(contrast), n_features, len(assignments)))
    batch = int(np.clip(response.BATCH_BUDGET // max(*sums.matrix.shape, 1), 8, 1024))
    for first, last, lo, hi in product.chunks:
        rows = product.rows(lo, hi)
        for start in range(0, len(assignments), batch):
            side_a = product.product(rows, assignments[start:start + batch])
            value, diff, inverse = response._statistic(
                side_a.reshape(last - first, width, -1),
                totals[lo:hi].reshape(last - first, width), n_features, dims)
            with np.errstate(divide="ignore"):
                cmh = np.where(inverse > 0, 1.0 / np.where(inverse > 0, inverse, 1.0), 0.0)
            here, c = slice(start, start + batch), contrast[:, first:last]
            per_state[here, first:last] = value.transpose(2, 0, 1)
            pooled[:, :, here] += np.einsum("ks,sb,sdb->kdb", c, cmh, diff)
            spread[:, :, here] += np.einsum("ks,sj,sb->kjb", c**2, variances[first:last], cmh)
    observed = sums.matrix[0::width] @ assignments[0].astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        studentised = ((pooled.reshape(len(contrast), n_features, dims, -1) ** 2).sum(axis=2)
                       / response.LEVELS**2 / spread).reshape(len(contrast) * n_features, -1).T
    return (per_state.reshape(len(assignments), -1), studentised,
            observed.astype(np.int64), (totals[0::width] - observed).astype(np.int64))


def one(args):
    name, rep, permutations, variant = args
    response.assignment_statistics = cmh_statistics if variant == "cmh" else SHIPPED
    rb.SETTINGS.update(alpha=0.05, permutations=permutations)
    rng, seed = rb.seeds(name, rep)
    return name, rep, variant, rb.response(rb.DESIGNS[name](rng), seed)


if __name__ == "__main__":
    from response_unit_variance_probe import main

    main(one, "shipped,cmh")
