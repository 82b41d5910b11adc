"""Scaling of the distance matrix over Dask workers (issue 25): prints a table, writes JSON.

The case of the issue: ``--sets`` trace sets × ``--runs`` runs × ``--steps`` steps of two float
features (lane changes, each set with its own lane-change duration), written as Parquet files,
then ``matrix`` over all pairs with the run-level test. Each configuration runs in its own process
(so every peak is its own): in-process (the reference), then a local Dask cluster of each worker
count in ``--workers``. Per configuration: wall seconds of the ``matrix`` call (cluster start
reported apart), speed-up against in-process, bytes moved between workers (in all and per pair),
peak RSS of the client and of the largest worker, and the SHA-256 of ``matrix.to_json()``, which
must be the same for every worker count.

Usage: python benchmarks/scale.py [--sets 16 --runs 6000 --steps 200 --workers 1,2]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from contextlib import nullcontext
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from dask.utils import key_split
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import machine, save_results  # noqa: E402

from simcred.compare import matrix  # noqa: E402
from simcred.engine import DaskEngine, Engine  # noqa: E402
from simcred.examples import lane_change_runs  # noqa: E402

FEATURES = ["x", "y"]


def write_sets(folder: Path, sets: int, runs: int, steps: int) -> list[str]:
    """``sets`` Parquet files of lane changes, set k with duration scale 1 - 0.01 k."""
    paths = []
    for k in range(sets):
        traces = lane_change_runs(runs, steps, 0.1, 1.0 - 0.01 * k, np.random.default_rng(k),
                                  f"set{k:02d}")
        path = folder / f"set{k:02d}.parquet"
        traces.write(path)
        paths.append(str(path))
    return paths


def peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # Linux: KiB


def _outgoing(dask_worker) -> int:
    return dask_worker.transfer_outgoing_bytes_total


class TimedEngine(Engine):
    """In-process, adding up the seconds of every task by the task's function name."""

    def __init__(self) -> None:
        self.task_seconds: dict[str, float] = defaultdict(float)

    def _timed(self, task):
        def timed(item):
            start = time.perf_counter()
            try:
                return task(item)
            finally:
                self.task_seconds[key_split(task.__qualname__)] += time.perf_counter() - start
        return timed

    def map(self, task, items, **options):
        return super().map(self._timed(task), items, **options)

    def keep(self, task, items, near=None):
        return super().keep(self._timed(task), items, near)


def stream_seconds(records: list[dict]) -> dict[str, float]:
    """Compute seconds per task function, and transfer seconds, of a Dask task stream."""
    out: dict[str, float] = defaultdict(float)
    for record in records:
        for part in record["startstops"]:
            name = key_split(record["key"]) if part["action"] == "compute" else "transfer"
            out[name] += part["stop"] - part["start"]
    return dict(out)


def run_one(paths: list[str], workers: int, permutations: int, whole: bool = False) -> dict:
    """One configuration in this process: 0 workers = in-process; ``whole``: every pair
    compared from its two whole prepared sets, as before the split into per-set parts (the
    reference of the same run)."""
    from distributed import get_task_stream

    if whole:
        from simcred.compare import pairwise

        pairwise.sorted_sets = SimpleNamespace(**{**vars(pairwise.sorted_sets),
                                                  "supports": lambda _options: False})

    start = time.perf_counter()
    runner = TimedEngine() if workers == 0 else DaskEngine(workers=workers)
    startup = time.perf_counter() - start
    try:
        moved_before = sum(runner.client.run(_outgoing).values()) if workers else 0
        start = time.perf_counter()
        with get_task_stream(runner.client) if workers else nullcontext() as stream:
            result = matrix(paths, features=FEATURES, bins=10, permutations=permutations,
                            seed=0, runner=runner)
        seconds = time.perf_counter() - start
        moved = sum(runner.client.run(_outgoing).values()) - moved_before if workers else 0
        worker_peak = max(runner.client.run(peak_rss_bytes).values()) if workers else 0
        tasks = stream_seconds(stream.data) if workers else dict(runner.task_seconds)
    finally:
        runner.close()
    return {"workers": workers, "path": "whole" if whole else "split", "seconds": seconds,
            "startup_seconds": startup,
            "bytes_between_workers": moved, "pairs": len(result.comparisons),
            "peak_rss_client": peak_rss_bytes(), "peak_rss_worker": worker_peak,
            "task_seconds": tasks,
            "sha256": hashlib.sha256(result.to_json().encode()).hexdigest()}


