"""``validate`` with an observed reference (issue 23, item 3) in the manufactured universe.

tests/observed_universe.py: one hidden car-following process; the reference is its recording
through the sensor (bias 0.3, delay 0.3 s, noise 0.25, 5 % dropouts held, on ``u`` and ``v``);
the candidate writes ground truth. Per replication, on fresh data of ``--runs`` runs ×
``--steps`` steps per side, the validation of ``observed_universe.validation`` (response of
``v`` given ``u``, tolerance 0.25 m/s², cells of ``u`` 16-20-24 m/s, P = 99, α = 0.05) by:

* ``direct``: the recording as the reference, compared as it is;
* ``declared``: the reference declared observed through the true sensor;
* ``estimated``: declared observed through a sensor model estimated on ``--cal-runs`` fresh
  paired GT/SD runs with ``--cal-bootstrap`` parameter draws;
* ``full``: the recorded process's own ground truth as the reference (fully observed).

Laws: ``H0`` — the candidate is the recorded process; ``reaction`` — the candidate's reaction
delay is 1.0 s (the process's 0.5 s), a real delay the validation must still find. The design
(sizes, tolerance, laws) was fixed before the first run of this script.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/observed_validate.py --reps 200 \
        --out benchmarks/results/observed_validate.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import observed_universe as universe  # noqa: E402
from simcred.compare.observed import estimate_sensor  # noqa: E402
from simcred.seeds import stream  # noqa: E402
from simcred.validate.loop import Inputs, validate  # noqa: E402

LAWS = {"H0": {}, "reaction": {"reaction": 10}}
ROUTES = ("direct", "declared", "estimated", "full")


def replicate(law: dict, rep: int, args) -> dict[str, object]:
    rng = stream(args.seed, rep)
    candidate = universe.truth(rng, args.runs, args.steps, **law)
    states = universe.hidden(rng, args.runs, args.steps)
    recorded = universe.traceset(universe.record(rng, states))
    own_truth = universe.traceset(states[:, universe.BURN:])
    gt, sd = universe.calibration_pairs(rng, args.cal_runs, args.steps)
    model = estimate_sensor(gt, sd, bootstrap=args.cal_bootstrap, seed=rng)
    seed = int(rng.integers(2**31))
    runs = {"direct": (recorded, None), "declared": (recorded, universe.SENSOR),
            "estimated": (recorded, model), "full": (own_truth, None)}
    out: dict[str, object] = {}
    for route, (reference, sensor) in runs.items():
        spec = universe.validation(seed, sensor=sensor)
        result = validate(spec, Inputs(reference, {"sim": candidate}, (), sensor=sensor))
        out[route] = result.candidates["sim"].verdict
        if route == "declared":
            out["sensor_alone"] = [c.bounds[0].estimate for c in result.observation.effects["sim"]
                                   if c.bounds]
    return out


def summary(rows: list[dict]) -> dict[str, object]:
    n = len(rows)
    out: dict[str, object] = {"replications": n}
    for route in ROUTES:
        counts = Counter(r[route] for r in rows)
        rate = counts["not valid"] / n
        out[route] = {"verdicts": dict(counts), "not_valid_rate": rate,
                      "se": float(np.sqrt(rate * (1 - rate) / n))}
    effect = np.concatenate([r["sensor_alone"] for r in rows])
    out["sensor_alone_deviation"] = {"mean": float(effect.mean()),
                                     "quartiles": np.quantile(effect, [.25, .5, .75]).tolist()}
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--reps-h1", type=int, default=100)
    parser.add_argument("--runs", type=int, default=60)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--cal-runs", type=int, default=20)
    parser.add_argument("--cal-bootstrap", type=int, default=30)
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--out", default="observed_validate.json")
    args = parser.parse_args(argv)
    out: dict[str, object] = {"options": vars(args)}
    for name, law in LAWS.items():
        start = time.perf_counter()
        reps = args.reps if name == "H0" else args.reps_h1
        out[name] = summary([replicate(law, rep, args) for rep in range(reps)])
        out[name]["seconds"] = round(time.perf_counter() - start, 1)
        print(name, json.dumps(out[name]), flush=True)
        Path(args.out).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
