"""Benchmarks of the paper-000 comparison: prints a table, writes benchmarks/results/compare.json.

(a) count-based compare vs the literal sample-based oracle (tests/oracle.py), identical results;
(b) the 9×9 distance matrix, bound and permutation test, serial and on 2 worker processes;
(c) one per-state permutation test at 2·10⁴, 2·10⁵, 2·10⁶ samples (cost flat in N);
(d) the run-level test (default) on 2 × 10,000 runs × 200 steps × 2 features, 999 permutations,
    against the paper's per-transition permutation test on the same data, with peak memory;
(e) peak RSS of every test mode on 2 × 20,000 runs × 300 steps × 3 features (12 M rows), each in
    its own process.

Times are best-of-k wall-clock seconds on this machine; every figure of merit is a ratio against a
reference measured in the same run. Usage: python benchmarks/compare.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import best_of, machine  # noqa: E402

from oracle import literal_compare  # noqa: E402
from simcred.compare import compare, matrix  # noqa: E402
from simcred.compare.kernels import Kernel  # noqa: E402
from simcred.compare.mmd import Estimator, MMDTestSpec, Test, mmd_test  # noqa: E402
from simcred.engine import Engine, engine  # noqa: E402
from simcred.examples import lane_change_runs  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402

FEATURES = ["x", "y"]


def runs_of(traces):
    values = traces.features(FEATURES)
    return [values[lo:hi] for lo, hi in zip(traces.offsets[:-1], traces.offsets[1:], strict=True)]


def same_as_oracle(result, oracle) -> bool:
    tested = {s.state: s.result for s in result.states}
    return (
        all(np.array_equal(e, f) for e, f in zip(result.space.edges, oracle["edges"], strict=True))
        and set(tested) == set(oracle["states"])
        and sorted(u.state for u in result.untestable) == oracle["untestable"]
        and all(tested[s].rejected == o["rejected"]
                and np.isclose(tested[s].statistic, o["statistic"], rtol=1e-9, atol=1e-7)
                for s, o in oracle["states"].items())
        and result.distance == oracle["distance"]
    )


def bench_oracle(runs: int, steps: int) -> dict:
    a = lane_change_runs(runs, steps, 0.1, 1.0, np.random.default_rng(1), "a")
    b = lane_change_runs(runs, steps, 0.1, 0.8, np.random.default_rng(2), "b")
    fast, result = best_of(lambda: compare(a, b, features=FEATURES, bins=10), 3)
    slow, oracle = best_of(lambda: literal_compare(runs_of(a), runs_of(b), 10, "gaussian"), 1)
    return {"case": f"(a) compare vs literal oracle, 2 sets × {runs} runs × {steps} steps, "
                    "2 features, 10 bins, bound test",
            "count_based_s": fast, "literal_s": slow, "speedup": slow / fast,
            "identical": same_as_oracle(result, oracle), "target": "speedup ≥ 100"}


def nine_sets(runs: int, steps: int):
    """Three groups of three independent sets (lane-change durations ×1.0, ×0.9, ×0.8)."""
    return [lane_change_runs(runs, steps, 0.1, scale, np.random.default_rng([g, k]), f"s{g}{k}")
            for g, scale in enumerate((1.0, 0.9, 0.8)) for k in range(3)]


def bench_matrix(runs: int, steps: int, permutations: int) -> list[dict]:
    sets = nine_sets(runs, steps)
    for s in sets:
        s.digest()  # hashing the inputs is I/O-side work, not part of the comparison
    rows, outputs = [], {}
    cases = [("bound", True, 1), ("bound", True, 2), ("permutation", True, 1),
             ("permutation", True, 2), ("permutation", False, 2)]
    start = time.perf_counter()
    with engine(workers=2) as cluster:
        startup = time.perf_counter() - start
        for test, stop_early, workers in cases:
            runner = cluster if workers == 2 else Engine()
            seconds, result = best_of(lambda t=test, s=stop_early, r=runner: matrix(
                sets, features=FEATURES, bins=10, test=t, permutations=permutations, seed=0,
                stop_early=s, runner=r), 2)
            outputs[test, stop_early, workers] = result.to_json()
            label = test
            if test == "permutation":
                label += f" ({permutations} perm., {'early stop' if stop_early else 'all drawn'})"
            where = "in-process" if workers == 1 else "Dask LocalCluster, 2 workers"
            rows.append({"case": f"(b) 9×9 matrix, {runs} runs × {steps} steps, {label}, "
                                 f"{where}", "seconds": seconds})
    reference = rows[0]["seconds"]
    for row in rows:
        row["ratio_to_serial_bound"] = row["seconds"] / reference
    rows[3]["target"] = "< 3 s on 2 cores"
    rows[3]["identical_serial_vs_workers"] = (
        outputs["permutation", True, 1] == outputs["permutation", True, 2]
        and outputs["bound", True, 1] == outputs["bound", True, 2])
    rows[1]["cluster_startup_seconds"] = startup
    return rows


def bench_flat_in_n(permutations: int) -> list[dict]:
    # all permutations drawn, so that the cost measured is the full test's
    spec = MMDTestSpec(Kernel.GAUSSIAN, Estimator.BIASED, Test.PERMUTATION, 0.05, permutations,
                       stop_early=False)
    vectors = np.array([[i, j] for i in range(3) for j in range(3)], dtype=float)
    probs = np.full(9, 1 / 9)
    rows = []
    for total in (20_000, 200_000, 2_000_000):
        rng = np.random.default_rng(total)
        codes = rng.choice(9, size=total, p=probs)  # raw successor samples, half A, half B
        half = total // 2
        count = lambda c=codes, h=half: (np.bincount(c[:h], minlength=9),  # noqa: E731
                                         np.bincount(c[h:], minlength=9))
        count_s, (cx, cy) = best_of(count, 5)
        test_s, _ = best_of(lambda cx=cx, cy=cy: mmd_test(
            vectors, cx, cy, spec, (3, 3), np.random.default_rng(0)), 5)
        rows.append({"case": f"(c) one permutation test ({permutations} perm.), N = {total:,}",
                     "seconds": test_s, "counting_seconds": count_s})
    for row in rows:
        row["ratio_to_smallest_N"] = row["seconds"] / rows[0]["seconds"]
    return rows


def trait_set(rng, runs: int, steps: int, features: int, shift: float = 0.0) -> TraceSet:
    """AR(1) runs with a Beta-distributed per-run level, sampled at 0.1 s (built columnar)."""
    x = np.empty((runs, steps, features))
    level = rng.beta(2, 5, size=(runs, features)) + shift
    x[:, 0] = rng.normal(size=(runs, features))
    for t in range(1, steps):
        x[:, t] = 0.9 * x[:, t - 1] + 0.1 * level + rng.normal(0, 0.3, size=(runs, features))
    return TraceSet(tuple("xyz"[:features]), np.tile(np.arange(steps) * 0.1, runs),
                    x.reshape(-1, features), np.arange(runs + 1) * steps,
                    tuple(map(str, range(runs))))


def _child(test: str, runs: int, steps: int, features: int, permutations: int) -> None:
    """Run one comparison and print wall/CPU seconds and this process's peak RSS as JSON."""
    rng = np.random.default_rng(0)
    a, b = trait_set(rng, runs, steps, features), trait_set(rng, runs, steps, features, 0.05)
    a.digest(), b.digest()
    rss_data = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    wall, cpu = time.perf_counter(), time.process_time()
    result = compare(a, b, test=test, permutations=permutations, seed=1)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "data_peak_mb": rss_data,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "distance": result.distance,
                      "chain_pvalue": None if result.chain is None else result.chain.pvalue}))