def measure(paths: list[str], workers: int, permutations: int, whole: bool = False) -> dict:
    """:func:`run_one` in a fresh process, so that its peaks are its own."""
    out = subprocess.run([sys.executable, __file__, "--one", str(workers), "--permutations",
                          str(permutations), *(["--whole-one"] if whole else []), *paths],
                         check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _pair_seconds(paths: list[str], pairs: list[tuple[int, int]], permutations: int,
                  barrier=None) -> float:
    """Seconds of comparing ``pairs`` in this process, the sets read and sorted before (and,
    with a barrier, every process starting its pairs at the same moment)."""
    from itertools import chain

    from simcred.compare import pairwise
    from simcred.compare.facts import SetFacts
    from simcred.compare.method import Method
    from simcred.compare.process import comparison_options, load

    needed = sorted(set(chain.from_iterable(pairs)))
    sets = {k: load(paths[k]) for k in needed}
    settings = comparison_options([SetFacts.of(sets[k]) for k in needed],
                                  Method.of(None, features=FEATURES, bins=10,
                                            permutations=permutations, seed=0))
    held = {k: pairwise._prepare_sorted((sets[k], settings)) for k in needed}
    sizes = [(held[i].prepared.info.runs, held[j].prepared.info.runs) for i, j in pairs]
    draws = pairwise._shared_draws(Engine(), sizes, settings)  # as the matrix draws them
    if barrier is not None:
        barrier.wait()
    start = time.perf_counter()
    for (i, j), draw in zip(pairs, draws, strict=True):
        pairwise._compare_sorted((held[i], held[j], settings, draw))
    return time.perf_counter() - start


def ceiling(paths: list[str], processes: int, permutations: int) -> dict:
    """The pairs' compute alone, dealt round robin to ``processes`` processes that start
    together (no Dask, no transfers, each set read by every process that needs it), against
    all pairs in one process: the speed-up that contention for memory and cores leaves to any
    scheduler. Every process runs with the Dask workers' thread settings (one BLAS thread:
    :data:`simcred.engine.WORKER_ENVIRON`), so 16 processes do not start 16 BLAS threads each."""
    import multiprocessing as mp
    from itertools import combinations
    from unittest import mock

    from simcred.engine import WORKER_ENVIRON

    pairs = list(combinations(range(len(paths)), 2))
    context = mp.get_context("spawn")
    with mock.patch.dict(os.environ, {k: str(v) for k, v in WORKER_ENVIRON.items()}):
        return _ceiling(context, paths, pairs, processes, permutations)


def _ceiling(context, paths: list[str], pairs: list[tuple[int, int]], processes: int,
             permutations: int) -> dict:
    with context.Pool(1) as pool:
        alone = pool.apply(_pair_seconds, (paths, pairs, permutations))
    manager = context.Manager()
    barrier = manager.Barrier(processes)
    with context.Pool(processes) as pool:
        shares = [pool.apply_async(_pair_seconds, (paths, pairs[k::processes], permutations,
                                                   barrier)) for k in range(processes)]
        together = [r.get() for r in shares]
    manager.shutdown()
    return {"processes": processes, "alone_seconds": alone, "slowest_seconds": max(together),
            "sum_seconds": sum(together), "ceiling": alone / max(together),
            "inflation": sum(together) / alone}


def table(rows: list[dict], title: str) -> Table:
    view = Table(title=title)
    for name in ("workers", "pairs compared", "matrix s", "start s", "speed-up", "efficiency",
                 "MB moved", "MB/pair", "client peak MB", "worker peak MB", "identical"):
        view.add_column(name, justify="right")
    for r in rows:
        view.add_row(str(r["workers"] or "in-process"), r["path"], f"{r['seconds']:.1f}",
                     f"{r['startup_seconds']:.1f}", f"{r['speedup']:.2f}",
                     f"{r['efficiency']:.0%}", f"{r['bytes_between_workers'] / 1e6:.0f}",
                     f"{r['bytes_between_workers'] / 1e6 / r['pairs']:.1f}",
                     f"{r['peak_rss_client'] / 1e6:.0f}", f"{r['peak_rss_worker'] / 1e6:.0f}",
                     "yes" if r["identical"] else "NO")
    return view


def phases(rows: list[dict]) -> Table:
    """Seconds spent in each kind of task, added over all workers (in-process: the reference)."""
    names = sorted({name for r in rows for name in r["task_seconds"]})
    view = Table(title="task seconds, added over workers (more than in-process: contention)")
    view.add_column("workers", justify="right")
    view.add_column("pairs compared")
    for name in names:
        view.add_column(name, justify="right")
    for r in rows:
        view.add_row(str(r["workers"] or "in-process"), r["path"],
                     *(f"{r['task_seconds'].get(name, 0.0):.1f}" for name in names))
    return view


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=16)
    parser.add_argument("--runs", type=int, default=6000)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--permutations", type=int, default=199)
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    parser.add_argument("--whole", default="", help="worker counts (comma-separated) to run "
                        "also with every pair compared from its two whole sets, as before the "
                        "per-set split; its in-process reference is added")
    parser.add_argument("--repeats", type=int, default=1, help="each worker count this often")
    parser.add_argument("--ceiling", type=int, default=0, help="also measure the pairs' compute "
                        "in this many processes started together, without Dask (0: not)")
    parser.add_argument("--out", type=Path, help="JSON file (default: "
                        "benchmarks/results/scale_<cpus>cpu.json)")
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--whole-one", dest="whole_one", action="store_true",
                        help=argparse.SUPPRESS)
    parser.add_argument("paths", nargs="*", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(run_one(args.paths, args.one, args.permutations, args.whole_one)))
        return
    configs = [(w, False) for w in [0, *_counts(args.workers)] * args.repeats]
    if args.whole:
        configs += [(w, True) for w in [0, *_counts(args.whole)]]
    with tempfile.TemporaryDirectory(prefix="simcred-scale-") as folder:
        start = time.perf_counter()
        paths = write_sets(Path(folder), args.sets, args.runs, args.steps)
        written = time.perf_counter() - start
        rows = []
        for w, whole in configs:
            rows.append(measure(paths, w, args.permutations, whole))
            print(f"{rows[-1]['path']} {w} workers: {rows[-1]['seconds']:.1f} s", flush=True)
        bound = ceiling(paths, args.ceiling, args.permutations) if args.ceiling else None
        if bound:
            print(f"ceiling at {bound['processes']} processes: {bound['ceiling']:.2f}x (pairs "
                  f"alone {bound['alone_seconds']:.1f} s, slowest share "
                  f"{bound['slowest_seconds']:.1f} s, work inflated {bound['inflation']:.2f}x)",
                  flush=True)
    reference = {r["path"]: r for r in reversed(rows) if r["workers"] == 0}
    for r in rows:
        r["speedup"] = reference[r["path"]]["seconds"] / r["seconds"]
        r["efficiency"] = r["speedup"] / max(r["workers"], 1)
        r["identical"] = r["sha256"] == reference["split"]["sha256"]
    case = (f"matrix of {args.sets} sets × {args.runs:,} runs × {args.steps} steps, 2 features, "
            f"10 bins, runs test, {args.permutations} permutations")
    console = Console(width=150)
    console.print(table(rows, case))
    console.print(phases(rows))
    out = args.out or ROOT / "benchmarks" / "results" / f"scale_{os.cpu_count()}cpu.json"
    save_results(out, {"machine": machine(), "case": case, "write_seconds": written,
                       "rows": rows, "ceiling": bound})


def _counts(text: str) -> list[int]:
    return [int(w) for w in text.split(",") if w]


if __name__ == "__main__":
    main()
