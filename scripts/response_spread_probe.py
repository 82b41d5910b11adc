"""Probe (not shipped in the test): a spread component for the response test's chain.

Written against the chain of commit 5e7c0df (session 11; run it there): the package has moved
on (the co-movement component, compare/state_sums.py).

The unpaired response test loses to the energy peer on variance and clip defects
(docs/calibration.md). This probe adds a Levene-type statistic — per state the A–B difference of
the mean absolute adjusted response ``|r|`` (dithered as the test dithers), pooled and
studentised exactly as ``T_j`` — and combines it with the shipped chain in three ways, on the
same data as ``scripts/response_bench.py`` (its seeds):

* ``sum``    — Tippett of the shipped chain and the spread statistics summed over features;
* ``foldg``  — per feature ``z(T_j) + z(S_j)`` (with the profile sum, Tippett), the spread term
  only for features whose adjusted residual is ≥ 5 % of its raw spread (label-free: kinematic
  identities carry only the dither and fit leftovers);
* ``foldgu`` — as ``foldg``, but ``S_j`` on per-(state, unit) means of ``|r|``, each unit one
  observation in each state it visits;
* ``eachg``  — as ``foldg``, but ``T_j`` and ``S_j`` each on their own in Tippett;
* ``foldmax`` — as ``foldg``, with ``max(z(T_j), z(S_j))`` per noisy feature in place of the sum;
* ``folda``  — as ``foldg``, with ``|r|`` itself adjusted on the covariates (global cubic and
  per-state fits, as the response is) before it is compared.

Besides the bench's designs, ``lengths_runs100``: the lengths design with 100 runs per side.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_spread_probe.py \
        --designs lengths,leaders_split --reps 100 --variants shipped,foldg
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as rb  # noqa: E402

import simcred.compare.conditional as conditional  # noqa: E402
import simcred.compare.response as response  # noqa: E402
import simcred.compare.transitions as transitions_module  # noqa: E402
from response_designs import lengths  # noqa: E402
from simcred.compare.paired_runs import tippett  # noqa: E402
from simcred.compare.runs import OneSided, exceedance_pvalues, standardise  # noqa: E402
from simcred.compare.transitions import adjusted, state_means  # noqa: E402

SHIPPED = response.response_test
_PER_STATE = transitions_module.per_state_residual
#: The last (state, covariates) the transitions were adjusted with (``folda``).
CAPTURED: dict = {}


def _capture(state, covariates, rate, **options):
    CAPTURED.update(state=state, covariates=covariates)
    return _PER_STATE(state, covariates, rate, **options)
#: Features whose adjusted residual is below this share of the raw spread get no spread term.
NOISE_FLOOR = 0.05
VARIANT = {"name": "shipped"}


def _abs_residual(data, rng):
    r = data.residual + response.RESOLUTION * data.spread * rng.normal(size=data.residual.shape)
    a = np.abs(r)
    if VARIANT["name"] == "folda":  # |r| adjusted on the covariates as the response is
        a = adjusted(CAPTURED["state"], CAPTURED["covariates"], a)
    return a / (a.std(axis=0) + 1e-300)


def _pooled_z(data, columns, variances, n_units, assignments):
    sums = response.unit_sums(data, columns, n_units)
    n_features = len(data.response)
    _, pooled, _, _ = response.assignment_statistics(sums, assignments, n_features,
                                                     np.maximum(variances, 0.0), None)
    return standardise(pooled[:, :n_features], OneSided.NEUTRAL)[0]


def spread_transitions(data, n_units, assignments, rng):
    """S_j with every transition one observation."""
    a = _abs_residual(data, rng)
    step = response.FOURIER
    columns = np.zeros((len(a), 1 + a.shape[1] * step))
    columns[:, 0] = 1.0
    columns[:, 1::step] = np.rint(response.LEVELS * a)
    q = columns[:, 1::step] / response.LEVELS
    mean = state_means(data.state, q)
    return _pooled_z(data, columns, state_means(data.state, q**2) - mean**2, n_units, assignments)


def spread_units(data, n_units, assignments, rng):
    """S_j with every (state, unit) mean one observation."""
    a = _abs_residual(data, rng)
    new = np.r_[True, (np.diff(data.state) != 0) | (np.diff(data.unit) != 0)]
    pair = np.cumsum(new) - 1
    size = np.bincount(pair).astype(float)
    step = response.FOURIER
    columns = np.zeros((len(a), 1 + a.shape[1] * step))
    columns[:, 0] = 1.0 / size[pair]
    columns[:, 1::step] = response.LEVELS * a / size[pair][:, None]
    first = np.flatnonzero(new)
    unit_mean = np.add.reduceat(a, first, axis=0) / size[:, None]
    mean = state_means(data.state[first], unit_mean)
    variances = state_means(data.state[first], unit_mean**2) - mean**2
    return _pooled_z(data, columns, variances, n_units, assignments)


def level_z(data, n_units, assignments, rng):
    kernel = response.kernel_sums(data, n_units, rng)
    _, pooled, _, _ = response.assignment_statistics(kernel.counts, assignments,
                                                     len(data.response), kernel.variances,
                                                     data.profile)
    return standardise(pooled, OneSided.NEUTRAL)[0]


def probe_test(data, n_units, assignments, rng):
    """The shipped response test with the chain of VARIANT['name'] (same rng use for T_j)."""
    out = SHIPPED(data, n_units, assignments, rng)
    name = VARIANT["name"]
    if name == "shipped":
        return out
    spread_rng = np.random.default_rng(12345)
    n_features = len(data.response)
    if name == "sum":
        z = spread_transitions(data, n_units, assignments, spread_rng)
        chain = tippett(out.chain_null, z.sum(axis=1))
    else:
        spread = spread_units if name == "foldgu" else spread_transitions
        z_s = spread(data, n_units, assignments, spread_rng)
        z_s = z_s * (data.residual.std(axis=0) >= NOISE_FLOOR * data.spread)
        z_l = level_z(data, n_units, assignments, rng)
        if name == "eachg":  # every feature's T_j and every noisy feature's S_j on their own
            noisy = np.flatnonzero(z_s.any(axis=0))
            parts = [z_l[:, j] for j in range(n_features)] + [z_s[:, j] for j in noisy]
        elif name == "foldmax":  # per feature the larger of z(T_j) and z(S_j)
            parts = [np.maximum(z_l[:, j], z_s[:, j]) if z_s[:, j].any() else z_l[:, j]
                     for j in range(n_features)]
        else:
            parts = [z_l[:, j] + z_s[:, j] for j in range(n_features)]
        if z_l.shape[1] > n_features:
            parts.append(z_l[:, n_features:].sum(axis=1))
        chain = tippett(*parts)
    pvalue = float(exceedance_pvalues(chain[:, None], chain[:1])[0])
    return dataclasses.replace(out, chain_statistic=float(chain[0]), chain_pvalue=pvalue,
                               chain_null=chain)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--designs", required=True)
    parser.add_argument("--reps", type=int, default=100)
    parser.add_argument("--first-rep", type=int, default=0)
    parser.add_argument("--variants", default="shipped,sum,foldg,foldgu")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    rb.DESIGNS["lengths_runs100"] = partial(lengths, runs=100)  # the lengths design, 100 runs
    conditional.response_test = probe_test
    transitions_module.per_state_residual = _capture
    rb.SETTINGS.update(alpha=0.05, permutations=99)
    names = rb.select(args.designs, list(rb.DESIGNS), rb.ALIASES)
    variants = args.variants.split(",")
    rejected = {n: dict.fromkeys(variants, 0) for n in names}
    reps = range(args.first_rep, args.first_rep + args.reps)
    for name in names:
        for rep in reps:
            rng, seed = rb.seeds(name, rep)
            design = rb.DESIGNS[name](rng)
            for variant in variants:
                VARIANT["name"] = variant
                rejected[name][variant] += rb.response(design, seed) <= 0.05
        print(name, {v: round(k / len(reps), 3) for v, k in rejected[name].items()}, flush=True)
    result = {"reps": len(reps), "first_rep": args.first_rep, "rejected": rejected}
    if args.out:
        args.out.write_text(json.dumps(result, indent=1) + "\n")
    return result


if __name__ == "__main__":
    main()
