"""Probe (not shipped in the test): a co-movement component for the response test's chain.

Written against the chain before the co-movement component: the results in calibration.md ran
at commit 925d22a (run it there; at later commits ``shipped`` already holds the co-movement and
``response.unit_sums`` / ``response.spread_statistics`` are gone).

A 0.5 s reaction delay or late braking shows less in any one response's law given the state than
in how two responses move *together*: in a car-following set the residual of the relative speed
``dv`` given the state is the leader's change over the step (exogenous), and a driver who reacts
within the step moves its acceleration with it; a delayed one does not. This probe adds, for
every pair of responses that both have noise of their own (adjusted residual ≥ NOISE_FLOOR of the
raw spread), ``C_jk`` = the pooled studentised statistic ``T`` computed on the product
``(r_j / sd_j)(r_k / sd_k)`` of the dithered adjusted residuals (per state: the A–B difference
of the conditional co-movement), and combines it with the shipped chain:

* ``pairs``    — every ``C_jk`` its own Tippett component beside the shipped components;
* ``pairsmax`` — the shipped chain's per-feature components, with ``C_jk`` folded into feature
  k's component (the pair's second) by ``max`` (no extra Tippett component).

Same data and seeds as ``scripts/response_bench.py``.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_comovement_probe.py \
        --designs h0 --reps 100 --variants shipped,pairs
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from functools import partial  # noqa: E402
from itertools import combinations  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as rb  # noqa: E402

import simcred.compare.conditional as conditional  # noqa: E402
import simcred.compare.response as response  # noqa: E402
from response_designs import lengths  # noqa: E402
from simcred.compare.paired_runs import tippett  # noqa: E402
from simcred.compare.runs import OneSided, exceedance_pvalues, standardise  # noqa: E402
from simcred.compare.transitions import state_means  # noqa: E402

SHIPPED = response.response_test
VARIANT = {"name": "shipped"}


def noisy_pairs(data) -> list[tuple[int, int]]:
    if data.spread is None:
        return []
    noisy = np.flatnonzero(data.residual.std(axis=0) >= response.NOISE_FLOOR * data.spread)
    return list(combinations(noisy.tolist(), 2))


def comovement_z(data, n_units, assignments, pairs, rng):
    """(P + 1, pairs) standardised C_jk."""
    r = data.residual + response.RESOLUTION * data.spread * rng.normal(size=data.residual.shape)
    z = r / (r.std(axis=0) + 1e-300)
    q = np.column_stack([z[:, j] * z[:, k] for j, k in pairs])
    values = np.rint(response.LEVELS * q)
    sums = response.unit_sums(data, np.column_stack([np.ones(len(q)), values]), n_units)
    mean = state_means(data.state, values)
    variances = np.maximum(state_means(data.state, values**2) - mean**2, 0.0) \
        / response.LEVELS**2
    _, pooled, _, _ = response.assignment_statistics(sums, assignments, len(pairs), variances,
                                                     None, dims=1)
    return standardise(pooled, OneSided.NEUTRAL)[0]


def probe_test(data, n_units, assignments, rng):
    pairs = noisy_pairs(data)
    if VARIANT["name"] == "shipped" or not pairs:
        return SHIPPED(data, n_units, assignments, rng)
    out = SHIPPED(data, n_units, assignments, copy.deepcopy(rng))  # same draws as _rebuild
    c = comovement_z(data, n_units, assignments, pairs, np.random.default_rng(12345))
    if VARIANT["name"] == "pairs":
        chain = _rebuild(data, n_units, assignments, rng,
                         extra=[c[:, i] for i in range(c.shape[1])])
    else:
        chain = _rebuild(data, n_units, assignments, rng, fold=(pairs, c))
    pvalue = float(exceedance_pvalues(chain[:, None], chain[:1])[0])
    return dataclasses.replace(out, chain_statistic=float(chain[0]), chain_pvalue=pvalue,
                               chain_null=chain)


def _rebuild(data, n_units, assignments, rng, extra=(), fold=None):
    """The shipped chain's parts (same rng use as the shipped test) with extra components."""
    kernel = response.kernel_sums(data, n_units, rng)
    n_features = len(data.response)
    _, pooled, _, _ = response.assignment_statistics(kernel.counts, assignments, n_features,
                                                     kernel.variances, data.profile)
    z = standardise(pooled, OneSided.NEUTRAL)[0]
    spread = response.spread_statistics(kernel, data, assignments)
    level = [z[:, j] if spread is None or not spread[:, j].any()
             else np.maximum(z[:, j], spread[:, j]) for j in range(n_features)]
    if fold is not None:
        for i, (_, k) in enumerate(fold[0]):
            level[k] = np.maximum(level[k], fold[1][:, i])  # into the pair's second feature
    parts = level + ([z[:, n_features:].sum(axis=1)] if z.shape[1] > n_features else [])
    return tippett(*parts, *extra)


def _one(args):
    name, rep, variants, permutations = args
    rb.DESIGNS["lengths_runs100"] = partial(lengths, runs=100)
    conditional.response_test = probe_test
    rb.SETTINGS.update(alpha=0.05, permutations=permutations)
    rng, seed = rb.seeds(name, rep)
    design = rb.DESIGNS[name](rng)
    out = {}
    for variant in variants:
        VARIANT["name"] = variant
        out[variant] = rb.response(design, seed)
    return name, rep, out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", required=True)
    parser.add_argument("--reps", type=int, default=100)
    parser.add_argument("--first-rep", type=int, default=0)
    parser.add_argument("--variants", default="shipped,pairs")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--permutations", type=int, default=99)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    rb.DESIGNS["lengths_runs100"] = partial(lengths, runs=100)
    names = rb.select(args.designs, list(rb.DESIGNS), rb.ALIASES)
    variants = args.variants.split(",")
    reps = range(args.first_rep, args.first_rep + args.reps)
    work = [(n, r, variants, args.permutations) for n in names for r in reps]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(_one, work, chunksize=4))
    pvalues = {n: {v: [p[v] for m, _, p in results if m == n] for v in variants} for n in names}
    rejected = {n: {v: sum(p <= 0.05 for p in pv[v]) for v in variants}
                for n, pv in pvalues.items()}
    for n in names:
        print(n, {v: round(k / len(reps), 3) for v, k in rejected[n].items()}, flush=True)
    result = {"reps": len(reps), "first_rep": args.first_rep,
              "permutations": args.permutations, "rejected": rejected,
              "pvalues": pvalues}
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
