"""Benchmark of the conditional comparison (``test="response"``): prints a table, writes
benchmarks/results/response.json.

Two trace sets of 20,000 runs × 200 steps × 2 features (the AR(1) traits of
benchmarks/compare.py, B's level shifted by 0.05), run ids equal across the sets (so
``pair_by="run_id"`` pairs run i of A with run i of B) and a per-run fact
``metadata["run_info"][run_id]["driver"]`` with 200 drivers per set (``group_by="driver"``).
10 bins, 999 permutations, seed 1. Cases, each in its own process (peak RSS is per case):

* ``runs`` — the run-level test (reference, ratio 1.00);
* ``response`` unpaired (runs design), paired (``pair_by="run_id"``) and grouped
  (``group_by="driver"``), each with ``bootstrap=200``; the unpaired one with the default
  500 bootstrap replicates; and, as an extra row (not the target's case), the paired one with
  ``bootstrap=1``: the API has no switch for the effect's interval (``bootstrap=0`` means the
  default 500), one replicate is as near to off as it gets (estimate and p-value stay).

Target (issue): the paired and grouped tests within 2× of the runs test; peak memory reported.
Times are best-of-k wall-clock seconds of the ``compare`` call alone (data generation and hashing
excluded), with its CPU seconds and their ratio beside (on a shared machine under load the wall
ratio swings with the reference's own wall time; the target is judged on the wall ratio of a
quiet run); peak RSS is the child process's maximum. ``--profile CASE`` runs one case under
cProfile and prints the top functions by cumulative time.

``--alternate K`` instead runs the cases in turn, K rounds, in ONE process on the same data (a
case name ending in ``:serial`` runs with ``SIMCRED_MAX_THREADS=1``, the comparison on one
thread but for BLAS's own; one uncounted round on small sets first): each round's ratio to that
round's runs test, so that a drift of the machine's speed moves both (medians and ranges
printed; results/response_alternating.json). Peak memory is not per case there.

Usage: python benchmarks/response.py [--small] [--repeats K] [--profile CASE] [--alternate K]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import machine, save_results  # noqa: E402

from compare import trait_set  # noqa: E402  (the AR(1) generator of benchmarks/compare.py)
from simcred.compare import compare  # noqa: E402
from simcred.traces import RUN_INFO, TraceSet  # noqa: E402

BINS, PERMUTATIONS, SEED, DRIVERS = 10, 999, 1, 200
TARGET = 2.0  # paired and grouped: at most this many times the runs test

#: name → (compare options, label); "runs" is the reference
CASES: dict[str, tuple[dict, str]] = {
    "runs": ({"test": "runs"}, "runs test (reference)"),
    "response": ({"test": "response", "bootstrap": 200}, "response, unpaired, bootstrap 200"),
    "paired": ({"test": "response", "pair_by": "run_id", "bootstrap": 200},
               "response, pair_by=run_id, bootstrap 200"),
    "grouped": ({"test": "response", "group_by": "driver", "bootstrap": 200},
                f"response, group_by=driver ({DRIVERS} per set), bootstrap 200"),
    "response-500": ({"test": "response"}, "response, unpaired, bootstrap 500 (default)"),
    "paired-b1": ({"test": "response", "pair_by": "run_id", "bootstrap": 1},
                  "extra: response, pair_by=run_id, bootstrap 1 (interval ~off)"),
}


def trace_sets(runs: int, steps: int) -> tuple[TraceSet, TraceSet]:
    """A and B with equal run ids and a ``driver`` fact per run (run i: driver i mod DRIVERS)."""
    rng = np.random.default_rng(0)
    out = []
    for shift in (0.0, 0.05):
        traces = trait_set(rng, runs, steps, 2, shift)
        info = {run: {"driver": f"d{i % DRIVERS}"} for i, run in enumerate(traces.run_ids)}
        out.append(replace(traces, metadata={RUN_INFO: info}))
    return out[0], out[1]


def _child(case: str, runs: int, steps: int, profile: bool) -> None:
    """Run one case; print wall/CPU seconds and this process's peak RSS as JSON (last line)."""
    a, b = trace_sets(runs, steps)
    a.digest(), b.digest()
    rss_data = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    options = CASES[case][0]
    call = lambda: compare(a, b, features=["x", "y"], bins=BINS,  # noqa: E731
                           permutations=PERMUTATIONS, seed=SEED, **options)
    if profile:
        import cProfile
        import pstats

        profiler = cProfile.Profile()
        wall = time.perf_counter()
        result = profiler.runcall(call)
        wall = time.perf_counter() - wall
        print(f"profiled {case}: {wall:.2f} s (with profiler overhead)", file=sys.stderr)
        stats = pstats.Stats(profiler, stream=sys.stderr).strip_dirs().sort_stats("cumulative")
        stats.print_stats(25)
        stats.sort_stats("tottime").print_stats(15)
        return
    wall, cpu = time.perf_counter(), time.process_time()
    result = call()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "data_peak_mb": rss_data,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "chain_pvalue": None if result.chain is None else result.chain.pvalue,
                      "distance": result.distance}))


