"""A distance whose law depends on itself alone: the Mahalanobis distance of paired run
summaries, with the exact interval of its Hotelling statistic (issue 21, session 30;
exploratory, not shipped; docs/calibration.md, "Session 30").

Per pair ``p`` of a replay design (tests/response_designs.py ``defect``), ``d_p`` is the
difference of the two members' run summaries (:func:`simcred.compare.paired_runs.run_summaries`
of the features, ``k`` columns); the distance is ``Δ = √(μᵀ Σ⁻¹ μ)`` of the pairs' law. With
``n`` pairs, ``F = (n − k) / (k (n − 1)) · n d̄ᵀ S⁻¹ d̄`` has a noncentral F law with ``(k,
n − k)`` degrees of freedom and noncentrality ``n Δ²`` when ``d_p`` is normal, so the interval
comes from inverting that law (Reiser, Commun. Stat. Simul. Comput. 30, 2001) — no variance
of the estimate to estimate. Scored here for coverage of the truth (the plug-in from
``--truth-pairs`` pairs, less its bias ``k / n``) at 90 % and 95 % on the three defects of the
deviation's coverage runs. ``--summaries mean,sd`` keeps those summary columns only.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/summary_distance_probe.py --pairs 40 \\
        --reps 200 --out benchmarks/results/summary_distance_probe_40.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import brentq
from scipy.stats import ncf

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import response_designs  # noqa: E402
from simcred.compare.paired_runs import run_summaries  # noqa: E402

SUMMARIES = ("mean", "sd", "q10", "q50", "q90", "step")  # run_summaries' column blocks
LEVELS = (0.90, 0.95)


def differences(rng, kind: str, pairs: int, keep: list[int]) -> np.ndarray:
    """(pairs, k) differences of the members' run summaries (A − B) of one defect design."""
    design = response_designs.defect(rng, kind, runs=pairs)
    out = []
    for side in (design.a, design.b):
        summaries = run_summaries(side.features(design.features), side.offsets)
        j = len(design.features)
        out.append(summaries[:, [b * j + f for b in keep for f in range(j)]])
    return out[0] - out[1]


def hotelling_f(d: np.ndarray) -> float:
    n, k = d.shape
    mean = d.mean(axis=0)
    t2 = n * mean @ np.linalg.solve(np.cov(d, rowvar=False), mean)
    return (n - k) / (k * (n - 1)) * t2


def interval(d: np.ndarray, level: float) -> tuple[float, float]:
    """Bounds of Δ from inverting the noncentral F law of :func:`hotelling_f`."""
    n, k = d.shape
    f, tail = hotelling_f(d), (1 - level) / 2

    def at(q):  # the noncentrality where the observed F is the law's q-quantile
        if ncf.cdf(f, k, n - k, 0.0) <= q:
            return 0.0
        top = 1.0
        while ncf.cdf(f, k, n - k, top) > q:
            top *= 2
        return brentq(lambda lam: ncf.cdf(f, k, n - k, lam) - q, 0.0, top)

    return float(np.sqrt(at(1 - tail) / n)), float(np.sqrt(at(tail) / n))


def truth(kind: str, pairs: int, keep: list[int]) -> tuple[float, float]:
    """Δ from ``pairs`` pairs in draws of 500 (seeds from 10⁶), less the plug-in's bias, and
    the number of summary columns."""
    d = np.vstack([differences(np.random.default_rng(10**6 + i), kind, 500, keep)
                   for i in range(pairs // 500)])
    n, k = d.shape
    mean = d.mean(axis=0)
    square = mean @ np.linalg.solve(np.cov(d, rowvar=False), mean) * (n - k - 2) / (n - 1) - k / n
    return float(np.sqrt(max(square, 0.0))), k


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--truth-pairs", type=int, default=10_000)
    parser.add_argument("--summaries", default=",".join(SUMMARIES))
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    keep = [SUMMARIES.index(s) for s in args.summaries.split(",")]
    cells = {}
    for kind in args.kinds.split(","):
        true, k = truth(kind, args.truth_pairs, keep)
        bounds = [[interval(differences(np.random.default_rng(rep), kind, args.pairs, keep), lv)
                   for lv in LEVELS] for rep in range(args.seed0, args.seed0 + args.reps)]
        ends = np.array(bounds)  # (reps, levels, 2)
        cells[kind] = {"truth": true, "columns": k} | {
            f"{lv}": [float(np.mean((ends[:, i, 0] <= true) & (true <= ends[:, i, 1]))),
                      float(np.mean(ends[:, i, 0] > true)), float(np.mean(ends[:, i, 1] < true))]
            for i, lv in enumerate(LEVELS)}
        print(kind, json.dumps(cells[kind]), flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                        "cells": cells}, indent=1) + "\n")


if __name__ == "__main__":
    main()