def in_process(test: str, runs: int, steps: int, features: int, permutations: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", test, str(runs), str(steps),
                          str(features), str(permutations)], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def bench_run_level(runs: int, steps: int, permutations: int, repeats: int = 3) -> list[dict]:
    rows = []
    for test in ("runs", "permutation"):
        measured = [in_process(test, runs, steps, 2, permutations) for _ in range(repeats)]
        best = min(measured, key=lambda m: m["wall_s"])
        rows.append({"case": f"(d) {test} test, 2 × {runs:,} runs × {steps} steps × 2 features, "
                             f"{permutations} perm.", "seconds": best["wall_s"],
                     "cpu_seconds": best["cpu_s"], "peak_rss_mb": best["peak_rss_mb"],
                     "data_peak_mb": best["data_peak_mb"]})
    rows[0]["target"] = "< 5 s on 2 cores"
    for row in rows:
        row["ratio_to_per_transition"] = row["seconds"] / rows[1]["seconds"]
    return rows


def bench_memory(runs: int, steps: int, permutations: int) -> list[dict]:
    rows = []
    for test in ("runs", "bound", "permutation"):
        m = in_process(test, runs, steps, 3, permutations)
        rows.append({"case": f"(e) {test} test, 2 × {runs:,} runs × {steps} steps × 3 features "
                             f"({2 * runs * steps / 1e6:.0f} M rows)", "seconds": m["wall_s"],
                     "peak_rss_mb": m["peak_rss_mb"], "data_peak_mb": m["data_peak_mb"],
                     "target": "peak RSS < 2 GB"})
    for row in rows:
        row["ratio_to_data"] = row["peak_rss_mb"] / row["data_peak_mb"]
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    parser.add_argument("--only", choices=["run-level", "memory"],
                        help="only (d) the run-level timing or (e) the peak-memory runs")
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        test, *sizes = args.child
        _child(test, *map(int, sizes))
        return
    scale = 10 if args.quick else 1
    results = {"machine": machine()}
    if args.only is None:
        results.update({
            "oracle": bench_oracle(500 // scale, 200),
            "matrix": bench_matrix(1000 // scale, 200, 999),
            "flat_in_n": bench_flat_in_n(999),
        })
    if args.only != "memory":
        results["run_level"] = bench_run_level(10_000 // scale, 200, 999)
    if args.only != "run-level":
        results["memory"] = bench_memory(20_000 // scale, 300, 999)
    table = Table(title="simcred compare benchmarks")
    for column in ("case", "seconds", "ratio", "note"):
        table.add_column(column)
    if "oracle" in results:
        _paper_rows(table, results)
    for row in results.get("run_level", []):
        table.add_row(row["case"], f"{row['seconds']:.2f} (CPU {row['cpu_seconds']:.2f})",
                      f"{row['ratio_to_per_transition']:.2f}× per-transition permutation",
                      f"peak RSS {row['peak_rss_mb']:.0f} MB (data alone "
                      f"{row['data_peak_mb']:.0f} MB) {row.get('target', '')}")
    for row in results.get("memory", []):
        table.add_row(row["case"], f"{row['seconds']:.1f}",
                      f"{row['ratio_to_data']:.2f}× data alone",
                      f"peak RSS {row['peak_rss_mb']:.0f} MB; {row['target']}")
    Console(width=170).print(table)
    name = f"compare-{args.only}" if args.only else "compare"
    out = ROOT / "benchmarks" / "results" / (f"{name}-quick.json" if args.quick else f"{name}.json")
    out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {out}")


def _paper_rows(table: Table, results: dict) -> None:
    o = results["oracle"]
    table.add_row(o["case"], f"{o['count_based_s']:.3f} vs {o['literal_s']:.1f}",
                  f"{o['speedup']:.0f}× faster", f"identical: {o['identical']}; {o['target']}")
    for row in results["matrix"]:
        note = row.get("target", "")
        if "cluster_startup_seconds" in row:
            note += f"cluster start (not timed): {row['cluster_startup_seconds']:.1f} s"
        if "identical_serial_vs_workers" in row:
            note += f"; serial = workers: {row['identical_serial_vs_workers']}"
        table.add_row(row["case"], f"{row['seconds']:.2f}",
                      f"{row['ratio_to_serial_bound']:.2f}× serial bound", note)
    for row in results["flat_in_n"]:
        table.add_row(row["case"], f"{row['seconds'] * 1e3:.2f} ms",
                      f"{row['ratio_to_smallest_N']:.2f}× N=2·10⁴",
                      f"counting the samples: {row['counting_seconds'] * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
