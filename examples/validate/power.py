"""Family-wise error rates of `simcred validate` on the synthetic universe (docs/validate.md).

The test case is the whole grid, 5 <= v <= 30 m/s in five cells (K = 5), tolerance 0.5 /s on
x's response deviation (simcred.validate.synthetic.TOLERANCE: an AR-coefficient error of about
0.075). Candidates with a known truth (true deviations measured on 1,500 runs per set, module
docs of simcred.validate.synthetic):

* ``same`` (effect 0 everywhere, deviation 0): truly valid. Measured: how often the test case
  comes out NOT VALID (family-wise false NOT VALID; bound alpha = 0.05) and how often VALID;
* ``within`` (effect 0.05 everywhere, deviation 0.31-0.35 < 0.5): truly valid, not identical;
  NOT VALID here is also wrong (bound alpha);
* ``beyond`` (effect 0.1 everywhere, deviation 0.71-0.73 > 0.5): truly not valid. VALID is a
  false validation (bound alpha; intersection-union over the cells);
* ``above 20`` (effect 0.15 above 20 m/s only): truly not valid (deviation ≥ 1.18 in two cells).

Each candidate against a fresh reference per seed, ``--seeds`` seeds (default 200) at each size
(runs per set). Rates with Clopper-Pearson 95 % intervals; JSON with ``--out``.

Usage: python examples/validate/power.py [--seeds 200] [--runs 100 400] [--out power.json]
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

from scipy.stats import binomtest

from simcred.validate.loop import Inputs, validate
from simcred.validate.synthetic import universe, validation_spec

#: name -> (effect, v_switch, truly valid)
CANDIDATES = {"same": (0.0, 0.0, True), "within": (0.05, 0.0, True),
              "beyond": (0.1, 0.0, False), "above 20": (0.15, 20.0, False)}
STEPS = 150


def verdict(name: str, seed: int, runs: int) -> str:
    effect, switch, _ = CANDIDATES[name]
    reference = universe(runs, STEPS, seed=1000 + seed)
    candidate = universe(runs, STEPS, seed=2000 + seed, effect=effect, v_switch=switch,
                         name="sim")
    return validate(validation_spec(seed), Inputs(reference, {"sim": candidate}, ())).verdict


def rate(k: int, n: int) -> dict:
    low, high = binomtest(k, n).proportion_ci(0.95, method="exact")
    return {"count": k, "of": n, "rate": k / n, "ci95": [low, high]}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--runs", type=int, nargs="+", default=[100, 400])
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    rows = []
    print(f"{'candidate':>9} {'runs':>5} {'truth':>9} {'VALID':>14} {'NOT VALID':>14} "
          f"{'INCONCL.':>9} {'wrong verdicts (bound 0.05)':>28}")
    for runs in args.runs:
        for name, (_, _, truly_valid) in CANDIDATES.items():
            counts = Counter(verdict(name, seed, runs) for seed in range(args.seeds))
            wrong = counts["not valid"] if truly_valid else counts["valid"]
            row = {"candidate": name, "runs": runs, "seeds": args.seeds,
                   "truly_valid": truly_valid,
                   "valid": rate(counts["valid"], args.seeds),
                   "not_valid": rate(counts["not valid"], args.seeds),
                   "inconclusive": rate(counts["inconclusive"], args.seeds),
                   "wrong": rate(wrong, args.seeds)}
            rows.append(row)
            low, high = row["wrong"]["ci95"]
            print(f"{name:>9} {runs:>5} {'valid' if truly_valid else 'not valid':>9} "
                  f"{counts['valid']:>8} / {args.seeds:<3} {counts['not valid']:>8} / "
                  f"{args.seeds:<3} {counts['inconclusive']:>9} "
                  f"{wrong / args.seeds:>12.3f} ({low:.3f}-{high:.3f})", flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"alpha": 0.05, "test_case_cells": 5, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
