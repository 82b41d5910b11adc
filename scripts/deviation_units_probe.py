"""How many units each of the deviation's states rests on (issue 21, interval coverage; session 30).

The deviation's variance has a part of degree four in each state's response law (the squared
noise ``Σ w² V²`` of its squared differences). From fewer than four units no unbiased estimate
of such a part exists (docs/calibration.md, "Session 30"), so where the entering states rest on
two or three units of a side an interval's width has to assume the law's shape. Per design and
size (``--pairs``, seeds from 0, ``--reps`` draws) this counts, over the states that enter the
shipped effect, the units of the less visited side: its weighted mean and median, the weight
share of states with fewer than 4 and fewer than 8 units, and the number of entering states;
besides, the mean plug-in ``θ̂`` and estimate ``θ̃`` of each response (the noise share).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_units_probe.py \\
        --out benchmarks/results/deviation_units_probe.json
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
from shift_refit_probe import RESPONSES  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import Entries  # noqa: E402


def units(data, design) -> dict:
    """The units of the less visited side per entering state (their weighted mean as the
    shipped ``units_per_state``), and the weight of the states with few."""
    entries = Entries.of(data, design)
    keep = entries.entering()
    fewest = entries.visits()[keep].min(axis=1)
    w = entries.state_weights(keep)
    return {"states": int(keep.sum()), "median_units": float(np.median(fewest)),
            "weighted_mean_units": entries.fewest_units(keep),
            "weight_below_4": float(w[fewest < 4].sum()),
            "weight_below_8": float(w[fewest < 8].sum())}


def measure(kind: str, pairs: int, reps: int) -> list[dict]:
    shipped = effect.response_effects
    rows: list = []

    def both(data, design, *a, **kw):
        out = shipped(data, design, *a, **kw)
        rows.append(units(data, design) | {
            f"{f.feature}_{name}": value for f in out.features if f.feature in RESPONSES
            for name, value in (("plugin", f.plugin**2), ("squared", f.squared))})
        return out

    conditional.response_effects = both
    try:
        for rep in range(reps):
            response_coverage.effects(response_designs.defect(np.random.default_rng(rep), kind,
                                                              runs=pairs), rep, 20,
                                      permutations=19)
    finally:
        conditional.response_effects = shipped
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--pairs", default="40,160")
    parser.add_argument("--reps", type=int, default=20)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    cells = {}
    for pairs in map(int, args.pairs.split(",")):
        for kind in args.kinds.split(","):
            rows = measure(kind, pairs, args.reps)
            cells[f"{pairs}/{kind}"] = cell = {key: float(np.mean([r[key] for r in rows]))
                                               for key in rows[0]}
            print(pairs, kind, json.dumps(cell), flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                        "cells": cells}, indent=1) + "\n")


if __name__ == "__main__":
    main()
