"""Benchmarks of paper 002's reprocessing: prints a table, writes benchmarks/results/reprocess.json.

* **fit** — one 20 s trace at 100 Hz (the cut-in TO from 0 to 20 s, 1 cm noise), the whole
  section search (target < 0.2 s). Reference in the same run: the final least-squares solve with
  scipy's finite-difference Jacobian instead of the analytic one (same start, same sections).
* **fit of a real track** — the A9 ego's GNSS fixes (``testfile_llc.csv``, the first 20 s at
  10 Hz, a lane change while accelerating from 2 to 21 m/s), the whole section search with the
  plausibility limits (target < 0.2 s). Reference in the same run: the same search without limits
  (the paper's position-only fit).
* **TTR risk** — time per scene of a batch of 2000 cut-in scenes with the default model: four
  evasive maneuvers (brake, steer left/right, kickdown) and the "keep" prediction as an 11-node
  set over the TO's acceleration (target < 5 ms; commonroad-crime takes 8-28 s per scene on a
  100 km/h cut-in). References in the same run: the same scenes one call each; the previous
  point model (one "keep", brake/left/right) on the same batch. Also timed: 2000 scenes of
  traffic in any direction (oncoming, crossing, reversing, standing).
* **pipeline** — ``reprocess`` of the default cut-in measurement: two fits, four resimulations,
  four refits, six risk series (target < 15 s). Reference: one closed-loop drive of the universe.

Usage: python benchmarks/reprocess.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.optimize import least_squares

from simcred import data
from simcred.reprocess.pipeline import reprocess
from simcred.risk import EvasionSet, PredictionSet, VehicleStates, risk
from simcred.scenario.fit import fit_track
from simcred.scenario.fit_problem import PositionProblem
from simcred.sim.experiments import cutin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine, save_results  # noqa: E402

TARGETS = {"fit": 0.2, "fit real": 0.2, "ttr per scene": 5e-3, "pipeline": 15.0}
A9_FILE = data.path("a9/testfile_llc.csv")  # shipped with simcred (Apache-2.0)


def trace_20s() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 20.0, 2001)
    truth = cutin.scripted_object(cutin.CutInScript(), t)
    rng = np.random.default_rng(0)
    return t, truth[:, 0] + 0.01 * rng.standard_normal(t.size), \
        truth[:, 1] + 0.01 * rng.standard_normal(t.size)


def bench_fit(repeats: int) -> dict:
    t, x, y = trace_20s()
    seconds, fit = best_of(lambda: fit_track(t, x, y), repeats)
    problem = PositionProblem(t, x, y, fit.sections)
    start = problem.initial_guess()
    analytic, _ = best_of(lambda: least_squares(problem.residuals, start, jac=problem.jacobian,
                                                method="lm", x_scale="jac"), repeats)
    numeric, _ = best_of(lambda: least_squares(problem.residuals, start, jac="2-point",
                                               method="lm", x_scale="jac"), repeats)
    return {"seconds": seconds, "sections": fit.sections, "rmse": fit.rmse,
            "final_solve_analytic_s": analytic, "final_solve_finite_difference_s": numeric,
            "speedup_of_analytic_jacobian": numeric / analytic}


def cutin_scenes(n: int) -> tuple[VehicleStates, VehicleStates]:
    rng = np.random.default_rng(1)
    zeros = np.zeros(n)
    ego = VehicleStates(x=zeros, y=zeros, v=np.full(n, 27.8), heading=zeros)
    to = VehicleStates(x=rng.uniform(20, 40, n), y=rng.uniform(0.0, 2.5, n),
                       v=rng.uniform(18, 26, n), heading=-rng.uniform(0.0, 0.08, n),
                       acceleration=-rng.uniform(0.0, 6.0, n))
    return ego, to


def any_direction_scenes(n: int) -> tuple[VehicleStates, VehicleStates]:
    """EGO at 27.8 m/s; TOs within 60 m in any direction at -5..30 m/s (negative: reversing)."""
    rng = np.random.default_rng(2)
    zeros = np.zeros(n)
    ego = VehicleStates(x=zeros, y=zeros, v=np.full(n, 27.8), heading=zeros)
    to = VehicleStates(x=rng.uniform(-20, 60, n), y=rng.uniform(-7, 7, n),
                       v=rng.uniform(-5, 30, n), heading=rng.uniform(-np.pi, np.pi, n),
                       acceleration=rng.uniform(-4, 2, n), yaw_rate=rng.uniform(-0.2, 0.2, n))
    return ego, to


def real_track_20s() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The A9 ego's projected GNSS fixes over the first 20 s (201 samples)."""
    from simcred.io.a9 import read_a9

    recording = read_a9(A9_FILE)
    keep = recording.time <= recording.time[0] + 20.0 + 1e-9
    return recording.time[keep], recording.ego["gnss_x"][keep], recording.ego["gnss_y"][keep]


