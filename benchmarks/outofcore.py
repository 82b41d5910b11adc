"""Out-of-core comparison of Parquet data sets: peak memory at 10⁸ rows, identity with memory.

Issue 25, part 2 and its acceptance point: two sets × 250,000 runs × 200 steps × two float
features (10⁸ rows) are written as partitioned Parquet by this script (streamed, one partition at
a time, into a temporary folder that is removed afterwards), then compared out of core
(``simcred.compare.compare`` on the two folders; default options: runs test, 10 bins, 999
permutations) in a child process whose peak RSS is measured (``VmHWM``, and ``getrusage`` of
the children). Also measured:

* identity: the same script's data at 2 × 5,000 runs in 5 partitions each, out of core against
  ``compare(read_dataset(A), read_dataset(B))`` in memory: the Comparison JSON byte for byte;
* memory per row of the in-memory path on 2 × 60,000 runs × 200 steps, two float features: peak
  RSS of ``compare`` minus the RSS before it (the sets already built), over the rows, against
  the issue's target of 40 B per row (measured only);
* the whole process's peak per row of ``compare(path_a, path_b)`` on random walks of the same
  size written as two Parquet files (imports, reading and comparing; measured only).

Prints a table and writes benchmarks/results/outofcore.json. Usage:
``python benchmarks/outofcore.py [--runs 250000] [--steps 200] [--runs-per-partition 5000]
[--data DIR] [--keep]``; ``--quick`` runs a small version (not written to the results file);
``--file-memory-only`` measures only the last case (written to ``--results``, e.g.
``outofcore-file-memory.json``), and ``--baseline-src DIR`` measures it with the sources in
``DIR/src`` too (an older commit's tree, e.g. from ``git archive``), on the same files.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import machine, save_results  # noqa: E402

PHI = {"a": 0.90, "b": 0.95}  # acceleration AR(1) coefficients of the two sets (a difference)
ROUGH_PHI = {"a": 0.90, "b": 0.85}  # --process rough: the signals themselves are AR(1)
DT = 0.1
TARGET_RSS = 2 * 1024**3
TARGET_BYTES_PER_ROW = 40
PROCESS = {"name": "smooth"}


def partition_table(which: str, part: int, runs: int, steps: int, seed: int) -> pa.Table:
    """One partition of ``runs`` runs in long format ``run``, ``t``, ``x``, ``y``; deterministic
    in (which, part, seed).

    ``smooth`` (default): vehicle-like signals sampled at 10 Hz, a speed-like ``x`` and an
    offset-like ``y``, each integrating an AR(1) acceleration (about 30 distinct (state,
    successor) pairs per run on 10 × 10 bins). ``rough``: ``x``, ``y`` themselves AR(1) with
    unit noise (about 180 pairs per run: the count matrix is six times larger).
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(ord(which), part)))
    xy = np.empty((runs, steps, 2))
    if PROCESS["name"] == "rough":
        phi = ROUGH_PHI[which]
        xy[:, 0] = rng.normal(0, 1 / np.sqrt(1 - phi * phi), size=(runs, 2))
        for t in range(1, steps):
            xy[:, t] = phi * xy[:, t - 1] + rng.normal(size=(runs, 2))
    else:
        phi, gain = PHI[which], np.array([0.2, 0.05])
        xy[:, 0] = rng.normal(0, [5.0, 1.0], size=(runs, 2))
        acceleration = rng.normal(size=(runs, 2))
        for t in range(1, steps):
            acceleration = phi * acceleration + rng.normal(0, np.sqrt(1 - phi * phi),
                                                           size=(runs, 2))
            xy[:, t] = xy[:, t - 1] + gain * acceleration
    labels = pa.array([f"{which}{part:05d}-{i:05d}" for i in range(runs)], type=pa.string())
    run = pa.DictionaryArray.from_arrays(np.repeat(np.arange(runs, dtype=np.int32), steps),
                                         labels)
    return pa.table({"run": run, "t": np.tile(np.arange(steps) * DT, runs),
                     "x": xy[:, :, 0].ravel(), "y": xy[:, :, 1].ravel()})


