"""A trace set as a directory of CSV files, one per run (the format of Neurohr et al. 2023 [1]).

Each file has a header row of signal names including the time column ``t``; the run id is the file
stem. Files are read in natural order (``run_2`` before ``run_10``); the suffix ``.csv`` is matched
without regard to case, and an entry that is not a regular file (a directory, a FIFO) is an error
rather than something to wait on. A header may name at most ``MAX_COLUMNS`` columns. An optional
``traceset.json`` beside them holds the metadata. Floats are written in their shortest round-trip
form, so write → read is exact.
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from simcred._json import read_json
from simcred.errors import TraceSetError
from simcred.io._columns import (
    MAX_COLUMNS,
    check_csv_header,
    check_table,
    check_width,
    float_column,
)
from simcred.traces import TIME, TraceSet, _check_same_signals, handed_over

METADATA_FILE = "traceset.json"
NAME_MAX = 255  # bytes of a file name on common file systems (ext4, XFS, APFS, NTFS in UTF-16)
_READ = pacsv.ConvertOptions(null_values=[""], strings_can_be_null=True)


def _natural_key(path: Path) -> list[object]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.stem)]


def _run_files(directory: Path) -> list[Path]:
    """The run files of a directory: ``*.csv`` in any case, regular files only."""
    files = sorted((p for p in directory.iterdir() if p.suffix.lower() == ".csv"),
                   key=_natural_key)
    stems: dict[str, Path] = {}
    for path in files:
        if not stat.S_ISREG(path.stat().st_mode):
            raise TraceSetError(f"{path}: not a regular file")
        if path.stem in stems:
            raise TraceSetError(f"{path}: run '{path.stem}' also in {stems[path.stem].name}")
        stems[path.stem] = path
    return files


def _check_header(path: Path) -> None:
    """Refuse undecodable or oversized headers before Arrow parses the file."""
    with path.open("rb") as stream:
        header = stream.readline(64 * MAX_COLUMNS)
    try:
        header.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise TraceSetError(f"{path}: header is not UTF-8 (byte {exc.start})") from None
    check_width(header.count(b",") + 1, str(path))


def _read_table(path: Path) -> pa.Table:
    _check_header(path)
    table = check_table(_read_csv(path, _READ), str(path))  # a quoted newline hides commas
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
    files = _run_files(directory)
    if not files:
        raise TraceSetError(f"{directory}: the trace set is empty (no *.csv files)")
    signals: list[str] | None = None
    times, blocks, lengths = [], [], []
    for path in files:
        table = _read_table(path)
        names = [n for n in table.column_names if n != TIME]
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
        time=handed_over(np.concatenate(times)),
        values=handed_over(np.concatenate(blocks)),
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
    meta = read_json(path, TraceSetError)
    if not isinstance(meta, dict):
        raise TraceSetError(f"{path}: metadata must be a JSON object")
    return meta


def write(traces: TraceSet, directory: Path) -> Path:
    for run_id in traces.run_ids:  # before anything in the directory changes
        if (not run_id or run_id.startswith(".") or any(c in run_id for c in "/\\\x00")
                or not run_id.isprintable()):
            raise TraceSetError(f"{traces.source}: run id {run_id!r} cannot be a file name")
        if len(os.fsencode(run_id)) + len(".csv") > NAME_MAX:
            raise TraceSetError(f"{traces.source}: run id {run_id[:40]!r}... is longer than a "
                                f"file name may be ({NAME_MAX} bytes with .csv): write Parquet")
    check_csv_header(traces.signals, traces.source)
    directory.mkdir(parents=True, exist_ok=True)
    for old in directory.glob("*.csv"):
        old.unlink()
    options = pacsv.WriteOptions(quoting_header="none")
    names = [TIME, *traces.signals]
    for i, run_id in enumerate(traces.run_ids):
        lo, hi = traces.offsets[i], traces.offsets[i + 1]
        columns = [traces.time[lo:hi], *(traces.values[lo:hi].T)]
        table = pa.table(dict(zip(names, columns, strict=True)))
        pacsv.write_csv(table, directory / f"{run_id}.csv", write_options=options)
    (directory / METADATA_FILE).write_text(json.dumps(dict(traces.metadata), indent=1,
                                                      sort_keys=True) + "\n")
    return directory