def bench_fit_real(repeats: int) -> dict:
    t, x, y = real_track_20s()
    seconds, fit = best_of(lambda: fit_track(t, x, y), repeats)
    plain, reference = best_of(lambda: fit_track(t, x, y, limits=None), repeats)
    return {"seconds": seconds, "samples": len(t), "sections": fit.sections, "rmse": fit.rmse,
            "stop_reason": str(fit.stop_reason), "violations": [str(r) for r in fit.violations],
            "without_limits_s": plain, "without_limits_sections": reference.sections,
            "without_limits_rmse": reference.rmse, "ratio_to_without_limits": seconds / plain}


def bench_ttr(scenes: int, single: int, repeats: int) -> dict:
    ego, to = cutin_scenes(scenes)
    batched, result = best_of(lambda: risk(ego, to), repeats)
    point = dict(predictions=PredictionSet(acceleration_sigma=0.0),
                 evasion=EvasionSet(maneuvers=("brake", "left", "right")))
    point_s, point_result = best_of(lambda: risk(ego, to, **point), repeats)
    anywhere = any_direction_scenes(scenes)
    anywhere_s, _ = best_of(lambda: risk(*anywhere), repeats)
    fields = ("x", "y", "v", "heading", "acceleration")

    def one_by_one() -> None:
        for i in range(single):
            risk(VehicleStates(**{f: getattr(ego, f)[i:i + 1] for f in fields}),
                 VehicleStates(**{f: getattr(to, f)[i:i + 1] for f in fields}))

    looped, _ = best_of(one_by_one, 1)
    return {"scenes": scenes, "seconds": batched, "per_scene_s": batched / scenes,
            "colliding_predictions_per_scene": float(np.isfinite(result.ttr).sum() / scenes),
            "one_call_per_scene_s": looped / single,
            "speedup_of_batching": (looped / single) / (batched / scenes),
            "maneuvers": list(result.maneuver_names),
            "predictions_per_object": len(result.prediction_names),
            "point_model_per_scene_s": point_s / scenes,
            "point_model_colliding_predictions_per_scene":
                float(np.isfinite(point_result.ttr).sum() / scenes),
            "cost_of_richer_model": batched / point_s,
            "any_direction_per_scene_s": anywhere_s / scenes}


def bench_pipeline(repeats: int) -> dict:
    measurement = cutin.simulate(0)
    seconds, _ = best_of(lambda: reprocess(measurement), repeats)
    drive, _ = best_of(lambda: cutin.drive(cutin.CutInConfig(), 0), repeats)
    return {"seconds": seconds, "one_closed_loop_drive_s": drive,
            "pipeline_in_drives": seconds / drive}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and scenes")
    quick = parser.parse_args().quick
    repeats = 2 if quick else 5
    results = {"fit": bench_fit(repeats), "fit real": bench_fit_real(repeats),
               "ttr per scene": bench_ttr(500 if quick else 2000, 20 if quick else 100, repeats),
               "pipeline": bench_pipeline(1 if quick else 3)}
    table = Table(title="paper 002 reprocessing (best of k, one process)")
    for column in ("what", "time", "target", "met", "reference", "ratio"):
        table.add_column(column)
    fit, ttr, pipe = results["fit"], results["ttr per scene"], results["pipeline"]
    real = results["fit real"]
    rows = [("fit 20 s @ 100 Hz", fit["seconds"], "fit", "finite-difference Jacobian",
             fit["speedup_of_analytic_jacobian"]),
            ("fit 20 s real (A9 GNSS, 10 Hz)", real["seconds"], "fit real",
             "same search without limits (time ratio)", real["ratio_to_without_limits"]),
            ("TTR risk per scene", ttr["per_scene_s"], "ttr per scene", "one call per scene",
             ttr["speedup_of_batching"]),
            ("  (point model, 3 maneuvers)", ttr["point_model_per_scene_s"], "ttr per scene",
             "default model / point model", ttr["cost_of_richer_model"]),
            ("  (any direction, default)", ttr["any_direction_per_scene_s"], "ttr per scene",
             "-", ttr["any_direction_per_scene_s"] / ttr["per_scene_s"]),
            ("whole pipeline", pipe["seconds"], "pipeline", "one closed-loop drive",
             pipe["pipeline_in_drives"])]
    for label, seconds, key, reference, ratio in rows:
        met = seconds < TARGETS[key]
        table.add_row(label, f"{seconds * 1e3:.2f} ms", f"< {TARGETS[key] * 1e3:g} ms",
                      "[green]yes[/green]" if met else "[red]no[/red]", reference, f"{ratio:.1f}×")
        if not label.startswith(" "):
            results[key]["target_s"], results[key]["met"] = TARGETS[key], met
    Console().print(table)
    save_results(ROOT / "benchmarks" / "results" / "reprocess.json",
                 {"machine": machine(), "results": results})


if __name__ == "__main__":
    main()
