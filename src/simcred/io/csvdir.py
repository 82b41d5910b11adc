"""A trace set as a directory of CSV files, one per run (the format of Neurohr et al. 2023 [1]).

Each file has a header row of signal names including the time column ``t``; the run id is the file
stem. Files are read in natural order (``run_2`` before ``run_10``). An optional ``traceset.json``
beside them holds the metadata. Floats are written in their shortest round-trip form, so
write → read is exact.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from simcred.errors import TraceSetError
from simcred.io._columns import float_column
from simcred.traces import TIME, TraceSet, _check_same_signals

METADATA_FILE = "traceset.json"
_READ = pacsv.ConvertOptions(null_values=[""], strings_can_be_null=True)


def _natural_key(path: Path) -> list[object]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.stem)]


def _read_table(path: Path) -> pa.Table:
    table = _read_csv(path, _READ)
    # Columns that look like integers are read again as floats: as int64, "-0" would lose its sign.
    ints = {f.name: pa.float64() for f in table.schema if pa.types.is_integer(f.type)}
    if ints:
        table = _read_csv(path, pacsv.ConvertOptions(null_values=[""], strings_can_be_null=True,
                                                     column_types=ints))
    return table


def _read_csv(path: Path, options: pacsv.ConvertOptions) -> pa.Table:
    try:
        return pacsv.read_csv(path, convert_options=options)
    except (pa.ArrowInvalid, OSError, UnicodeDecodeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise TraceSetError(f"{path}: unreadable CSV ({reason})") from None


def read(directory: Path) -> TraceSet:
    files = sorted(directory.glob("*.csv"), key=_natural_key)
    if not files:
        raise TraceSetError(f"{directory}: the trace set is empty (no *.csv files)")
    signals: list[str] | None = None
    times, blocks, lengths = [], [], []
    for path in files:
        table = _read_table(path)
        names = [n for n in table.column_names if n != TIME]
        if len(set(table.column_names)) != len(table.column_names):
            raise TraceSetError(f"{path}: duplicate column names {table.column_names}")
        if signals is None:
            signals = names
        else:
            _check_same_signals(signals, names, str(path))
        times.append(float_column(table, TIME, str(path)))
        block = np.empty((table.num_rows, len(signals)))
        for j, name in enumerate(signals):
            block[:, j] = float_column(table, name, str(path))
        blocks.append(block)
        lengths.append(table.num_rows)
    return TraceSet(
        signals=tuple(signals or ()),
        time=np.concatenate(times),
        values=np.concatenate(blocks),
        offsets=np.concatenate([[0], np.cumsum(lengths)]),
        run_ids=tuple(p.stem for p in files),
        metadata=_read_metadata(directory),
        source=str(directory),
        run_sources=tuple(str(p) for p in files),
    )


def _read_metadata(directory: Path) -> dict:
    path = directory / METADATA_FILE
    if not path.exists():
        return {}
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise TraceSetError(f"{path}: unreadable metadata ({exc})") from None
    if not isinstance(meta, dict):
        raise TraceSetError(f"{path}: metadata must be a JSON object")
    return meta


def write(traces: TraceSet, directory: Path) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    for old in directory.glob("*.csv"):
        old.unlink()
    options = pacsv.WriteOptions(quoting_header="none")
    names = [TIME, *traces.signals]
    for i, run_id in enumerate(traces.run_ids):
        if not run_id or "/" in run_id or "\\" in run_id or run_id.startswith("."):
            raise TraceSetError(f"{traces.source}: run id {run_id!r} cannot be a file name")
        lo, hi = traces.offsets[i], traces.offsets[i + 1]
        columns = [traces.time[lo:hi], *(traces.values[lo:hi].T)]
        table = pa.table(dict(zip(names, columns, strict=True)))
        pacsv.write_csv(table, directory / f"{run_id}.csv", write_options=options)
    (directory / METADATA_FILE).write_text(json.dumps(dict(traces.metadata), indent=1,
                                                      sort_keys=True) + "\n")
    return directory
