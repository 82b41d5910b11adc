"""Benchmarks of the contracts: prints tables, writes benchmarks/results/contracts.json.

(a) configuring an architecture of 8 components × 4 candidate models (a chain of interval
    contracts, seeded), with the optimum proven by the search and checked against the cheapest
    setup found by exhaustive enumeration of all 4⁸ = 65,536 setups (enumeration is done with the
    closed form of interval chains, not with z3, so that it finishes);
(b) monitors: samples per second on invariant clauses over 10⁷ samples, against a hand-written
    numpy expression of the same clauses in the same run.
Usage: python benchmarks/contracts.py [--quick]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine  # noqa: E402

from simcred.contracts.algebra import Contract  # noqa: E402
from simcred.contracts.configure import configure  # noqa: E402
from simcred.contracts.library import Library  # noqa: E402
from simcred.contracts.monitor import monitor  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402


def chain_library(components: int, candidates: int, seed: int) -> tuple[Library, list]:
    """I_k maps x_k to x_{k+1}; model (k, j) assumes 0 <= x_k <= hi and guarantees
    0 <= x_{k+1} <= out; wider domains and tighter outputs cost more."""
    rng = np.random.default_rng(seed)
    spec = {"variables": {f"x{k}": {"unit": "m"} for k in range(components + 1)},
            "components": {f"I{k}": {"inputs": [f"x{k}"], "outputs": [f"x{k + 1}"]}
                           for k in range(components)},
            "models": {}, "architecture": [f"I{k}" for k in range(components)],
            "test_cases": {"tc": {"assumption": "0 <= x0 <= 10",
                                  "guarantee": f"x{components} <= 9"}}}
    table = []
    for k in range(components):
        row = []
        for j in range(candidates):
            hi, out = int(rng.integers(6, 16)), int(rng.integers(5, 14))
            cost = round(float(hi - out) * 0.5 + 10 + rng.uniform(0, 3), 2)
            spec["models"][f"M{k}_{j}"] = {
                "implements": f"I{k}", "cost": cost,
                "contract": {"assumption": f"0 <= x{k} <= {hi}",
                             "guarantee": f"0 <= x{k + 1} <= {out}"}}
            row.append((f"M{k}_{j}", hi, out, cost))
        table.append(row)
    return Library.from_dict(spec, source=f"chain(seed={seed})"), table


def cheapest_by_enumeration(table, input_hi: int = 10, final: int = 9):
    """Closed form of a chain of interval contracts: valid iff every model's domain contains the
    previous bound (the test case's input range first) and the last output is within ``final``."""
    best = None
    for choice in itertools.product(*table):
        bound, ok = input_hi, True
        for _, hi, out, _ in choice:
            if bound > hi:
                ok = False
                break
            bound = out
        if ok and bound <= final:
            cost = sum(c for *_, c in choice)
            if best is None or cost < best[0] - 1e-9:
                best = (cost, [m for m, *_ in choice])
    return best


def bench_configuration(seeds) -> list[dict]:
    rows = []
    for seed in seeds:
        lib, table = chain_library(8, 4, seed)
        seconds, result = best_of(lambda lib=lib: configure(lib, "tc"), 1)
        brute_seconds, best = best_of(lambda table=table: cheapest_by_enumeration(table), 1)
        rows.append({"case": f"(a) 8 components × 4 models, seed {seed}", "seconds": seconds,
                     "status": result.status.value, "cost": result.cost,
                     "optimum_by_enumeration": None if best is None else best[0],
                     "optimal": (best is None and result.cost is None)
                     or (best is not None and result.cost is not None
                         and abs(result.cost - best[0]) < 1e-6),
                     "candidates_checked": result.iterations, "setups": 4 ** 8,
                     "enumeration_seconds": brute_seconds})
    return rows


def bench_monitor(samples: int) -> list[dict]:
    """Smooth recorded signals that leave the domain now and then (a few hundred violations)."""
    rng = np.random.default_rng(0)
    runs = 100
    steps = samples // runs
    t = np.arange(steps) * 0.01
    phase = rng.uniform(0, 2 * np.pi, (runs, 1))
    v = (20 + 19.5 * np.sin(t / 7 + phase)).ravel()
    a_lat = (2.5 * np.sin(t / 3 + 2 * phase) + rng.normal(0, 0.2, (runs, steps))).ravel()
    traces = TraceSet(("ego.v", "ego.a_lat"), np.tile(t, runs),
                      np.column_stack([v, a_lat]), np.arange(runs + 1) * steps,
                      tuple(f"r{i}" for i in range(runs)))
    contract = Contract.from_strings("0 <= ego.v <= 40 and abs(ego.a_lat) <= 4", "true")
    seconds, report = best_of(lambda: monitor(traces, {"KS": contract}), 3)
    reference, _ = best_of(lambda: [np.flatnonzero(~(v >= 0)), np.flatnonzero(~(v <= 40)),
                                    np.flatnonzero(~(np.abs(a_lat) <= 4))], 3)
    return [{"case": f"(b) monitor, 3 invariant clauses, {runs * steps:,} samples",
             "seconds": seconds, "samples_per_s": runs * steps / seconds,
             "violations": len(report.violations),
             "numpy_reference_seconds": reference,
             "ratio_to_numpy_reference": seconds / reference, "target": "≥ 1e7 samples/s"}]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    results = {"machine": machine(),
               "configuration": bench_configuration(range(2) if args.quick else range(5)),
               "monitor": bench_monitor(10**6 if args.quick else 10**7)}
    table = Table(title="simcred contracts benchmarks")
    for column in ("case", "seconds", "result", "note"):
        table.add_column(column)
    for r in results["configuration"]:
        table.add_row(r["case"], f"{r['seconds']:.2f}",
                      f"{r['status']}, cost {r['cost']}, optimal: {r['optimal']}",
                      f"{r['candidates_checked']} of {r['setups']:,} setups checked; "
                      f"target < 5 s")
    for r in results["monitor"]:
        table.add_row(r["case"], f"{r['seconds']:.3f}", f"{r['samples_per_s']:.3g} samples/s",
                      f"{r['ratio_to_numpy_reference']:.1f}× the bare numpy expression; "
                      f"{r['target']}")
    Console(width=160).print(table)
    out = ROOT / "benchmarks" / "results" / ("contracts-quick.json" if args.quick
                                             else "contracts.json")
    out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
