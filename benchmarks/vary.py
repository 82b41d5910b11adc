"""Benchmark of paper 002's local variation: prints a table, writes benchmarks/results/vary.json.

300 variations of the cut-in's fit(GT) generated (C2 Bézier, plausibility check), refitted and
resimulated (KS, ideal sensor, 100 Hz) — target < 10 s on 2 cores; the time includes each
variation's assessment too (max TTR risk every 0.1 s, reaction, category). Measured serially
(one process) and on a local Dask cluster of 2 workers (cluster start-up excluded, one warm-up
run first). References in the same run, serially, on the same variations:

* **before** issue 24 point 6: the campaign as it was (``max_risk`` with the default 11 "keep"
  nodes and the search and refit code of then: ``benchmarks/_vary_before.py`` patches reference
  copies in); the ratio before / now;
* the **literal** assessment, ``risk(...).risk.max()`` run by run with 11 nodes (timed alone);
* **uncached**: the campaign as it is now but without the refit's and the resimulation's
  caches (``_vary_before.without_caches``: the code of just before them, the same numbers, which
  the benchmark checks); the ratio uncached / now, serial, in wall and CPU seconds.

Every variation's maximum risk is compared with the before path's: the largest change in
decades (the campaign now takes 5 nodes, docs/variation.md) and, with 11 nodes, identity of the
exact speed-ups. The serial runs are also timed in CPU seconds of this process (less inflated
by other processes on a loaded machine). Also timed alone: the generation (vary, refit,
plausibility) and the assessment of the resimulated runs (each path), to say where the rest of
the time goes.

Usage: python benchmarks/vary.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from simcred.engine import Engine, engine
from simcred.kinematics import Track
from simcred.reprocess.pipeline import reprocess
from simcred.reprocess.vary import VaryConfig, _max_risks, _resimulate_chunk, jobs, task_size
from simcred.risk import PredictionSet, VehicleStates, risk
from simcred.scenario.variation import generate_variations
from simcred.sim.experiments import cutin
from simcred.sim.resimulation import resimulate
from simcred.traces import TIME

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine, save_results  # noqa: E402
from _vary_before import before_path, without_caches  # noqa: E402

TARGET = 10.0


def generate_and_resimulate(description, config: VaryConfig, runner: Engine) -> np.ndarray:
    """The campaign's generation, resimulation and assessment; each variation's max risk."""
    config = replace(config, chunk_size=task_size(config, runner))
    variations = generate_variations(description, config.n, config.seed, options=config.options,
                                     limits=config.limits, runner=runner,
                                     chunk_size=config.chunk_size)
    indices = [v.index for v in variations.variations]
    parts = runner.map(_resimulate_chunk, jobs(variations, config), shared_values={
        "config": config, "sensor": None, "indices": indices, "original": description})
    return np.array([o.max_risk for _, outcomes in parts for o in outcomes])


def _literal_max_risks(tracks, c: VaryConfig) -> np.ndarray:
    """The literal assessment: the full risk series of every run (11 nodes), one call per run."""
    peaks = []
    for ego, to in tracks:
        step = max(1, int(round(c.risk_dt / (ego.t[1] - ego.t[0]))))
        peaks.append(float(risk(VehicleStates.of_tracks(ego[::step], name=c.ego),
                                VehicleStates.of_tracks([to[::step]], name="objects")
                                ).risk.max()))
    return np.array(peaks)


def _decades(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |log10(a / b)| (0 where both are 0, inf where only one is)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.abs(np.log10(a) - np.log10(b))
    return float(np.max(np.where(a == b, 0.0, d)))


def parts(description, config: VaryConfig) -> dict[str, object]:
    """Seconds of the generation alone and of the assessment alone (each path), serial, and
    how far each path's maxima lie from the before path's."""
    start = time.perf_counter()
    config = replace(config, chunk_size=task_size(config, Engine()))
    variations = generate_variations(description, config.n, config.seed, options=config.options,
                                     limits=config.limits, chunk_size=config.chunk_size)
    generation = time.perf_counter() - start
    runs = resimulate([v.description for v in variations.variations], vehicle=config.vehicle,
                      driver=config.driver, dt=config.dt, seed=config.seed, ego=config.ego,
                      indices=[v.index for v in variations.variations])
    tracks = [tuple(Track.from_columns(runs.run(k), name, time=TIME).with_rates()
                    for name in (config.ego, config.to)) for k in range(runs.n_runs)]

    def assess(c: VaryConfig) -> np.ndarray:
        return np.concatenate([_max_risks(tracks[k:k + c.chunk_size], c)
                               for k in range(0, len(tracks), c.chunk_size)])

    now, now_risks = best_of(lambda: assess(config), 1)
    exact, exact_risks = best_of(lambda: assess(replace(config, predictions=PredictionSet())), 1)
    with before_path(config) as old_config:
        before, before_risks = best_of(lambda: assess(old_config), 1)
    literal, literal_risks = best_of(lambda: _literal_max_risks(tracks, config), 1)
    return {"generation_s": generation, "assessment_s": now,
            "assessment_11_nodes_s": exact, "assessment_before_s": before,
            "assessment_literal_s": literal,
            "assessment_ratio_before_to_now": before / now,
            "assessment_ratio_before_to_11_nodes": before / exact,
            "11_nodes_identical_to_before": bool(np.array_equal(exact_risks, before_risks)),
            "before_identical_to_literal": bool(np.array_equal(before_risks, literal_risks)),
            "max_change_decades_now_vs_before": _decades(now_risks, before_risks)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 variations, one repeat")
    quick = parser.parse_args().quick
    load_start = _load()
    config = VaryConfig(n=100 if quick else 300)
    repeats = 1 if quick else 2
    description = reprocess(cutin.simulate(0)).descriptions["fit(GT)"]
    one, _ = best_of(lambda: resimulate(description), 3)
    generate_and_resimulate(description, VaryConfig(n=20), Engine())  # warm-up
    with before_path(config) as old_config:
        before, before_cpu, old_risks = _wall_and_cpu(
            lambda: generate_and_resimulate(description, old_config, Engine()), 1)
    with without_caches():
        uncached, uncached_cpu, uncached_risks = _wall_and_cpu(
            lambda: generate_and_resimulate(description, config, Engine()), repeats)
    serial, serial_cpu, new_risks = _wall_and_cpu(
        lambda: generate_and_resimulate(description, config, Engine()), repeats)
    split = parts(description, config)
    with engine(2, None) as runner:
        generate_and_resimulate(description, VaryConfig(n=20), runner)  # warm-up
        dask, _ = best_of(lambda: generate_and_resimulate(description, config, runner), repeats)
    table = Table(title=f"{config.n} variations generated, refitted, resimulated and assessed")
    for column in ("where", "seconds", "target", "met", "in unvaried resimulations"):
        table.add_column(column)
    results = {"variations": config.n, "kept": int(new_risks.size), "one_resimulation_s": one,
               "before_serial_s": before, "ratio_before_to_now_serial": before / serial,
               "before_serial_cpu_s": before_cpu, "serial_cpu_s": serial_cpu,
               "ratio_before_to_now_serial_cpu": before_cpu / serial_cpu,
               "max_change_decades_campaign": _decades(new_risks, old_risks),
               "uncached_serial_s": uncached, "uncached_serial_cpu_s": uncached_cpu,
               "ratio_uncached_to_now_serial": uncached / serial,
               "ratio_uncached_to_now_serial_cpu": uncached_cpu / serial_cpu,
               "identical_to_uncached": bool(np.array_equal(uncached_risks, new_risks)), **split}
    rows = (("before (issue 24 point 6), serial", before), ("serial (1 process)", serial),
            ("Dask, 2 workers", dask))
    for label, seconds in rows:
        met = seconds < TARGET
        table.add_row(label, f"{seconds:.2f}", f"< {TARGET:g}",
                      "[green]yes[/green]" if met else "[red]no[/red]", f"{seconds / one:.0f}")
        if not label.startswith("before"):
            results[label] = {"seconds": seconds, "met": met,
                              "ratio_to_one_resimulation": seconds / one}
    Console().print(table)
    print(f"before / now serial: {before / serial:.2f}x; largest change of a variation's maximum "
          f"risk: {results['max_change_decades_campaign']:.4f} decades ({new_risks.size} "
          f"variations)")
    print(f"CPU time of this process, serial: before {before_cpu:.2f} s, now {serial_cpu:.2f} s "
          f"({before_cpu / serial_cpu:.2f}x); without the refit caches {uncached_cpu:.2f} s CPU, "
          f"{uncached:.2f} s wall ({uncached_cpu / serial_cpu:.2f}x CPU, {uncached / serial:.2f}x "
          f"wall; maxima identical: {results['identical_to_uncached']})")
    print(f"alone, serial: generation {split['generation_s']:.2f} s; assessment now "
          f"{split['assessment_s']:.2f} s, with 11 nodes {split['assessment_11_nodes_s']:.2f} s "
          f"(identical to before: {split['11_nodes_identical_to_before']}), before "
          f"{split['assessment_before_s']:.2f} s, literal {split['assessment_literal_s']:.2f} s")
    save_results(ROOT / "benchmarks" / "results" / ("vary-quick.json" if quick else "vary.json"),
                 {"machine": machine(), "load_average_start": load_start,
                  "load_average_end": _load(), "results": results})


def _wall_and_cpu(fn, repeats: int) -> tuple[float, float, np.ndarray]:
    """The fastest of ``repeats`` calls: wall seconds, this process's CPU seconds, result (CPU
    time is less inflated by other processes on a loaded machine; serial work only)."""
    best = (np.inf, np.inf, None)
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        result = fn()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        best = min(best, (wall, cpu, result), key=lambda b: b[0])
    return best


def _load() -> list[float]:
    import os

    return [round(x, 2) for x in os.getloadavg()]


if __name__ == "__main__":
    main()
