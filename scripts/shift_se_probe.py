"""The shift's standard error three ways against its sampling spread (issue 21, interval
coverage): the cluster bootstrap's (shipped), a delete-one-cluster jackknife's (the same
:meth:`ClusterSums.deviation`, weights ``1 − e_c``), each divided by the standard deviation of
the shift over independent replications of the design (tests/response_designs.py ``defect``,
40 paired runs, seeds 0 to ``--reps`` − 1, 500 bootstrap replicates).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_se_probe.py --reps 200 \\
        --out benchmarks/results/shift_se_probe.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
import response_coverage  # noqa: E402

from response_designs import defect  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = ("dv", "a")  # gap and v are kinematic consequences here (shift ~1e-15)


def recording(into: list):
    """``response_effects`` that also appends, per call, each response's (shift, bootstrap
    standard deviation, jackknife standard error)."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        if keep.any():
            n = entries.n_clusters
            jack = ClusterSums.of(entries, keep).deviation(np.ones((n, n)) - np.eye(n))["shift"]
            se = np.sqrt((n - 1) / n * ((jack - jack.mean(axis=1, keepdims=True))**2).sum(axis=1))
            into.append({f.feature: (f.shift, float(np.std(f.shift_replicates, ddof=1)),
                                     float(s)) for f, s in zip(out.features, se, strict=True)})
        return out
    return wrapped


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="delay,variance,clip")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    result = {}
    for kind in args.kinds.split(","):
        found: list = []
        conditional.response_effects = recording(found)
        for rep in range(args.reps):
            response_coverage.effects(defect(np.random.default_rng(rep), kind, runs=40), rep, 500)
        for name in RESPONSES:
            shift, boot, jack = (np.array([r[name][k] for r in found]) for k in range(3))
            spread = float(shift.std(ddof=1))
            result[f"{kind}/{name}"] = {"sampling_sd": spread,
                                        "bootstrap_over_sampling": float(boot.mean() / spread),
                                        "jackknife_over_sampling": float(jack.mean() / spread)}
            print(kind, name, {k: round(v, 4) for k, v in result[f"{kind}/{name}"].items()},
                  flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": 40, "bootstrap": 500,
                                        "cells": result}, indent=1) + "\n")


if __name__ == "__main__":
    main()
