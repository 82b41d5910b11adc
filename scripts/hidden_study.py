"""Size and power of path b (the HMM comparison, issue 23) in the manufactured universe.

tests/observed_universe.py, one feature (the follower's speed ``v``, 5 bins; with u and v, 4
bins each, rare corner states were never seen in 20 calibration runs, so no emission model could
be estimated for them). Per replication, fresh data of ``--runs`` × ``--steps`` per side and
``--cal-runs`` paired GT/SD calibration runs:

* ``hmm``: :func:`simcred.compare.hidden.compare_hidden` (``--resamples`` bootstrap replicates);
* ``direct``: run-level comparison of the simulation's truth against the recording;
* ``full``: run-level comparison against the recorded process's ground truth (fully observed).

Laws as in scripts/observed_study.py (H0; gain 0.7; reaction delay 1.0 s), fixed beforehand.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/hidden_study.py --reps 200 \
        --out benchmarks/results/observed_hmm.json
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
from simcred.compare.hidden import compare_hidden  # noqa: E402
from simcred.seeds import stream  # noqa: E402

ALPHA = 0.05
OPTIONS = {"features": ["v"], "bins": 5, "alpha": ALPHA, "permutations": 99,
           "multiplicity": "fwer"}
LAWS = {"H0": {}, "gain": {"gain": 0.7}, "reaction": {"reaction": 10}}
ROUTES = ("hmm", "direct", "full")


def replicate(law: dict, rep: int, args) -> tuple[dict[str, bool], dict[str, float]]:
    rng = stream(args.seed, rep)
    sim = universe.truth(rng, args.runs, args.steps)
    states = universe.hidden(rng, args.runs, args.steps, **law)
    recorded = universe.traceset(universe.record(rng, states))
    real_truth = universe.traceset(states[:, universe.BURN:])
    calibration = universe.calibration_pairs(rng, args.cal_runs, args.steps)
    seed = int(rng.integers(2**32))
    hmm = compare_hidden(sim, recorded, observed="b", calibration=calibration, features=["v"],
                         bins=OPTIONS["bins"], alpha=ALPHA, n_resamples=args.resamples,
                         seed=seed)
    return ({"hmm": hmm.rejected,
             "direct": bool(compare(sim, recorded, seed=seed, **OPTIONS).chain.rejected),
             "full": bool(compare(sim, real_truth, seed=seed, **OPTIONS).chain.rejected)},
            {"pvalue": hmm.pvalue, "markov_pvalue": hmm.markov_pvalue,
             "emission_pvalue": hmm.emission_pvalue})


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--runs", type=int, default=60)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--cal-runs", type=int, default=20)
    parser.add_argument("--resamples", type=int, default=49)
    parser.add_argument("--seed", type=int, default=2323)
    parser.add_argument("--first", type=int, default=0, help="first replication index (to "
                        "extend a study with fresh replications)")
    parser.add_argument("--laws", default="H0,reaction,gain")
    parser.add_argument("--out", default="observed_hmm.json")
    args = parser.parse_args(argv)
    out = {"args": vars(args), "options": OPTIONS, "laws": LAWS,
           "sensor": universe.SENSOR.to_dict(), "table": {}}
    start = time.perf_counter()
    for name in args.laws.split(","):
        results = [replicate(LAWS[name], rep, args)
                   for rep in range(args.first, args.first + args.reps)]
        hits = np.array([[r[0][k] for k in ROUTES] for r in results])
        checks = np.array([[r[1][k] for k in ("pvalue", "markov_pvalue", "emission_pvalue")]
                           for r in results])
        rate = hits.mean(axis=0)
        out["table"][name] = {
            **{r: {"rejection": float(rate[k]),
                   "se": float(np.sqrt(rate[k] * (1 - rate[k]) / args.reps))}
               for k, r in enumerate(ROUTES)},
            "hmm_pvalue_quartiles": np.quantile(checks[:, 0], [0.25, 0.5, 0.75]).tolist(),
            "markov_check_rejects": float(np.mean(checks[:, 1] <= ALPHA)),
            "emission_check_rejects": float(np.mean(checks[:, 2] <= ALPHA))}
        out["seconds"] = round(time.perf_counter() - start, 1)
        Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
        print(name, {r: round(float(rate[k]), 3) for k, r in enumerate(ROUTES)}, flush=True)


if __name__ == "__main__":
    main()
