"""Coverage of the response test's effect intervals, and the size of its equivalence test.

For each design (tests/response_designs.py ``defect`` kinds, paired, known nonzero deviation):
the "true" response deviation of every response feature is the estimate on one draw of
``--truth-runs`` runs (the population value of the same estimand); then ``--reps`` draws at
``--runs`` runs give the share of 90 % and 95 % intervals that contain it, and the share of
equivalence declarations at margin = the true deviation (must be ≤ α: the boundary of H0).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_coverage.py --reps 400
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from response_designs import defect  # noqa: E402
from simcred.compare import compare  # noqa: E402


def estimate(d, seed, level_bootstrap, margin=None):
    result = compare(d.a, d.b, features=list(d.features), test="response", pair_by=d.pair_by,
                     bins=4, permutations=19, seed=seed, alpha=0.05, bootstrap=level_bootstrap,
                     margin=margin)
    return {f.feature: f for f in result.response.effect.features}


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=400)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--truth-runs", type=int, default=1500)
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--out", default="coverage.json")
    args = parser.parse_args(argv)
    from simcred.compare import conditional

    table = {}
    for kind in args.kinds.split(","):
        truth = estimate(defect(np.random.default_rng(10**6), kind, runs=args.truth_runs),
                         0, 50)
        true = {name: f.plugin for name, f in truth.items()}
        hits = {level: {name: 0 for name in true} for level in (0.90, 0.95)}
        equivalent = {name: 0 for name in true}
        for rep in range(args.reps):
            d = defect(np.random.default_rng(rep), kind, runs=args.runs)
            for level in (0.90, 0.95):
                conditional.INTERVAL_LEVEL = level
                found = estimate(d, rep, args.bootstrap,
                                 margin={n: true[n] for n in true} if level == 0.95 else None)
                for name, f in found.items():
                    hits[level][name] += f.low <= true[name] <= f.high
                    if level == 0.95:
                        equivalent[name] += bool(f.equivalent)
        conditional.INTERVAL_LEVEL = 0.95
        table[kind] = {"truth": true,
                       "coverage": {str(level): {n: k / args.reps for n, k in h.items()}
                                    for level, h in hits.items()},
                       "equivalent_at_truth": {n: k / args.reps for n, k in equivalent.items()}}
        print(kind, json.dumps(table[kind]), flush=True)
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
