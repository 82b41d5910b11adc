"""Chain p-values and effect numbers of the response test on five of the bench's designs, for
comparing two versions of the code on the same data (run once per version, then --compare).

    PYTHONPATH=/path/to/old/src .venv/bin/python scripts/response_identity.py old.json
    .venv/bin/python scripts/response_identity.py new.json
    .venv/bin/python scripts/response_identity.py --compare old.json new.json
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import response_bench as bench  # noqa: E402

from simcred.compare import compare  # noqa: E402

DESIGNS = ("lengths_markov", "leaders_split", "grouped", "defect:delay:40:paired",
           "defect:variance:40:unpaired")


def measure(reps: int) -> dict:
    rows = {}
    for name in DESIGNS:
        for rep in range(reps):
            rng, seed = bench.seeds(name, rep)
            d = bench.DESIGNS[name](rng)
            c = compare(d.a, d.b, features=list(d.features), test="response", inputs=d.inputs,
                        pair_by=d.pair_by, group_by=d.group_by, permutations=99, seed=seed,
                        alpha=0.05, bins=4, bootstrap=20)
            rows[f"{name}/{rep}"] = {"chain": c.chain.pvalue, "effect": [
                [f.estimate, f.low, f.high, f.shift, f.pvalue] for f in c.response.effect.features]}
    return rows


def differences(old: dict, new: dict) -> dict:
    numbers = [(x, y) for k in old for fa, fb in zip(old[k]["effect"], new[k]["effect"],
                                                      strict=True)
               for x, y in zip(fa[:4], fb[:4], strict=True)
               if x is not None and y is not None and not math.isnan(x)]
    return {"comparisons": len(old),
            "chain_pvalues_identical": sum(old[k]["chain"] == new[k]["chain"] for k in old),
            "effect_pvalues_identical": sum(fa[4] == fb[4] for k in old for fa, fb in zip(
                old[k]["effect"], new[k]["effect"], strict=True)),
            "effect_numbers": len(numbers),
            "largest_relative_difference": max(abs(x - y) / max(abs(x), 1e-12)
                                               for x, y in numbers)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?")
    parser.add_argument("--reps", type=int, default=30)
    parser.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    args = parser.parse_args()
    if args.compare:
        old, new = (json.loads(Path(p).read_text())["rows"] for p in args.compare)
        print(json.dumps(differences(old, new), indent=1))
        return
    Path(args.out).write_text(json.dumps({"reps": args.reps, "rows": measure(args.reps)}))


if __name__ == "__main__":
    main()
