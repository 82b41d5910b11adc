"""Issue 21's equivalence acceptance for the test-inversion interval of the corrected deviation
(scripts/deviation_calibrated_probe.py ``u_inv``, ``g_inv`` and their CLs versions, not
shipped): a 0.5 s reaction delay and 20
car-following episodes, compared as scripts/equivalence_delay.py compares them (features gap, v,
v_leader, input v_leader, paired by run id, 4 bins), against the shipped bound on the same draws.

Per replication the one-sided upper 95 % bound of the acceleration response's deviation (``v``,
m/s²) — the inverted interval's 90 % upper end, as a root — and the share of replications
declared equivalent (upper bound below δ) at each δ of ``--margins`` and at the true deviation
(benchmarks/results/equivalence_delay.json), for the delay (seeds ``seed0 + r``) and the
same-law control (kind ``none``, seeds ``100000 + seed0 + r``).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/equivalence_inversion_probe.py --reps 400 \\
        --out benchmarks/results/equivalence_inversion_probe.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "scripts")]
from deviation_calibrated_probe import permutation_recording  # noqa: E402
from equivalence_delay import CONTROL_SEEDS, FEATURE, OPTIONS, wilson  # noqa: E402
from response_coverage import effects  # noqa: E402

from response_designs import defect  # noqa: E402
from simcred.compare import conditional  # noqa: E402

#: The inverted intervals of scripts/deviation_calibrated_probe.py compared with the shipped one.
INTERVALS = ("u_inv", "g_inv", "uc_inv", "gc_inv", "r_inv", "rp16_inv", "rp50_inv", "rf_inv")


def upper_bounds(kind: str, seeds: range, args) -> dict[str, np.ndarray]:
    """Per replication, the shipped and the inverted one-sided upper 95 % bounds of ``v``."""
    rows: list = []
    shipped_upper = []
    options = OPTIONS | {"bins": args.bins, "permutations": args.permutations}
    effect_call = conditional.response_effects
    try:
        conditional.response_effects = permutation_recording(rows)
        for seed in seeds:
            d = defect(np.random.default_rng(seed), kind, runs=args.runs)
            shipped_upper.append(effects(d, seed, args.bootstrap, **options)[FEATURE].upper)
    finally:
        conditional.response_effects = effect_call
    return {"shipped": np.asarray(shipped_upper)} | {
        name: np.sqrt(np.maximum([r[FEATURE][f"{name}_0.9_high"] for r in rows], 0.0))
        for name in INTERVALS}


def shares(upper: np.ndarray, margins: list[float]) -> dict[str, list]:
    n = len(upper)
    return {f"{m:g}": [int((upper < m).sum()), n, *wilson(int((upper < m).sum()), n)]
            for m in margins}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--bins", type=int, default=4)
    parser.add_argument("--permutations", type=int, default=999)
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--kinds", default="delay,none")
    parser.add_argument("--truth", default=str(ROOT / "benchmarks/results/"
                                               "equivalence_delay.json"))
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    true = json.loads(Path(args.truth).read_text())["truth"]["delay"][FEATURE]["deviation"]
    margins = [0.012, 0.025, 0.05, true, 0.075, 0.1, 0.15]
    table = {}
    for kind in args.kinds.split(","):
        start = args.seed0 + (CONTROL_SEEDS if kind == "none" else 0)
        bounds = upper_bounds(kind, range(start, start + args.reps), args)
        table[kind] = {name: {"equivalent": shares(u, margins),
                              "upper_quantiles": np.quantile(u, [0.05, 0.5, 0.95]).tolist(),
                              "upper_mean": float(u.mean())} for name, u in bounds.items()}
        print(kind, json.dumps(table[kind]), flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": vars(args) | {"out": str(args.out)},
                                        "true_deviation": true, "table": table},
                                       indent=1) + "\n")


if __name__ == "__main__":
    main()