def write_set(folder: Path, which: str, runs: int, steps: int, per_partition: int,
              seed: int) -> int:
    """Write the set partition by partition (only one partition in memory); number of files."""
    folder.mkdir(parents=True, exist_ok=True)
    parts = 0
    for part, first in enumerate(range(0, runs, per_partition)):
        table = partition_table(which, part, min(per_partition, runs - first), steps, seed)
        pq.write_table(table, folder / f"part-{part:05d}.parquet")
        parts += 1
        del table
    return parts


def peak_rss() -> int:
    """This process's peak resident set (bytes), from /proc (VmHWM)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def current_rss() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) * 1024
    return 0


def reset_peak() -> bool:
    """Reset VmHWM to the current RSS (Linux ``clear_refs`` 5); False where not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


# -- children (each measured in its own process) -----------------------------------------------

ENTRIES: dict = {}


def child_outofcore(a: str, b: str, out: str) -> None:
    import simcred.compare.outofcore as outofcore
    from simcred.compare import compare

    measured = outofcore.counts_comparison

    def counted(counts, *rest):  # records the count matrix's size, changes nothing
        ENTRIES["nnz"] = int(counts.matrix.nnz)
        return measured(counts, *rest)

    outofcore.counts_comparison = counted

    before = current_rss()
    start = time.perf_counter()
    result = compare(a, b, seed=1)
    wall = time.perf_counter() - start
    Path(out).write_text(result.to_json())
    print(json.dumps({"wall_s": wall, "peak_rss": peak_rss(), "rss_before": before,
                      "distance": result.distance, "chain_pvalue": result.chain.pvalue,
                      "n_states": result.n_states, "count_entries": ENTRIES.get("nnz")}))


def child_memory(runs: int, steps: int) -> None:
    from simcred.compare import compare
    from simcred.traces import TraceSet

    sets = []
    for which in ("a", "b"):
        table = partition_table(which, 0, runs, steps, seed=11)
        sets.append(TraceSet.from_arrow(table, source=which))
        del table
    rows = sum(s.n_rows for s in sets)
    resettable = reset_peak()
    before = current_rss()
    start = time.perf_counter()
    result = compare(*sets, seed=1)
    wall = time.perf_counter() - start
    peak = peak_rss()
    print(json.dumps({"wall_s": wall, "peak_rss": peak, "rss_before": before, "rows": rows,
                      "peak_reset": resettable, "distance": result.distance}))


def walk_table(which: str, runs: int, steps: int, seed: int) -> pa.Table:
    """Random walks (``x``, ``y`` cumulative sums of standard normal steps) in the layout of
    :func:`partition_table`; set ``b``'s steps have standard deviation 1.1."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(ord(which),)))
    scale = 1.0 if which == "a" else 1.1
    xy = np.cumsum(rng.normal(0, scale, size=(runs, steps, 2)), axis=1)
    labels = pa.array([f"{which}-{i:06d}" for i in range(runs)], type=pa.string())
    run = pa.DictionaryArray.from_arrays(np.repeat(np.arange(runs, dtype=np.int32), steps),
                                         labels)
    return pa.table({"run": run, "t": np.tile(np.arange(steps) * DT, runs),
                     "x": xy[:, :, 0].ravel(), "y": xy[:, :, 1].ravel()})


def child_file_memory(a: str, b: str) -> None:
    """The whole process's peak of ``compare(path_a, path_b)``: imports, reading, comparing."""
    imported = current_rss()
    from simcred.compare import compare

    imported = current_rss()
    start = time.perf_counter()
    result = compare(a, b, seed=1)
    wall = time.perf_counter() - start
    rows = sum(i.rows for i in result.inputs)
    print(json.dumps({"wall_s": wall, "peak_rss": peak_rss(), "rss_imports": imported,
                      "rows": rows, "peak_bytes_per_row": peak_rss() / rows,
                      "distance": result.distance}))


