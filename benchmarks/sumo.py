"""Benchmark of the SUMO replay: prints a table, writes benchmarks/results/sumo.json.

Target (issue 13): 600 real OpenACC episodes (10 s at 0.1 s) × 3 car-following models (Krauss,
IDM, EIDM) in < 60 s on 2 cores. Measured: the replay in-process (1 core) and on a local Dask
cluster of 2 workers (cluster start-up excluded, it is paid once per campaign), as wall-clock
seconds, as a ratio to the 60 s target, and per episode. Reference measured in the same run: bare
libsumo on the same episodes (load the same network and routes, step 100 times, no TraCI calls
per step), so the ratio replay / bare is the cost of imposing the leader and reading the states.

Usage: python benchmarks/sumo.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from simcred.engine import engine
from simcred.io.openacc import read_openacc
from simcred.sim import sumo
from simcred.traces import take

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import machine, save_results  # noqa: E402

MODELS = ("Krauss", "IDM", "EIDM")
TARGET_S = 60.0


def episodes(n: int):
    human = read_openacc(follower="human")
    if n <= human.n_runs:
        return take(human, range(n))
    acc = read_openacc(follower="acc")  # top up with ACC episodes (leaders are all we replay)
    return take(acc, range(n)) if n <= acc.n_runs else acc


def bare(traces, models) -> float:
    """Seconds for load + steps only, the same episodes and vTypes, no per-step TraCI calls."""
    lib = sumo._libsumo()
    net = sumo._network()
    routes = net.parent / "bench.rou.xml"
    start = time.perf_counter()
    started = False
    for name in models:
        model = sumo.SumoModel(name)
        for i in range(traces.n_runs):
            ep = sumo._episode(traces, i)
            routes.write_text(sumo._routes(model, ep))
            options = sumo._options(net, routes, ep.step, sumo.episode_seed(0, ep.run_id))
            lib.load(options) if started else lib.start(["sumo", *options])
            started = True
            for _ in range(len(ep.time)):
                lib.simulationStep()
    lib.close()
    return time.perf_counter() - start


def timed(traces, workers: int | None) -> tuple[float, dict]:
    with engine(workers) as runner:
        if workers:  # warm the workers (imports, network) outside the timing
            sumo.replay(take(traces, [0]), ["IDM"], runner=runner)
        start = time.perf_counter()
        out = sumo.replay(traces, MODELS, seed=0, runner=runner, chunk_size=50)
        return time.perf_counter() - start, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="60 episodes instead of 600")
    n = 60 if parser.parse_args().quick else 600
    traces = episodes(n)
    reference = bare(traces, MODELS)
    serial, a = timed(traces, None)
    dask, b = timed(traces, 2)
    same = all(a[m].digest() == b[m].digest() for m in MODELS)
    runs = traces.n_runs * len(MODELS)
    rows = [("bare libsumo (reference, 1 core)", reference),
            ("replay in-process (1 core)", serial), ("replay on Dask, 2 workers", dask)]
    table = Table(title=f"SUMO replay: {traces.n_runs} episodes × {len(MODELS)} models "
                        f"({', '.join(MODELS)}), {int(traces.lengths[0])} steps each")
    for col in ("case", "wall [s]", "ms / episode-model", "÷ bare", "÷ 60 s target"):
        table.add_column(col, justify="left" if col == "case" else "right")
    for name, wall in rows:
        table.add_row(name, f"{wall:.1f}", f"{1000 * wall / runs:.1f}",
                      f"{wall / reference:.2f}", f"{wall / TARGET_S:.2f}")
    Console().print(table)
    print(f"serial and Dask outputs identical: {same}")
    results = {"machine": machine(), "sumo": sumo.sumo_version(), "episodes": traces.n_runs,
               "models": list(MODELS), "steps": int(traces.lengths[0]),
               "target_s": TARGET_S, "identical_serial_dask": same,
               "cases": [{"case": name, "wall_s": wall, "ms_per_episode_model":
                          1000 * wall / runs, "ratio_to_bare": wall / reference,
                          "ratio_to_target": wall / TARGET_S} for name, wall in rows]}
    name = "sumo-quick.json" if n < 600 else "sumo.json"
    save_results(ROOT / "benchmarks" / "results" / name, results)
    np.testing.assert_equal(same, True)  # a wrong benchmark is worse than none


if __name__ == "__main__":
    main()
