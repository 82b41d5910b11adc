"""Benchmarks of the simulator: prints tables, writes benchmarks/results/sim.json.

Cost per simulated second (RK4, fixed dt) of SimpleCar, KS and ST stepped as one batch of runs,
and of CommonRoad's own per-state functions looped over a single run (the reference the batched
models reproduce). Every ratio is against batched SimpleCar measured in the same run: per run for
the cost, so the reference's single run is compared with one run's share of a batch.

Then the T-junction experiment in runs per second per category, as a ratio to the SimpleCar
sweep's runs per second (both 1000 runs, one process).

Times are best-of-k wall-clock seconds on this machine, one process (numpy is single-threaded
here). Usage: python benchmarks/sim.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from simcred.sim.experiments import simplecar_sweep, tjunction  # noqa: E402
from simcred.sim.vehicles import (  # noqa: E402
    KinematicSingleTrack,
    SimpleCar,
    SingleTrack,
    VehicleModel,
    initial_state,
    rk4_step,
)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine  # noqa: E402

DT = 0.01
TARGET = 1e6  # vehicle-steps/s, batched SimpleCar on 2 cores


def drive(model: VehicleModel, runs: int, steps: int, rng: np.random.Generator):
    """Start states and a per-step input schedule: weaving at 5–30 m/s, inside every limit."""
    speed = rng.uniform(5.0, 30.0, runs)
    state = initial_state(model, x=rng.normal(0, 10, runs), y=rng.normal(0, 10, runs),
                          heading=rng.uniform(-np.pi, np.pi, runs),
                          **({} if model.name == "simplecar" else {"speed": speed}))
    t = np.arange(steps)[:, None] * DT
    steering_rate = 0.2 * np.sin(2 * np.pi * (t / rng.uniform(2.0, 6.0, runs)))
    if model.name == "simplecar":
        schedule = np.stack([np.broadcast_to(speed, steering_rate.shape), steering_rate], axis=2)
    else:
        schedule = np.stack([steering_rate, np.zeros_like(steering_rate)], axis=2)
    return state, np.ascontiguousarray(schedule)


def simulate(model: VehicleModel, state: np.ndarray, schedule: np.ndarray) -> np.ndarray:
    for inputs in schedule:
        state = rk4_step(model, state, inputs, DT)
    return state


def measure(model: VehicleModel, runs: int, seconds: float, repeats: int) -> dict:
    steps = round(seconds / DT)
    state, schedule = drive(model, runs, steps, np.random.default_rng(0))
    wall, _ = best_of(lambda: simulate(model, state, schedule), repeats)
    return {"model": model.name, "runs": runs, "steps": steps, "simulated_s": seconds,
            "wall_s": wall, "s_per_simulated_s": wall / seconds,
            "s_per_simulated_s_per_run": wall / seconds / runs,
            "vehicle_steps_per_s": runs * steps / wall}


def experiments(runs: int, repeats: int) -> list[dict]:
    """Runs per second of the paper-000 experiments at their default settings."""
    cases = [("simplecar sweep (λ = 1, dt 2 s, 40 s)",
              lambda: simplecar_sweep.simulate(range(runs), 0, lam=1.0))]
    cases += [(f"tjunction {c} (dt 0.1 s)",
               lambda c=c: tjunction.simulate(range(runs), 0, category=c))
              for c in tjunction.CATEGORIES]
    rows = []
    for name, fn in cases:
        wall, _ = best_of(fn, repeats)
        rows.append({"experiment": name, "runs": runs, "wall_s": wall, "runs_per_s": runs / wall})
    for row in rows:
        row["ratio_to_simplecar_sweep"] = row["runs_per_s"] / rows[0]["runs_per_s"]
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="shorter runs, for a smoke run")
    args = parser.parse_args()
    seconds, repeats = (2.0, 2) if args.quick else (10.0, 3)
    ks, st = KinematicSingleTrack(), SingleTrack()
    cases = [(SimpleCar(wheelbase=ks.params.a + ks.params.b), 1000, "batched"),
             (ks, 1000, "batched"), (st, 1000, "batched"),
             (SimpleCar(wheelbase=ks.params.a + ks.params.b), 10_000, "batched"),
             (st, 1, "batched, a batch of one"),
             (ks.reference(), 1, "CommonRoad per-state function, looped"),
             (st.reference(), 1, "CommonRoad per-state function, looped")]
    rows = []
    for model, runs, how in cases:
        row = measure(model, runs, seconds if runs > 1 else seconds / 2, repeats)
        rows.append(row | {"how": how})
    reference = rows[0]["s_per_simulated_s_per_run"]
    for row in rows:
        row["cost_per_run_ratio_to_simplecar"] = row["s_per_simulated_s_per_run"] / reference
    results = {
        "machine": machine(),
        "settings": {"integrator": "RK4", "dt_s": DT, "vehicle_parameters": "CommonRoad vehicle 2"
                     " (BMW 320i)", "repeats": repeats, "timing": "best of repeats, one process"},
        "rows": rows,
        "simplecar_vehicle_steps_per_s": rows[0]["vehicle_steps_per_s"],
        "target": f"batched SimpleCar ≥ {TARGET:.0e} vehicle-steps/s on 2 cores",
        "target_met": rows[0]["vehicle_steps_per_s"] >= TARGET,
    }

    table = Table(title=f"simcred vehicle models: RK4, dt = {DT} s")
    for column in ("model", "how", "runs", "s per simulated s", "per run", "× SimpleCar (per run)",
                   "vehicle-steps/s"):
        table.add_column(column, justify="left" if column in ("model", "how") else "right")
    for row in rows:
        table.add_row(row["model"], row["how"], f"{row['runs']:,}",
                      f"{row['s_per_simulated_s'] * 1e3:.2f} ms",
                      f"{row['s_per_simulated_s_per_run'] * 1e6:.2f} µs",
                      f"{row['cost_per_run_ratio_to_simplecar']:.1f}",
                      f"{row['vehicle_steps_per_s']:.3g}")
    console = Console(width=150)
    console.print(table)
    console.print(f"batched SimpleCar: {results['simplecar_vehicle_steps_per_s']:.3g} "
                  f"vehicle-steps/s; target {results['target']}: "
                  f"{'met' if results['target_met'] else 'NOT met'}")
    results["experiments"] = experiments(100 if args.quick else 1000, repeats)
    table = Table(title="experiments: runs per second, one process")
    for column in ("experiment", "runs", "runs/s", "× SimpleCar sweep"):
        table.add_column(column)
    for row in results["experiments"]:
        table.add_row(row["experiment"], f"{row['runs']:,}", f"{row['runs_per_s']:,.0f}",
                      f"{row['ratio_to_simplecar_sweep']:.3f}")
    console.print(table)
    out = ROOT / "benchmarks" / "results" / ("sim-quick.json" if args.quick else "sim.json")
    out.write_text(json.dumps(results, indent=1, ensure_ascii=False) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
