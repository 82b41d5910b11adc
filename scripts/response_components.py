"""Diagnostic: the rejection rate of each component of the response chain on its own.

For every replication of the selected designs (the data and seeds of scripts/response_bench.py)
the chain's p-value and each component's own permutation p-value over the same assignments:
``T_<feature>`` (pooled statistic), ``S_<feature>`` (spread, noisy responses only), ``profile``
(the summed profile statistics), ``comove`` (the largest co-movement statistic). Where the chain
loses its level, this says which statistic carries the excess.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_components.py \
        --designs lengths,lengths_markov --reps 200 --permutations 999 --out components.json
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as rb  # noqa: E402

import simcred.compare.conditional as conditional  # noqa: E402
import simcred.compare.response as response  # noqa: E402
from simcred.compare.runs import OneSided, exceedance_pvalues, standardise  # noqa: E402

SHIPPED = response.response_test
#: The components' p-values of the last call (one process, one call at a time).
LAST: dict[str, float] = {}


def components(data, n_units, assignments, rng) -> dict[str, np.ndarray]:
    """Each component of the chain over the assignments (the shipped test's rng use)."""
    kernel = response.kernel_sums(data, n_units, rng)
    n_features = len(data.response)
    _, pooled, _, _ = response.assignment_statistics(kernel.counts, assignments, n_features,
                                                     data.profile)
    z = standardise(pooled, OneSided.NEUTRAL)[0]
    spread, comovement = response.moment_statistics(kernel, n_features, assignments)
    out = {}
    for j, name in enumerate(data.response):
        out[f"T_{name}"] = z[:, j]
        if spread is not None and spread[:, j].any():
            out[f"S_{name}"] = spread[:, j]
    if z.shape[1] > n_features:
        out["profile"] = z[:, n_features:].sum(axis=1)
    if comovement is not None:
        out["comove"] = comovement
    return out


def recording_test(data, n_units, assignments, rng):
    outcome = SHIPPED(data, n_units, assignments, copy.deepcopy(rng))
    LAST.clear()
    LAST.update({name: float(exceedance_pvalues(c[:, None], c[:1])[0])
                 for name, c in components(data, n_units, assignments, rng).items()})
    return outcome


def one(args: tuple) -> tuple:
    name, rep, permutations = args
    conditional.response_test = recording_test
    rb.SETTINGS.update(alpha=0.05, permutations=permutations)
    rng, seed = rb.seeds(name, rep)
    chain = rb.response(rb.DESIGNS[name](rng), seed)
    return name, rep, chain, dict(LAST)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", required=True)
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--first-rep", type=int, default=0)
    parser.add_argument("--permutations", type=int, default=999)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    names = rb.select(args.designs, list(rb.DESIGNS), rb.ALIASES)
    work = [(n, r, args.permutations) for n in names
            for r in range(args.first_rep, args.first_rep + args.reps)]
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(one, work, chunksize=4))
    table = {}
    for name in names:
        mine = [r for r in rows if r[0] == name]
        keys = mine[0][3].keys()
        table[name] = {"chain": float(np.mean([r[2] <= 0.05 for r in mine])),
                       **{k: float(np.mean([r[3][k] <= 0.05 for r in mine])) for k in keys}}
        print(name, {k: round(v, 3) for k, v in table[name].items()}, flush=True)
    result = {"reps": args.reps, "first_rep": args.first_rep, "permutations": args.permutations,
              "rejected": table, "rows": rows}
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
