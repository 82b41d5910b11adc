"""Coverage of the response test's effect intervals, and the size of its equivalence test.

For each design (tests/response_designs.py ``defect`` kinds, paired, known nonzero deviation):
the true response deviation of every response feature is the population value of the estimand
(effect.py: states holding ≥ 0.5 % of each side's transitions, weighted by the average share,
both shares of the two laws, so the same quantity at every number of runs), computed as
``√(mean θ̃)`` over ``--truth-draws`` independent draws of ``--truth-runs`` pairs (θ̃ the
bias-corrected squared deviation: unbiased, so the mean over draws converges to it; its
standard error is printed). Then ``--reps`` draws at ``--runs`` runs give the share of 90 % and
95 % intervals that contain it (and on which side they miss), and the share of equivalence
declarations at margin = the true deviation (must be ≤ α = 0.05: the boundary of H0).

``--null-sizes``: the same-law control (kind ``none``): mean estimate, mean one-sided 95 %
upper bound and the share of estimates that are exactly 0, per number of pairs.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_coverage.py --reps 400
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from response_designs import defect  # noqa: E402
from simcred.compare import compare  # noqa: E402

LEVELS = (0.90, 0.95)


def effects(d, seed, bootstrap, margin=None, **options):
    """Per response feature, the effect of ``d`` (``options`` override the comparison's
    ``features``, ``inputs``, ``bins`` and ``permutations``: d.features, none, 4, 19)."""
    settings = {"features": list(d.features), "bins": 4, "permutations": 19} | options
    result = compare(d.a, d.b, test="response", pair_by=d.pair_by, seed=seed, alpha=0.05,
                     bootstrap=bootstrap, margin=margin, **settings)
    return {f.feature: f for f in result.response.effect.features}


def truth(kind, draws, runs, **options):
    """Per feature: (true deviation, its standard error, true shift, its standard error) from
    ``draws`` draws of ``runs`` (the shift's plug-in is its mean over the draws); ``options``
    as :func:`effects` takes them."""
    squared, shifts = {}, {}
    for i in range(draws):
        for name, f in effects(defect(np.random.default_rng(10**6 + i), kind, runs=runs),
                               i, 2, **options).items():
            squared.setdefault(name, []).append(f.squared)
            shifts.setdefault(name, []).append(f.shift)
    out = {}
    for name, values in squared.items():
        mean, se = float(np.mean(values)), float(np.std(values, ddof=1) / np.sqrt(draws))
        root = np.sqrt(max(mean, 0.0))
        shift = shifts[name]
        out[name] = (float(root), float(se / (2 * root)) if root > 0 else float("nan"),
                     float(np.mean(shift)), float(np.std(shift, ddof=1) / np.sqrt(draws)))
    return out


def coverage(kind, true, reps, runs, bootstrap, seed0=0, true_shift=None, permutations=19):
    true_shift = true_shift or {}
    counts = {name: {"cover": {lv: 0 for lv in LEVELS}, "low_above": {lv: 0 for lv in LEVELS},
                     "high_below": {lv: 0 for lv in LEVELS}, "width95": 0.0, "equivalent": 0,
                     "estimate": 0.0, "shift_cover": {lv: 0 for lv in LEVELS},
                     "shift_low_above": {lv: 0 for lv in LEVELS},
                     "shift_high_below": {lv: 0 for lv in LEVELS}} for name in true}
    for rep in range(seed0, seed0 + reps):
        d = defect(np.random.default_rng(rep), kind, runs=runs)
        found = effects(d, rep, bootstrap, margin={n: t for n, t in true.items() if t > 1e-9},
                        permutations=permutations)
        for name, f in found.items():
            c, t = counts[name], true[name]
            for lv in LEVELS:
                low, high = f.bounds((1 - lv) / 2)
                c["cover"][lv] += low <= t <= high
                c["low_above"][lv] += low > t
                c["high_below"][lv] += high < t
                if lv == 0.95:
                    c["width95"] += high - low
                if name in true_shift:
                    s_low, s_high = f.shift_bounds((1 - lv) / 2)
                    c["shift_cover"][lv] += s_low <= true_shift[name] <= s_high
                    c["shift_low_above"][lv] += s_low > true_shift[name]
                    c["shift_high_below"][lv] += s_high < true_shift[name]
            c["equivalent"] += bool(f.equivalent) if t > 1e-9 else 0
            c["estimate"] += f.estimate
    return {name: {"coverage": {str(lv): c["cover"][lv] / reps for lv in LEVELS},
                   "low_above_truth": {str(lv): c["low_above"][lv] / reps for lv in LEVELS},
                   "high_below_truth": {str(lv): c["high_below"][lv] / reps for lv in LEVELS},
                   "mean_width_95": c["width95"] / reps, "mean_estimate": c["estimate"] / reps,
                   "equivalent_at_truth": c["equivalent"] / reps,
                   "shift_coverage": {str(lv): c["shift_cover"][lv] / reps for lv in LEVELS},
                   "shift_low_above_truth": {str(lv): c["shift_low_above"][lv] / reps
                                             for lv in LEVELS},
                   "shift_high_below_truth": {str(lv): c["shift_high_below"][lv] / reps
                                              for lv in LEVELS}}
            for name, c in counts.items()}


def null_check(sizes, reps, bootstrap):
    out = {}
    for runs in sizes:
        rows = {}
        for rep in range(reps):
            d = defect(np.random.default_rng(50_000 + rep), "none", runs=runs)
            for name, f in effects(d, rep, bootstrap).items():
                r = rows.setdefault(name, {"estimate": [], "upper": [], "zero": []})
                r["estimate"].append(f.estimate)
                r["upper"].append(f.upper)
                r["zero"].append(f.estimate == 0)
        out[runs] = {name: {k: float(np.mean(v)) for k, v in r.items()}
                     for name, r in rows.items()}
        print("none", runs, json.dumps(out[runs]), flush=True)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=400)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--truth-runs", type=int, default=1500)
    parser.add_argument("--truth-draws", type=int, default=30)
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--seed0", type=int, default=0, help="first replication's seed")
    parser.add_argument("--null-sizes", default="")
    parser.add_argument("--null-reps", type=int, default=50)
    parser.add_argument("--permutations", type=int, default=19,
                        help="the effect's permutation null (sets the upper bounds' floor)")
    parser.add_argument("--truth-from", metavar="JSON",
                        help="take the truths from an earlier run's output (same designs)")
    parser.add_argument("--out", default="coverage.json")
    args = parser.parse_args(argv)
    known = json.loads(Path(args.truth_from).read_text())["table"] if args.truth_from else {}
    table = {}
    for kind in filter(None, args.kinds.split(",")):
        start = time.time()
        true = {n: (t["truth"], t["truth_se"], t["true_shift"], t["true_shift_se"])
                for n, t in known[kind].items()} if kind in known \
            else truth(kind, args.truth_draws, args.truth_runs)
        cov = coverage(kind, {n: t[0] for n, t in true.items()}, args.reps, args.runs,
                       args.bootstrap, args.seed0, {n: t[2] for n, t in true.items()},
                       args.permutations)
        table[kind] = {name: {"truth": true[name][0], "truth_se": true[name][1],
                              "true_shift": true[name][2], "true_shift_se": true[name][3],
                              **cov[name]} for name in true}
        print(kind, f"{time.time() - start:.0f}s", json.dumps(table[kind]), flush=True)
    null = null_check([int(s) for s in args.null_sizes.split(",") if s], args.null_reps,
                      args.bootstrap)
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table, "null": null},
                                         indent=1))


if __name__ == "__main__":
    main()