def tree_state() -> dict:
    """The commit measured and the files that differed from it (src/ may be work in progress)."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True).stdout
    return {"commit": git("rev-parse", "HEAD").strip(),
            "modified": git("status", "--porcelain", "--untracked-files=no").split("\n")[:-1]}


def in_process(case: str, runs: int, steps: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", case, str(runs), str(steps)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def alternate(cases: list[str], rounds: int, runs: int, steps: int) -> None:
    """``--alternate``: every case in turn, ``rounds`` times, in this process (module docs)."""
    warm = trace_sets(500, 50)  # imports and first calls, not counted
    a, b = trace_sets(runs, steps)
    a.digest(), b.digest()
    times: dict[str, list[tuple[float, float]]] = {case: [] for case in cases}
    for round_ in range(-1, rounds):
        for case in cases:
            name, serial = case.removesuffix(":serial"), case.endswith(":serial")
            os.environ.pop("SIMCRED_MAX_THREADS", None)
            if serial:
                os.environ["SIMCRED_MAX_THREADS"] = "1"
            wall, cpu = time.perf_counter(), time.process_time()
            compare(*(warm if round_ < 0 else (a, b)), features=["x", "y"], bins=BINS,
                    permutations=PERMUTATIONS, seed=SEED, **CASES[name][0])
            if round_ >= 0:
                times[case].append((time.perf_counter() - wall, time.process_time() - cpu))
    os.environ.pop("SIMCRED_MAX_THREADS", None)
    table = Table(title=f"alternating, {rounds} rounds: ratio to the same round's runs test")
    for column in ("case", "wall s (median)", "wall ratio median (min–max)", "CPU ratio median"):
        table.add_column(column)
    rows = []
    for case in cases:
        ratios = [t[0] / r[0] for t, r in zip(times[case], times["runs"], strict=True)]
        cpu = [t[1] / r[1] for t, r in zip(times[case], times["runs"], strict=True)]
        rows.append({"case": case, "wall_s": [t[0] for t in times[case]],
                     "cpu_s": [t[1] for t in times[case]], "ratios": ratios,
                     "median_ratio": float(np.median(ratios)),
                     "median_cpu_ratio": float(np.median(cpu))})
        table.add_row(case, f"{np.median([t[0] for t in times[case]]):.2f}",
                      f"{np.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f})",
                      f"{np.median(cpu):.2f}")
    Console(width=150).print(table)
    save_results(ROOT / "benchmarks" / "results" / "response_alternating.json",
                 {"machine": machine(), "tree": tree_state(), "rounds": rounds,
                  "size": f"2 × {runs:,} runs × {steps} steps", "cases": rows})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true", help="2,000 runs × 50 steps (smoke run)")
    parser.add_argument("--repeats", type=int, default=None,
                        help="processes per case, best taken (default 1; --small: 2)")
    parser.add_argument("--cases", default=",".join(CASES),
                        help=f"comma-separated subset of {list(CASES)} (runs is always measured)")
    parser.add_argument("--profile", choices=list(CASES),
                        help="profile one case under cProfile instead of the table")
    parser.add_argument("--alternate", type=int, metavar="K",
                        help="K rounds of the cases in turn in one process (module docs)")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    runs, steps = (2_000, 50) if args.small else (20_000, 200)
    if args.child:
        case, runs_, steps_ = args.child
        _child(case, int(runs_), int(steps_), profile=False)
        return
    if args.profile:
        _child(args.profile, runs, steps, profile=True)
        return
    cases = ["runs"] + [c for c in args.cases.split(",") if c != "runs"]
    if args.alternate:
        alternate(cases, args.alternate, runs, steps)
        return
    repeats = args.repeats or (2 if args.small else 1)
    rows = []
    for case in cases:
        measured = [in_process(case, runs, steps) for _ in range(repeats)]
        best = min(measured, key=lambda m: m["wall_s"])
        rows.append({"case": case, "label": CASES[case][1], "options": CASES[case][0],
                     "seconds": best["wall_s"], "cpu_seconds": best["cpu_s"],
                     "all_seconds": [m["wall_s"] for m in measured],
                     "peak_rss_mb": best["peak_rss_mb"], "data_peak_mb": best["data_peak_mb"],
                     "chain_pvalue": best["chain_pvalue"], "distance": best["distance"]})
    reference, reference_cpu = rows[0]["seconds"], rows[0]["cpu_seconds"]
    for row in rows:
        row["ratio_to_runs"] = row["seconds"] / reference
        row["cpu_ratio_to_runs"] = row["cpu_seconds"] / reference_cpu
        if row["case"] in ("paired", "grouped"):
            row["target"] = f"≤ {TARGET:g}× runs test"
            row["met"] = row["ratio_to_runs"] <= TARGET
    size = f"2 × {runs:,} runs × {steps} steps × 2 features, {BINS} bins, {PERMUTATIONS} perm."
    table = Table(title=f"simcred response test: {size}")
    for column in ("case", "wall s", "CPU s", "× runs test", "CPU × runs", "peak RSS MB", "note"):
        table.add_column(column)
    for row in rows:
        note = f"data alone {row['data_peak_mb']:.0f} MB"
        if "target" in row:
            note += f"; target {row['target']}: {'met' if row['met'] else 'NOT met'}"
        table.add_row(row["label"], f"{row['seconds']:.2f}", f"{row['cpu_seconds']:.2f}",
                      f"{row['ratio_to_runs']:.2f}", f"{row['cpu_ratio_to_runs']:.2f}",
                      f"{row['peak_rss_mb']:.0f}", note)
    Console(width=150).print(table)
    name = "response-small.json" if args.small else "response.json"
    save_results(ROOT / "benchmarks" / "results" / name,
                 {"machine": machine(), "tree": tree_state(), "size": size, "repeats": repeats,
                  "cases": rows})


if __name__ == "__main__":
    main()
