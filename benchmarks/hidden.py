"""Benchmark of path b (issue 23 acceptance "2 × 1,000 runs × 200 steps in < 60 s on 2 cores"):
prints a table, writes benchmarks/results/hidden.json.

The manufactured universe of tests/observed_universe.py: a simulated side and a recorded side
(noise, delay, dropouts, bias) of RUNS runs × STEPS steps each, 50 calibration pairs, 5 bins of
``v``, 99 resamples, seed 1. Cases, in this one process (so their ratio is measured under the
same load):

* ``full`` — the fully observed run-level comparison of the simulated side with a second truth
  set (``compare``; reference, ratio 1.00);
* ``hmm`` — ``compare_hidden(..., observed="b")`` (path b).

Times are best-of-k wall-clock seconds of the comparison call alone (data generation excluded).
``--profile`` runs the hmm case once under cProfile and prints the top functions by cumulative
time. On a shared machine absolute seconds are noisy; the ratio is the number to compare.

Usage: python benchmarks/hidden.py [--small] [--repeats K] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
from _timing import best_of, machine, save_results  # noqa: E402

import observed_universe as universe  # noqa: E402
from simcred.compare import compare  # noqa: E402
from simcred.compare.hidden import compare_hidden  # noqa: E402
from simcred.seeds import stream  # noqa: E402

BINS, RESAMPLES, SEED, CAL_RUNS = 5, 99, 1, 50
TARGET = 60.0  # seconds for the hmm case at 2 × 1,000 runs × 200 steps


def data(runs: int, steps: int) -> dict:
    rng = stream(SEED, 0)
    sim, truth = universe.truth(rng, runs, steps), universe.truth(rng, runs, steps)
    rec = universe.recording(rng, runs, steps)
    cal = universe.calibration_pairs(rng, CAL_RUNS, steps)
    return {"sim": sim, "truth": truth, "rec": rec, "cal": cal}


def cases(d: dict) -> dict:
    return {
        "full": lambda: compare(d["sim"], d["truth"], features=["v"], bins=BINS, alpha=0.05,
                                permutations=RESAMPLES, seed=SEED).chain.pvalue,
        "hmm": lambda: compare_hidden(d["sim"], d["rec"], observed="b", calibration=d["cal"],
                                      features=["v"], bins=BINS, n_resamples=RESAMPLES,
                                      seed=SEED).pvalue,
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--small", action="store_true", help="2 × 200 runs (a quick look)")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/hidden.json"))
    args = parser.parse_args(argv)
    runs, steps = (200, 200) if args.small else (1000, 200)
    run = cases(data(runs, steps))
    if args.profile:
        prof = cProfile.Profile()
        prof.runcall(run["hmm"])
        pstats.Stats(prof).sort_stats("cumulative").print_stats(20)
        return
    rows = {}
    for name, fn in run.items():
        seconds, pvalue = best_of(fn, args.repeats)
        rows[name] = {"seconds": round(seconds, 3), "pvalue": pvalue}
    for row in rows.values():
        row["ratio"] = round(row["seconds"] / rows["full"]["seconds"], 1)
    table = Table(title=f"path b, 2 × {runs} runs × {steps} steps, {RESAMPLES} resamples")
    for col in ("case", "seconds", "ratio", "p-value"):
        table.add_column(col)
    for name, row in rows.items():
        table.add_row(name, f"{row['seconds']:.2f}", f"{row['ratio']:.1f}", f"{row['pvalue']:.3f}")
    Console().print(table)
    result = {"runs": runs, "steps": steps, "resamples": RESAMPLES, "machine": machine(),
              "load": os.getloadavg(), "target_seconds": TARGET, "cases": rows}
    if not args.small:
        save_results(Path(args.out), result)


if __name__ == "__main__":
    main()
