"""Speed of path b (issue 23 acceptance): compare_hidden on 2 × RUNS runs × STEPS steps, with
the fully observed run-level comparison of the same sets timed in the same process (ratio).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/hidden_bench.py --runs 1000 --steps 200 \
        --out benchmarks/results/observed_hmm_speed.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import observed_universe as universe  # noqa: E402
from simcred.compare import compare  # noqa: E402
from simcred.compare.hidden import compare_hidden  # noqa: E402
from simcred.seeds import stream  # noqa: E402


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--cal-runs", type=int, default=50)
    parser.add_argument("--resamples", type=int, default=99)
    parser.add_argument("--out", default="observed_hmm_speed.json")
    args = parser.parse_args(argv)
    rng = stream(1, 0)
    sim, truth = universe.truth(rng, args.runs, args.steps), universe.truth(rng, args.runs,
                                                                             args.steps)
    rec = universe.recording(rng, args.runs, args.steps)
    cal = universe.calibration_pairs(rng, args.cal_runs, args.steps)
    start = time.perf_counter()
    full = compare(sim, truth, features=["v"], bins=5, alpha=0.05, permutations=args.resamples,
                   seed=1)
    full_s = time.perf_counter() - start
    start = time.perf_counter()
    hmm = compare_hidden(sim, rec, observed="b", calibration=cal, features=["v"], bins=5,
                         n_resamples=args.resamples, seed=1)
    hmm_s = time.perf_counter() - start
    out = {"args": vars(args), "cpus": os.cpu_count(), "load": os.getloadavg(),
           "full_seconds": round(full_s, 2), "hmm_seconds": round(hmm_s, 2),
           "ratio": round(hmm_s / full_s, 1), "hmm_pvalue": hmm.pvalue,
           "full_pvalue": full.chain.pvalue}
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(out)


if __name__ == "__main__":
    main()
