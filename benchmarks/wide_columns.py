"""Benchmark of wide tables (issue 29): 10,000 columns read in linear time, in every tabular
format; prints a table, writes benchmarks/results/wide_columns.json.

Per format (a CSV directory, one Parquet file, one long CSV): the time to read one run of
**2 rows x 10,000 columns** (``MAX_COLUMNS``, the limit: ``t`` and 9,999 signals; the long CSV:
``run``, ``t`` and 9,998), against the same reader in the same process on

* **2 columns x 5,000 rows** (``t`` and one signal, and ``run`` in the long CSV: the
  acceptance's reference),
* **2 columns x 10,000 rows** (as many cells as the wide table),
* **5,000 columns x 2 rows** (half the width: linear time reads it in about half the time).

The acceptance: the wide table in < 5 s, and the ratio to the tall one stated (a quadratic
per-column lookup made it 47,000x; 235 s). Every time is the best of ``--repeats`` reads.

Usage: python benchmarks/wide_columns.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from simcred.io import csvdir, longformat, parquet
from simcred.io._columns import MAX_COLUMNS
from simcred.traces import TraceSet

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine, save_results  # noqa: E402

TARGET_S = 5.0
#: shape name -> (rows, signals; None: as many as the limit allows besides t (and run))
SHAPES = {"wide": (2, None), "half": (2, MAX_COLUMNS // 2 - 1),
          "tall 2 x 5,000": (5_000, 1), "tall 2 x 10,000": (10_000, 1)}
#: format -> (extra columns besides t and the signals, writer, reader)
FORMATS: dict[str, tuple[int, Callable, Callable]] = {
    "csv-dir": (0, lambda ts, p: ts.write(p), csvdir.read),
    "parquet": (1, lambda ts, p: ts.write(p.with_suffix(".parquet")),
                lambda p: parquet.read(p.with_suffix(".parquet"))),
    "long csv": (1, lambda ts, p: longformat.write(ts, p.with_suffix(".csv"), run_column="run"),
                 lambda p: longformat.read(p.with_suffix(".csv"), run_column="run")),
}


def traces(rows: int, signals: int) -> TraceSet:
    """One run of ``rows`` steps and ``signals`` signals (distinct values)."""
    values = np.arange(rows * signals, dtype=np.float64).reshape(rows, signals) / 7
    return TraceSet.from_runs([{"t": np.arange(rows, dtype=np.float64),
                                **{f"s{j}": values[:, j] for j in range(signals)}}],
                              run_ids=["a"])


def bench_format(name: str, folder: Path, repeats: int) -> dict:
    extra, write, read = FORMATS[name]
    found = {}
    for shape, (rows, signals) in SHAPES.items():
        signals = signals or MAX_COLUMNS - 1 - extra
        path = folder / f"{name.replace(' ', '_')}-{shape.replace(' ', '_').replace(',', '')}"
        write(traces(rows, signals), path)
        seconds, ts = best_of(lambda p=path: read(p), repeats)
        assert ts.values.shape == (rows, signals), ts.values.shape
        found[shape] = {"rows": rows, "columns": signals + 1 + extra, "seconds": seconds}
    wide = found["wide"]["seconds"]
    return {"shapes": found, "target_s": TARGET_S, "met": wide < TARGET_S,
            "ratio_to_tall_5000": wide / found["tall 2 x 5,000"]["seconds"],
            "ratio_to_tall_same_cells": wide / found["tall 2 x 10,000"]["seconds"],
            "ratio_to_half_width": wide / found["half"]["seconds"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    repeats = 2 if parser.parse_args().quick else 5
    with tempfile.TemporaryDirectory() as folder:
        results = {name: bench_format(name, Path(folder), repeats) for name in FORMATS}
    table = Table(title=f"reading 2 rows x {MAX_COLUMNS:,} columns (best of {repeats}, one "
                        "process)")
    for column in ("format", "wide", "target", "met", "2 col x 5,000 rows", "ratio",
                   "2 col x 10,000 rows", "ratio", "5,000 col", "ratio"):
        table.add_column(column)
    for name, r in results.items():
        s = {k: v["seconds"] for k, v in r["shapes"].items()}
        table.add_row(name, f"{s['wide']:.3f} s", f"< {TARGET_S:g} s",
                      "[green]yes[/green]" if r["met"] else "[red]no[/red]",
                      f"{s['tall 2 x 5,000'] * 1e3:.1f} ms", f"{r['ratio_to_tall_5000']:.0f}x",
                      f"{s['tall 2 x 10,000'] * 1e3:.1f} ms",
                      f"{r['ratio_to_tall_same_cells']:.0f}x", f"{s['half']:.3f} s",
                      f"{r['ratio_to_half_width']:.2f}x")
    Console(width=150).print(table)
    save_results(ROOT / "benchmarks" / "results" / "wide_columns.json",
                 {"machine": machine(), "repeats": repeats, "results": results})


if __name__ == "__main__":
    main()
