"""Benchmark of seed 002's local variation: prints a table, writes benchmarks/results/vary.json.

300 variations of the cut-in's fit(GT) generated (C2 Bézier, plausibility check), refitted and
resimulated (KS, ideal sensor, 100 Hz) — target < 10 s on 2 cores; the time includes each
variation's assessment too (max TTR risk every 0.1 s, reaction, category). Measured serially
(one process) and on a local Dask cluster of 2 workers (cluster start-up excluded, one warm-up
run first). Reference in the same run: one resimulation of the unvaried description, and the
old assessment path (``risk(...).risk.max()`` run by run, before ``max_risk``), serially, on the
same variations: the ratio old / new, and whether every variation's maximum risk is identical.
Also timed alone: the generation (vary, refit, plausibility) and the assessment of the
resimulated runs (new and old path), to say where the rest of the time goes.

Usage: python benchmarks/vary.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

import simcred.reprocess.vary as vary_module
from simcred.engine import Engine, engine
from simcred.kinematics import Track
from simcred.reprocess.pipeline import reprocess
from simcred.reprocess.vary import VaryConfig, _max_risks, _resimulate_chunk
from simcred.risk import VehicleStates, risk
from simcred.scenario.variation import generate_variations
from simcred.sim.experiments import cutin
from simcred.sim.resimulation import resimulate
from simcred.traces import TIME

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine, save_results  # noqa: E402

TARGET = 10.0


def generate_and_resimulate(description, config: VaryConfig, runner: Engine) -> np.ndarray:
    """The campaign's generation, resimulation and assessment; each variation's max risk."""
    variations = generate_variations(description, config.n, config.seed, options=config.options,
                                     limits=config.limits, runner=runner,
                                     chunk_size=config.chunk_size)
    jobs = [(k, [v.description for v in variations.variations[k:k + config.chunk_size]])
            for k in range(0, len(variations.variations), config.chunk_size)]
    indices = [v.index for v in variations.variations]
    parts = runner.map(_resimulate_chunk, jobs, shared_values={
        "config": config, "sensor": None, "indices": indices, "original": description})
    return np.array([o.max_risk for _, outcomes in parts for o in outcomes])


def _old_max_risks(tracks, c: VaryConfig) -> np.ndarray:
    """The assessment before max_risk: the full risk series of every run, one call per run."""
    peaks = []
    for ego, to in tracks:
        step = max(1, int(round(c.risk_dt / (ego.t[1] - ego.t[0]))))
        peaks.append(float(risk(VehicleStates.of_tracks(ego[::step], name=c.ego),
                                VehicleStates.of_tracks([to[::step]], name="objects")
                                ).risk.max()))
    return np.array(peaks)


@contextmanager
def old_path():
    """The campaign with the old assessment (in this process: the serial runs only)."""
    vary_module._max_risks = _old_max_risks
    try:
        yield
    finally:
        vary_module._max_risks = _max_risks


def parts(description, config: VaryConfig) -> dict[str, float]:
    """Seconds of the generation alone and of the assessment alone (new and old path), serial."""
    start = time.perf_counter()
    variations = generate_variations(description, config.n, config.seed, options=config.options,
                                     limits=config.limits, chunk_size=config.chunk_size)
    generation = time.perf_counter() - start
    runs = resimulate([v.description for v in variations.variations], vehicle=config.vehicle,
                      driver=config.driver, dt=config.dt, seed=config.seed, ego=config.ego,
                      indices=[v.index for v in variations.variations])
    tracks = [tuple(Track.from_columns(runs.run(k), name, time=TIME).with_rates()
                    for name in (config.ego, config.to)) for k in range(runs.n_runs)]
    new, _ = best_of(lambda: [_max_risks(tracks[k:k + config.chunk_size], config)
                              for k in range(0, len(tracks), config.chunk_size)], 1)
    old, _ = best_of(lambda: _old_max_risks(tracks, config), 1)
    return {"generation_s": generation, "assessment_s": new, "assessment_old_s": old}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 variations, one repeat")
    quick = parser.parse_args().quick
    config = VaryConfig(n=100 if quick else 300)
    repeats = 1 if quick else 2
    description = reprocess(cutin.simulate(0)).descriptions["fit(GT)"]
    one, _ = best_of(lambda: resimulate(description), 3)
    with old_path():
        before, old_risks = best_of(lambda: generate_and_resimulate(description, config,
                                                                    Engine()), 1)
    serial, new_risks = best_of(lambda: generate_and_resimulate(description, config, Engine()),
                                repeats)
    identical = bool(np.array_equal(old_risks, new_risks))
    split = parts(description, config)
    with engine(2, None) as runner:
        generate_and_resimulate(description, VaryConfig(n=20), runner)  # warm-up
        dask, _ = best_of(lambda: generate_and_resimulate(description, config, runner), repeats)
    table = Table(title=f"{config.n} variations generated, refitted, resimulated and assessed")
    for column in ("where", "seconds", "target", "met", "in unvaried resimulations"):
        table.add_column(column)
    results = {"variations": config.n, "kept": int(new_risks.size), "one_resimulation_s": one,
               "old_path_serial_s": before, "ratio_old_to_new_serial": before / serial,
               "max_risks_identical_to_old_path": identical, **split}
    rows = (("old path, serial (1 process)", before), ("serial (1 process)", serial),
            ("Dask, 2 workers", dask))
    for label, seconds in rows:
        met = seconds < TARGET
        table.add_row(label, f"{seconds:.2f}", f"< {TARGET:g}",
                      "[green]yes[/green]" if met else "[red]no[/red]", f"{seconds / one:.0f}")
        if not label.startswith("old"):
            results[label] = {"seconds": seconds, "met": met,
                              "ratio_to_one_resimulation": seconds / one}
    Console().print(table)
    print(f"old / new serial: {before / serial:.2f}x; every variation's maximum risk identical "
          f"to the old path's: {identical} ({new_risks.size} variations)")
    print(f"alone, serial: generation {split['generation_s']:.2f} s, assessment "
          f"{split['assessment_s']:.2f} s (old path {split['assessment_old_s']:.2f} s)")
    save_results(ROOT / "benchmarks" / "results" / ("vary-quick.json" if quick else "vary.json"),
                 {"machine": machine(), "results": results})


if __name__ == "__main__":
    main()
