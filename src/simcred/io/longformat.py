"""A trace set as one long-format table: a row per (run, time[, object]) in a CSV or Parquet file.

Logger exports, highD-style track files and SUMO FCD exported to CSV/Parquet are long tables: a
column naming the run, one naming the time, optionally one naming the object (vehicle id, role),
and value columns. The user names those columns; everything else numeric becomes a signal.

Rules (also in ``docs/formats.md``)
-----------------------------------
* **Runs**: by first appearance of the run label; without a run column the file is one run named
  after the file stem. Rows need not be sorted: each (run, object) is ordered by time.
* **Objects** become dotted signal names ``<object>.<column>``; a label that is an integer
  (``12``) becomes ``obj12`` (``object_prefix`` overrides this: every label gets that prefix).
  With ``objects_as="runs"`` every (run, object) is a run of its own (id ``<run>.<object>``, or
  ``<object>`` without a run column) with plain signal names.
* **Missing values**: a column that is missing (empty) in *every* row of an object is not a signal
  of that object (objects may carry different columns); missing in *some* rows is an error, or,
  with ``dropouts="drop"``, the row is a dropout: removed, and counted per (run, object) label in
  the metadata (``dropouts``). NaN and infinite values count as missing then.
* **Missing rows**: with ``missing="error"`` (default) every object of a run must have a row at
  every time step of that run; ``missing="intersect"`` keeps the time steps where all objects of
  the run have a row (documented data loss, counted in the metadata).
* **Time** is the time column times ``time_scale`` (seconds per unit: 0.04 for 25 Hz frame
  numbers, 0.001 for milliseconds). A CSV file's delimiter is ``,``, ``;`` or tab, whichever
  its header line has most of.
* Two rows for the same (run, object, time), non-finite values, text in a value column named in
  ``signals``: one-line errors naming the file, row (1-based, header excluded), column and label.
  Text columns not named in ``signals`` are skipped and listed in the metadata.

This module reads files into records (and drops dropouts) and writes trace sets;
:mod:`simcred.io.longformat_records` assembles records into runs (shared with SUMO FCD, OSI and
CommonRoad).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import (
    check_csv_header,
    check_table,
    float_column,
    parquet_table,
)
from simcred.io._paths import local
from simcred.io.longformat_records import (
    MISSING,
    OBJECTS_AS,
    Records,
    check_choice,
    object_name,
    to_traceset,
)
from simcred.traces import TIME, TraceSet

__all__ = [  # the face of the long format; the records and their assembly are re-exported
    "DROPOUTS",
    "METADATA_KEY",
    "MISSING",
    "OBJECTS_AS",
    "PARQUET_SUFFIXES",
    "Records",
    "csv_delimiter",
    "from_table",
    "object_name",
    "read",
    "split_signal",
    "to_table",
    "to_traceset",
    "write",
]

DROPOUTS = ("error", "drop")
PARQUET_SUFFIXES = (".parquet", ".pq")
METADATA_KEY = b"simcred"


# -- files -> records ------------------------------------------------------------------------------


def _read_table(path: Path, keys: Sequence[str]) -> pa.Table:
    if path.suffix.lower() in PARQUET_SUFFIXES:
        try:
            return parquet_table(path)
        except (pa.ArrowException, OSError) as exc:
            raise TraceSetError(f"{path}: unreadable Parquet ({_first_line(exc)})") from None
    text = {k: pa.string() for k in keys}
    delimiter = csv_delimiter(path)
    table = check_table(_read_csv(path, text, delimiter), str(path))
    # integer-looking value columns are read again as floats: as int64, "-0" would lose its sign
    floats = {f.name: pa.float64() for f in table.schema
              if pa.types.is_integer(f.type) and f.name not in text}
    return _read_csv(path, {**text, **floats}, delimiter) if floats else table


def csv_delimiter(path: Path) -> str:
    """The delimiter of a CSV file: whichever of ``,`` ``;`` tab its header line has most of.

    SUMO's ``xml2csv.py`` writes ``;`` by default, spreadsheet exports often ``;`` or tabs.
    """
    try:
        with open(path, "rb") as stream:
            header = stream.readline()
    except OSError as exc:
        raise TraceSetError(f"{path}: unreadable CSV ({_first_line(exc)})") from None
    counts = {d: header.count(d.encode()) for d in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _read_csv(path: Path, types: Mapping[str, pa.DataType], delimiter: str) -> pa.Table:
    options = pacsv.ConvertOptions(null_values=[""], strings_can_be_null=True,
                                   column_types=dict(types))
    try:
        return pacsv.read_csv(path, parse_options=pacsv.ParseOptions(delimiter=delimiter),
                              convert_options=options)
    except (pa.ArrowInvalid, OSError, UnicodeDecodeError) as exc:
        raise TraceSetError(f"{path}: unreadable CSV ({_first_line(exc)})") from None


def _first_line(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def _labels(table: pa.Table, name: str | None, where: str) -> pa.Array | None:
    """The key column ``name`` as an Arrow string array (integers become their decimal text)."""
    if name is None:
        return None
    _require(table, name, where)
    column = table.column(name)
    if column.null_count:
        row = int(np.flatnonzero(column.is_null().to_numpy(zero_copy_only=False))[0]) + 1
        raise TraceSetError(f"{where}: column '{name}', row {row}: value is missing")
    try:
        return pc.cast(column.combine_chunks(), pa.string())
    except pa.ArrowException:
        raise TraceSetError(f"{where}: column '{name}' (type {column.type}) cannot name runs "
                            "or objects") from None


def _require(table: pa.Table, name: str, where: str) -> None:
    if name not in table.column_names:
        raise TraceSetError(f"{where}: no column '{name}' (columns are: "
                            f"{', '.join(table.column_names)})")


def _value_columns(table: pa.Table, keys: Sequence[str], signals: Sequence[str] | None,
                   where: str) -> tuple[dict, list[str]]:
    """The value columns as (values, present) pairs, and the text columns skipped."""
    if signals is not None:
        for name in signals:
            _require(table, name, where)
            if name in keys:
                raise OptionError(f"signals: '{name}' is a run, time or object column")
    names = list(signals) if signals is not None else [n for n in table.column_names
                                                        if n not in keys]
    fields, skipped = {}, []
    for name in names:
        column = table.column(name)
        numeric = (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
                   or pa.types.is_null(column.type))
        if not numeric:
            if signals is not None:
                raise TraceSetError(f"{where}: column '{name}' is not numeric (type "
                                    f"{column.type})")
            skipped.append(name)
            continue
        present = ~column.is_null().to_numpy(zero_copy_only=False)
        values = column.fill_null(0).to_numpy(zero_copy_only=False) if column.null_count else \
            column.to_numpy(zero_copy_only=False)
        fields[name] = (np.asarray(values, dtype=np.float64), np.asarray(present, dtype=bool))
    if not fields:
        raise TraceSetError(f"{where}: no numeric value columns besides the run, time and "
                            "object columns")
    return fields, skipped


def read(path: str | Path, *, run_column: str | None = None, time_column: str = TIME,
         object_column: str | None = None, signals: Sequence[str] | None = None,
         objects_as: str = "signals", missing: str = "error",
         object_prefix: str | None = None, time_scale: float = 1.0,
         dropouts: str = "error") -> TraceSet:
    """Read one long-format CSV or Parquet file (see the module docstring for the rules).

    Parameters
    ----------
    path : path
        A ``.csv`` file, or a ``.parquet``/``.pq`` file.
    run_column, time_column, object_column : str
        Names of the columns holding the run label, the time in seconds and the object label.
        Without a run column the file is one run; without an object column every row is one
        time step of its run and the value columns are the signals.
    signals : sequence of str, optional
        Value columns to keep (default: every numeric column that is not a key).
    objects_as : {"signals", "runs"}
        Objects as dotted signal names of one run, or each object a run of its own.
    missing : {"error", "intersect"}
        What a missing row of an object means (see the rules).
    object_prefix : str, optional
        Prefix of every object name (default: ``obj`` before integer labels only).
    time_scale : float, default: 1
        Seconds per unit of the time column: 0.04 for frame numbers at 25 Hz (highD), 0.001
        for milliseconds.
    dropouts : {"error", "drop"}
        What a missing or non-finite value in some rows means: an error naming the row, or a
        dropout: the row is removed and counted in ``metadata["dropouts"]`` (``{label: rows}``,
        label ``<run>.<object>``, ``<object>`` or ``<run>``). Needs ``signals``, so that only the
        named columns decide.
    """
    path = Path(path)
    keys = _read_iv(run_column, time_column, object_column, signals, time_scale, dropouts)
    table = _read_table(path, keys)
    return from_table(table, where=str(path), default_run=path.stem, run_column=run_column,
                      time_column=time_column, object_column=object_column, signals=signals,
                      objects_as=objects_as, missing=missing, object_prefix=object_prefix,
                      time_scale=time_scale, dropouts=dropouts)


def from_table(table: pa.Table, *, where: str, default_run: str, run_column: str | None = None,
               time_column: str = TIME, object_column: str | None = None,
               signals: Sequence[str] | None = None, objects_as: str = "signals",
               missing: str = "error", object_prefix: str | None = None,
               time_scale: float = 1.0, dropouts: str = "error") -> TraceSet:
    """A long-format Arrow table as a trace set (the rules and options of :func:`read`).

    ``where`` names the table in errors; ``default_run`` is the run id without a run column.
    Metadata comes from the schema metadata ``simcred`` (a JSON object) when present.
    """
    keys = _read_iv(run_column, time_column, object_column, signals, time_scale, dropouts)
    if table.num_rows == 0:
        raise TraceSetError(f"{where}: the trace set is empty (no rows)")
    fields, skipped = _value_columns(table, [*keys, time_column], signals, where)
    records = Records(
        where=where,
        time=float_column(table, time_column, where) * float(time_scale),
        runs=_labels(table, run_column, where),
        objects=_labels(table, object_column, where),
        fields=fields,
        default_run=default_run,
    )
    metadata = _stored_metadata(table, where)
    if skipped:
        metadata["skipped_columns"] = skipped
    if dropouts == "drop":
        records, dropped = _without_dropouts(records)
        if dropped:
            metadata["dropouts"] = dropped
    return to_traceset(records, objects_as=objects_as, missing=missing,
                       object_prefix=object_prefix, metadata=metadata, source=where)


def _read_iv(run_column: str | None, time_column: str, object_column: str | None,
             signals: Sequence[str] | None, time_scale: float, dropouts: str) -> list[str]:
    """Check the reading options (before any file is read); return the run/object columns."""
    if not (isinstance(time_scale, int | float) and np.isfinite(time_scale) and time_scale > 0):
        raise OptionError(f"time_scale must be a finite number > 0 (seconds per unit of the "
                          f"time column), got {time_scale!r}")
    check_choice("dropouts", dropouts, DROPOUTS)
    if dropouts == "drop" and signals is None:
        raise OptionError("dropouts='drop' needs signals: the columns whose missing values "
                          "make a row a dropout")
    keys = [k for k in (run_column, object_column) if k is not None]
    if len({*keys, time_column}) != len(keys) + 1:
        raise OptionError("run, time and object columns must be different columns")
    return keys


def _without_dropouts(records: Records) -> tuple[Records, dict[str, int]]:
    """The records without rows that miss a value (or hold a non-finite one), and the rows
    removed per label."""
    bad = np.zeros(len(records.time), dtype=bool)
    for values, present in records.fields.values():
        bad |= ~present | ~np.isfinite(values)
    if not bad.any():
        return records, {}
    keep = ~bad
    parts = [_as_text(lab) for lab in (records.runs, records.objects) if lab is not None]
    labels = (np.array([".".join(p) for p in zip(*parts, strict=True)], dtype=object)
              if parts else np.full(len(bad), records.default_run, dtype=object))
    names, counts = np.unique(labels[bad].astype(str), return_counts=True)
    kept = Records(
        where=records.where, time=records.time[keep],
        runs=None if records.runs is None else _as_text(records.runs)[keep],
        objects=None if records.objects is None else _as_text(records.objects)[keep],
        fields={n: (v[keep], p[keep]) for n, (v, p) in records.fields.items()},
        default_run=records.default_run, row_name=records.row_name)
    return kept, {str(n): int(c) for n, c in zip(names, counts, strict=True)}


def _as_text(labels) -> np.ndarray:
    values = labels.to_pylist() if isinstance(labels, pa.Array) else list(labels)
    return np.array([str(v) for v in values], dtype=object)


def _stored_metadata(table: pa.Table, where: str) -> dict:
    raw = (table.schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        return {}
    try:
        meta = json.loads(raw)
    except ValueError:
        meta = None
    if not isinstance(meta, dict):
        raise TraceSetError(f"{where}: schema metadata 'simcred' is not a JSON object")
    return meta


# -- TraceSet -> file ------------------------------------------------------------------------------


def split_signal(name: str, *, where: str = "",
                 hint: str = "write without an object column") -> tuple[str, str]:
    """``"ego.sensor.x"`` -> ``("ego.sensor", "x")``: the object is all before the last dot."""
    obj, dot, field = name.rpartition(".")
    if not dot or not obj or not field:
        prefix = f"{where}: " if where else ""
        raise TraceSetError(f"{prefix}signal '{name}' is not '<object>.<field>'; {hint}")
    return obj, field


def to_table(traces: TraceSet, *, run_column: str = "run", time_column: str = TIME,
             object_column: str | None = None) -> pa.Table:
    """The long table of ``traces``: rows ordered by run, time and object (signal order)."""
    runs = np.repeat(np.asarray(traces.run_ids, dtype=object), traces.lengths)
    if object_column is None:
        columns = {run_column: pa.array(runs, type=pa.string()), time_column: traces.time}
        for j, name in enumerate(traces.signals):
            columns[name] = traces.values[:, j]
        _check_names([run_column, time_column], traces.signals)
        return pa.table(columns)
    parts = [split_signal(s) for s in traces.signals]
    objects = list(dict.fromkeys(o for o, _ in parts))
    fields = list(dict.fromkeys(f for _, f in parts))
    _check_names([run_column, time_column, object_column], fields)
    n, k = traces.n_rows, len(objects)
    # row i of object k goes to output row i * k + position of the object
    out = {run_column: pa.array(np.repeat(runs, k), type=pa.string()),
           time_column: np.repeat(traces.time, k),
           object_column: pa.array(np.tile(np.asarray(objects, dtype=object), n),
                                   type=pa.string())}
    for field in fields:
        values = np.zeros(n * k)
        present = np.zeros(n * k, dtype=bool)
        for j, (obj, f) in enumerate(parts):
            if f == field:
                slot = objects.index(obj)
                values[slot::k] = traces.values[:, j]
                present[slot::k] = True
        out[field] = pa.array(values, mask=~present)
    return pa.table(out)


def _check_names(keys: Sequence[str], fields: Sequence[str]) -> None:
    if len(set(keys)) != len(keys):
        raise OptionError("run, time and object columns must be different columns")
    clash = sorted(set(keys) & set(fields))
    if clash:
        raise TraceSetError(f"signal or field '{clash[0]}' has the name of a run, time or object "
                            "column; choose other column names")


def write(traces: TraceSet, path: str | Path, *, run_column: str = "run",
          time_column: str = TIME, object_column: str | None = None) -> Path:
    """Write ``traces`` as one long-format CSV or Parquet file (Parquet keeps the metadata)."""
    path = Path(path)
    table = to_table(traces, run_column=run_column, time_column=time_column,
                     object_column=object_column)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() in PARQUET_SUFFIXES:
        meta = json.dumps(dict(traces.metadata), sort_keys=True).encode()
        pq.write_table(table.replace_schema_metadata({METADATA_KEY: meta}), local(path))
    else:
        check_csv_header(table.column_names, traces.source)
        pacsv.write_csv(table, path, write_options=pacsv.WriteOptions(quoting_header="none"))
    return path
