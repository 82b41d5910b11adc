"""Size and power of the observed comparison (issue 23) in the manufactured universe.

tests/observed_universe.py: one hidden car-following process, recorded once as ground truth
and once through a sensor (bias 0.3, delay 0.3 s, noise 0.25, 5 % dropouts held). Per
replication, on fresh data of ``--runs`` runs × ``--steps`` steps per side:

* ``direct``: simulation ground truth against the recording, compared as they are;
* ``declared``: the observation-model route with the true sensor declared;
* ``estimated``: the route with a sensor model estimated on ``--cal-runs`` fresh paired GT/SD
  runs (``--cal-bootstrap`` parameter draws carry its uncertainty);
* ``full``: the fully observed comparison (ground truth against ground truth), the reference
  for power.

Under H0 the recorded process is the simulated one; under ``gain`` its gain is 0.7 (1.0 in the
simulation), under ``reaction`` its reaction delay is 1.0 s (0.5 s). Both effects were fixed
before the first run. Run-level test, 4 bins per feature, P = 99, α = 0.05, FWER.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/observed_study.py --reps 1000 \
        --out benchmarks/results/observed.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import observed_universe as universe  # noqa: E402
from simcred.compare import compare  # noqa: E402
from simcred.compare.observed import compare_observed, estimate_sensor  # noqa: E402
from simcred.seeds import stream  # noqa: E402

ALPHA = 0.05
OPTIONS = {"features": ["u", "v"], "bins": 4, "alpha": ALPHA, "permutations": 99,
           "multiplicity": "fwer"}
LAWS = {"H0": {}, "gain": {"gain": 0.7}, "reaction": {"reaction": 10}}
ROUTES = ("direct", "declared", "estimated", "full")


def replicate(law: dict, rep: int, args) -> dict[str, bool]:
    rng = stream(args.seed, rep)
    sim = universe.truth(rng, args.runs, args.steps)
    states = universe.hidden(rng, args.runs, args.steps, **law)
    recorded = universe.traceset(universe.record(rng, states))
    real_truth = universe.traceset(states[:, universe.BURN:])
    gt, sd = universe.calibration_pairs(rng, args.cal_runs, args.steps)
    model = estimate_sensor(gt, sd, bootstrap=args.cal_bootstrap, seed=rng)
    seed = int(rng.integers(2**32))
    return {
        "direct": bool(compare(sim, recorded, seed=seed, **OPTIONS).chain.rejected),
        "declared": compare_observed(sim, recorded, observed="b", sensor=universe.SENSOR,
                                     seed=seed, **OPTIONS).rejected,
        "estimated": compare_observed(sim, recorded, observed="b", sensor=model, seed=seed,
                                      **OPTIONS).rejected,
        "full": bool(compare(sim, real_truth, seed=seed, **OPTIONS).chain.rejected),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--runs", type=int, default=60)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--cal-runs", type=int, default=20)
    parser.add_argument("--cal-bootstrap", type=int, default=30)
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--laws", default="H0,gain,reaction")
    parser.add_argument("--features", default="u,v")
    parser.add_argument("--bins", type=int, default=4)
    parser.add_argument("--out", default="observed.json")
    args = parser.parse_args(argv)
    OPTIONS.update(features=args.features.split(","), bins=args.bins)
    table = {}
    out = {"args": vars(args), "options": OPTIONS, "laws": LAWS, "sensor":
           universe.SENSOR.to_dict(), "table": table}
    start = time.perf_counter()
    for name in args.laws.split(","):
        hits = np.array([[replicate(LAWS[name], rep, args)[r] for r in ROUTES]
                         for rep in range(args.reps)])
        rate = hits.mean(axis=0)
        table[name] = {r: {"rejection": float(rate[k]),
                           "se": float(np.sqrt(rate[k] * (1 - rate[k]) / args.reps))}
                       for k, r in enumerate(ROUTES)}
        print(name, {r: round(v["rejection"], 3) for r, v in table[name].items()}, flush=True)
        out["seconds"] = round(time.perf_counter() - start, 1)
        Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