def file_memory(folder: Path, runs: int, steps: int, baseline: Path | None = None) -> dict:
    """Random walks written as two Parquet files, compared from their paths in a child (and in
    one running the ``baseline`` tree's sources, if given)."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for which in ("a", "b"):
        paths.append(str(folder / f"{which}.parquet"))
        pq.write_table(walk_table(which, runs, steps, seed=13), paths[-1])
    measured = run_child("file-memory", *paths)
    measured["target_met"] = measured["peak_bytes_per_row"] <= TARGET_BYTES_PER_ROW
    if baseline is not None:
        measured["baseline"] = run_child("file-memory", *paths, src=baseline / "src")
    return measured


def run_child(*args: str, src: Path = ROOT / "src") -> dict:
    done = subprocess.run([sys.executable, __file__, "--process", PROCESS["name"], "--child",
                           *args], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(src)})
    if done.returncode:
        raise SystemExit(f"child {args[0]} failed ({done.returncode}): {done.stderr.strip()}")
    measured = json.loads(done.stdout.strip().splitlines()[-1])
    measured["children_maxrss"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    return measured


# -- the benchmark -------------------------------------------------------------------------------

def identity(folder: Path, runs: int, steps: int) -> dict:
    """Out of core vs in memory on data that fits: byte-identical Comparison JSON."""
    from simcred.compare import compare
    from simcred.io.dataset import read_dataset

    paths = []
    for which in ("a", "b"):
        write_set(folder / which, which, runs, steps, runs // 5, seed=7)
        paths.append(folder / which)
    start = time.perf_counter()
    ooc = compare(*paths, seed=1).to_json()
    wall_ooc = time.perf_counter() - start
    start = time.perf_counter()
    memory = compare(*(read_dataset(p) for p in paths), seed=1).to_json()
    wall_memory = time.perf_counter() - start
    return {"runs_per_set": runs, "steps": steps, "partitions_per_set": 5,
            "identical_json": ooc == memory, "wall_outofcore_s": wall_ooc,
            "wall_memory_s": wall_memory, "distance": json.loads(ooc)["distance"]}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=250_000)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--runs-per-partition", type=int, default=5_000)
    parser.add_argument("--memory-runs", type=int, default=60_000)
    parser.add_argument("--identity-runs", type=int, default=5_000)
    parser.add_argument("--data", type=Path, default=None)
    parser.add_argument("--keep", action="store_true")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--process", choices=["smooth", "rough"], default="smooth")
    parser.add_argument("--results", default="outofcore.json")
    parser.add_argument("--child", nargs="+")
    parser.add_argument("--file-memory-only", action="store_true")
    parser.add_argument("--baseline-src", type=Path, default=None)
    args = parser.parse_args()
    PROCESS["name"] = args.process
    if args.child:
        kind, *rest = args.child
        if kind == "outofcore":
            child_outofcore(*rest)
        elif kind == "file-memory":
            child_file_memory(*rest)
        else:
            child_memory(int(rest[0]), int(rest[1]))
        return
    if args.quick:
        args.runs, args.memory_runs, args.identity_runs = 5_000, 5_000, 500
        args.runs_per_partition = 1_000
    sys.path.insert(0, str(ROOT / "src"))
    from rich.console import Console
    from rich.table import Table

    data = args.data or Path(tempfile.mkdtemp(prefix="simcred-outofcore-"))
    if args.file_memory_only:
        return file_memory_only(args, data)
    results: dict = {"machine": machine(), "process": args.process, "runs_per_set": args.runs,
                     "steps": args.steps, "runs_per_partition": args.runs_per_partition,
                     "options": "compare(A, B, seed=1): runs test, 10 bins, 999 permutations"}
    try:
        start = time.perf_counter()
        parts = [write_set(data / w, w, args.runs, args.steps, args.runs_per_partition, seed=3)
                 for w in ("a", "b")]
        results["write"] = {"wall_s": time.perf_counter() - start,
                            "writer_peak_rss": peak_rss(), "partitions": sum(parts),
                            "rows": 2 * args.runs * args.steps,
                            "bytes_on_disk": sum(f.stat().st_size
                                                 for f in data.rglob("*.parquet"))}
        out = data / "comparison.json"
        results["outofcore"] = run_child("outofcore", str(data / "a"), str(data / "b"),
                                         str(out))
        results["outofcore"]["rows"] = results["write"]["rows"]
        results["outofcore"]["bytes_per_row"] = results["outofcore"]["peak_rss"] \
            / results["write"]["rows"]
        results["outofcore"]["below_2GB"] = results["outofcore"]["peak_rss"] < TARGET_RSS
        shutil.rmtree(data / "a"), shutil.rmtree(data / "b")
        results["identity"] = identity(data / "identity", args.identity_runs, args.steps)
        memory = run_child("memory", str(args.memory_runs), str(args.steps))
        memory["delta_bytes_per_row"] = (memory["peak_rss"] - memory["rss_before"]) \
            / memory["rows"]
        memory["peak_bytes_per_row"] = memory["peak_rss"] / memory["rows"]
        memory["ratio_to_target"] = memory["delta_bytes_per_row"] / TARGET_BYTES_PER_ROW
        results["memory"] = memory
        results["file_memory"] = file_memory(data / "walks", args.memory_runs, args.steps)
    finally:
        if not args.keep:
            shutil.rmtree(data, ignore_errors=True)
    show(results, Console(), Table)
    if not args.quick:
        save_results(ROOT / "benchmarks" / "results" / args.results, results)


def file_memory_only(args: argparse.Namespace, data: Path) -> None:
    """Only the whole-process case of ``compare(path_a, path_b)`` (and its baseline)."""
    try:
        measured = file_memory(data / "walks", args.memory_runs, args.steps, args.baseline_src)
    finally:
        if not args.keep:
            shutil.rmtree(data, ignore_errors=True)
    results = {"machine": machine(), "runs_per_set": args.memory_runs, "steps": args.steps,
               "options": "compare(path_a, path_b, seed=1): runs test, 10 bins, 999 "
               "permutations", "file_memory": measured}
    for name, case in (("this tree", measured), ("baseline", measured.get("baseline"))):
        if case:
            print(f"{name}: peak {case['peak_rss'] / 1024**3:.3f} GiB, "
                  f"{case['peak_bytes_per_row']:.1f} B per row, {case['wall_s']:.1f} s")
    if not args.quick:
        save_results(ROOT / "benchmarks" / "results" / args.results, results)


def show(results: dict, console, table_type) -> None:
    gib = 1024**3
    table = table_type(title="out of core (issue 25): 2 sets, two float features, runs test")
    for column in ("case", "rows", "wall (s)", "peak RSS", "per row", "check"):
        table.add_column(column, justify="right" if column != "case" else "left")
    w, o, i, m = (results[k] for k in ("write", "outofcore", "identity", "memory"))
    table.add_row(f"write {w['partitions']} partitions", f"{w['rows']:,}", f"{w['wall_s']:.0f}",
                  f"{w['writer_peak_rss'] / gib:.2f} GiB", "", f"{w['bytes_on_disk'] / gib:.1f} "
                  "GiB on disk")
    table.add_row("compare out of core", f"{o['rows']:,}", f"{o['wall_s']:.0f}",
                  f"{o['peak_rss'] / gib:.2f} GiB", f"{o['bytes_per_row']:.1f} B",
                  "< 2 GB" if o["below_2GB"] else "≥ 2 GB (target missed)")
    table.add_row(f"identity 2 × {i['runs_per_set']:,} runs",
                  f"{2 * i['runs_per_set'] * i['steps']:,}",
                  f"{i['wall_outofcore_s']:.1f} / {i['wall_memory_s']:.1f}", "", "",
                  "same JSON" if i["identical_json"] else "DIFFERENT JSON")
    table.add_row("compare in memory", f"{m['rows']:,}", f"{m['wall_s']:.1f}",
                  f"{m['peak_rss'] / gib:.2f} GiB", f"{m['delta_bytes_per_row']:.0f} B "
                  f"(Δ)", f"{m['ratio_to_target']:.1f}× the 40 B target")
    f = results.get("file_memory")
    if f:
        table.add_row("compare(path_a, path_b), random walks, whole process", f"{f['rows']:,}",
                      f"{f['wall_s']:.1f}", f"{f['peak_rss'] / gib:.2f} GiB",
                      f"{f['peak_bytes_per_row']:.0f} B", "≤ 40 B" if f["target_met"]
                      else "> 40 B (target missed)")
    console.print(table)
    entries = o.get("count_entries")
    if entries:
        console.print(f"count matrix: {entries:,} (run, state, successor) entries, "
                      f"{entries / (2 * results['runs_per_set']):.1f} per run "
                      f"({results['process']} process)")


if __name__ == "__main__":
    main()
