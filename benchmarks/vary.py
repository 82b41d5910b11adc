"""Benchmark of seed 002's local variation: prints a table, writes benchmarks/results/vary.json.

300 variations of the cut-in's fit(GT) generated (C2 Bézier, plausibility check), refitted and
resimulated (KS, ideal sensor, 100 Hz) — target < 10 s on 2 cores; the time includes each
variation's assessment too (max TTR risk every 0.1 s, reaction, category). Measured serially
(one process) and on a local Dask cluster of 2 workers (cluster start-up excluded, one warm-up
run first). Reference in the same run: one resimulation of the unvaried description.

Usage: python benchmarks/vary.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rich.console import Console
from rich.table import Table

from simcred.engine import Engine, engine
from simcred.reprocess.pipeline import reprocess
from simcred.reprocess.vary import VaryConfig, _resimulate_chunk
from simcred.scenario.variation import generate_variations
from simcred.sim.experiments import cutin
from simcred.sim.resimulation import resimulate

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine, save_results  # noqa: E402

TARGET = 10.0


def generate_and_resimulate(description, config: VaryConfig, runner: Engine) -> int:
    variations = generate_variations(description, config.n, config.seed, options=config.options,
                                     limits=config.limits, runner=runner,
                                     chunk_size=config.chunk_size)
    jobs = [(k, [v.description for v in variations.variations[k:k + config.chunk_size]])
            for k in range(0, len(variations.variations), config.chunk_size)]
    indices = [v.index for v in variations.variations]
    runner.map(_resimulate_chunk, jobs, shared_values={
        "config": config, "sensor": None, "indices": indices, "original": description})
    return variations.kept


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 variations, one repeat")
    quick = parser.parse_args().quick
    config = VaryConfig(n=100 if quick else 300)
    repeats = 1 if quick else 2
    description = reprocess(cutin.simulate(0)).descriptions["fit(GT)"]
    one, _ = best_of(lambda: resimulate(description), 3)
    serial, kept = best_of(lambda: generate_and_resimulate(description, config, Engine()),
                           repeats)
    with engine(2, None) as runner:
        generate_and_resimulate(description, VaryConfig(n=20), runner)  # warm-up
        dask, _ = best_of(lambda: generate_and_resimulate(description, config, runner), repeats)
    table = Table(title=f"{config.n} variations generated, refitted and resimulated")
    for column in ("where", "seconds", "target", "met", "in unvaried resimulations"):
        table.add_column(column)
    results = {"variations": config.n, "kept": kept, "one_resimulation_s": one}
    for label, seconds in (("serial (1 process)", serial), ("Dask, 2 workers", dask)):
        met = seconds < TARGET
        table.add_row(label, f"{seconds:.2f}", f"< {TARGET:g}",
                      "[green]yes[/green]" if met else "[red]no[/red]", f"{seconds / one:.0f}")
        results[label] = {"seconds": seconds, "met": met, "ratio_to_one_resimulation":
                          seconds / one}
    Console().print(table)
    save_results(ROOT / "benchmarks" / "results" / "vary.json",
                 {"machine": machine(), "results": results})


if __name__ == "__main__":
    main()
