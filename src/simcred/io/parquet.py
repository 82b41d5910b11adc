"""A trace set as one Parquet file: columns ``run``, ``t`` and the signals.

Rows of a run need not be contiguous; runs are ordered by first appearance and rows keep their
order within a run. Metadata lives in the schema metadata under the key ``simcred``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from simcred._json import loads
from simcred.errors import TraceSetError
from simcred.io._columns import MAX_COLUMNS, float_column, parquet_table
from simcred.io._paths import local
from simcred.traces import TIME, TraceSet, handed_over

RUN = "run"
METADATA_KEY = b"simcred"


def read(path: Path) -> TraceSet:
    traces = _read_row_groups(path)
    if traces is not None:
        return traces
    try:
        table = parquet_table(path)  # the width checked before any value is read
    except (pa.ArrowException, OSError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise TraceSetError(f"{path}: unreadable Parquet ({reason})") from None
    traces = from_table(table, path)
    del table
    pa.default_memory_pool().release_unused()  # else Arrow's pool keeps the table's pages
    return traces


def from_table(table: pa.Table, path: Path | str) -> TraceSet:
    """The trace set of a table in this layout (``path`` names it in errors and is its source;
    a partition of a data set, :mod:`simcred.io.dataset`, is read through here too)."""
    if table.num_rows == 0:
        raise TraceSetError(f"{path}: the trace set is empty (no rows)")
    if RUN not in table.column_names:
        raise TraceSetError(f"{path}: no column '{RUN}' naming the run of each row")
    runs = table.column(RUN)
    if runs.null_count:
        raise TraceSetError(f"{path}: column '{RUN}' has missing values")
    label_type = runs.type.value_type if pa.types.is_dictionary(runs.type) else runs.type
    if not (pa.types.is_string(label_type) or pa.types.is_large_string(label_type)
            or pa.types.is_integer(label_type)):
        raise TraceSetError(f"{path}: column '{RUN}' must hold text or integer run ids, not "
                            f"{runs.type}")
    grouped = _grouped_runs(runs)
    if grouped is None:
        ids, run_of_row = _run_codes(runs, path)
        rows = np.argsort(run_of_row, kind="stable")
        offsets = np.r_[0, np.cumsum(np.bincount(run_of_row, minlength=len(ids)))]
        del run_of_row
    else:  # rows grouped by run (as simcred writes them): no per-row codes, no reordering
        (ids, offsets), rows = grouped, slice(None)
    del runs
    table = table.drop_columns([RUN])
    signals = [n for n in table.column_names if n != TIME]
    values, table = _signal_values(table, signals, rows, path)
    time = float_column(table, TIME, str(path))[rows]
    time = time.copy() if grouped else time  # not a view into Arrow's buffer
    return TraceSet(
        signals=tuple(signals),
        time=handed_over(time),
        values=handed_over(values),
        offsets=offsets,
        run_ids=ids,
        metadata=_metadata(table, path),
        source=str(path),
    )


def _read_row_groups(path: Path) -> TraceSet | None:
    """The trace set of a file whose rows are grouped by run (as :func:`write` stores them),
    read row group by row group into its arrays: the whole table is never held in Arrow (it was
    twice the arrays' bytes at its peak). None for any other file, and wherever something is
    wrong with it: the whole-table reading then gives the same result or the same error."""
    grouped = GroupedRuns.open(path)
    if grouped is None:
        return None
    time, values = np.empty(grouped.n_rows), np.empty((grouped.n_rows, len(grouped.signals)))

    def place(lo: int, table: pa.Table) -> None:
        time[lo:lo + table.num_rows] = grouped.column(table, TIME)
        grouped.place(table, values, lo)

    try:
        grouped.each_row_group(place)
    except (pa.ArrowException, OSError, TraceSetError):
        return None
    return TraceSet(signals=grouped.signals, time=handed_over(time), values=handed_over(values),
                    offsets=grouped.offsets, run_ids=grouped.run_ids, metadata=grouped.metadata,
                    source=str(path))


@dataclass(frozen=True, slots=True, eq=False)
class GroupedRuns:
    """A Parquet file whose rows are grouped by run (as :func:`write` stores them): its runs and
    signals, and its rows row group by row group (one row group held at a time, read on the
    calling thread: Arrow's reading threads kept their freed pages, 30 MB a file)."""

    path: Path
    file: pq.ParquetFile
    signals: tuple[str, ...]
    run_ids: tuple[str, ...]
    offsets: np.ndarray
    metadata: dict

    @classmethod
    def open(cls, path: Path) -> GroupedRuns | None:
        """None for any other file, or wherever something is wrong with it (the whole-table
        reading then gives the same result or the same error)."""
        try:
            file = pq.ParquetFile(local(path))
            names = file.schema_arrow.names
            if len(names) > MAX_COLUMNS or len(set(names)) != len(names) \
                    or RUN not in names or TIME not in names or file.metadata.num_rows == 0:
                return None
            runs = file.read(columns=[RUN], use_threads=False).column(RUN)
            if runs.null_count or not pa.types.is_dictionary(runs.type) or not (
                    pa.types.is_string(runs.type.value_type)
                    or pa.types.is_large_string(runs.type.value_type)
                    or pa.types.is_integer(runs.type.value_type)):
                return None
            grouped = _grouped_runs(runs)
            del runs
            if grouped is None or grouped[1][-1] != file.metadata.num_rows:
                return None
            signals = tuple(n for n in names if n not in (RUN, TIME))
            return cls(path, file, signals, *grouped, _metadata(file.schema_arrow, path))
        except (pa.ArrowException, OSError, TraceSetError):
            return None

    @property
    def n_rows(self) -> int:
        return int(self.offsets[-1])

    def each_row_group(self, use: Callable[[int, pa.Table], None],
                       columns: list[str] | None = None) -> None:
        """``use(first row, table)`` of every row group (``columns`` of it), each released before
        the next is read; TraceSetError where the row groups do not hold the file's rows."""
        position, pool = 0, pa.default_memory_pool()
        for group in range(self.file.num_row_groups):
            table = self.file.read_row_group(group, columns=columns, use_threads=False)
            if position + table.num_rows > self.n_rows:
                raise TraceSetError(f"{self.path}: row groups hold more rows than the file")
            use(position, table)
            position += table.num_rows
            del table
            pool.release_unused()
        if position != self.n_rows:
            raise TraceSetError(f"{self.path}: row groups hold fewer rows than the file")

    def place(self, table: pa.Table, values: np.ndarray, lo: int) -> None:
        """The signals of a row group into ``values`` from row ``lo``."""
        for j, name in enumerate(self.signals):
            values[lo:lo + table.num_rows, j] = self.column(table, name)

    def column(self, table: pa.Table, name: str) -> np.ndarray:
        """Column ``name`` of a row group as float64 (the checks of the whole-table reading)."""
        return float_column(table, name, str(self.path))


def _grouped_runs(runs: pa.ChunkedArray) -> tuple[tuple[str, ...], np.ndarray] | None:
    """Run labels and offsets read off a dictionary column whose rows are grouped by run with
    distinct labels (as :func:`write` stores them; a run may span row groups); None for any
    other column, which :func:`_run_codes` reads."""
    if not pa.types.is_dictionary(runs.type):
        return None
    labels: list[str] = []
    starts: list[np.ndarray] = []
    position = 0
    for chunk in runs.chunks:  # one per row group, each with its own dictionary
        index = chunk.indices.to_numpy(zero_copy_only=False)
        if len(index) == 0:
            continue
        first = np.r_[0, np.flatnonzero(index[1:] != index[:-1]) + 1]
        names = [str(v) for v in chunk.dictionary.take(pa.array(index[first])).to_pylist()]
        if labels and names[0] == labels[-1]:  # the last run goes on in this row group
            names, first = names[1:], first[1:]
        labels += names
        starts.append(first + position)
        position += len(index)
    if len(set(labels)) != len(labels):
        return None  # a run in two blocks, or labels equal as text: the general reading
    return tuple(labels), np.r_[np.concatenate(starts), position].astype(np.int64)


def _run_codes(runs: pa.ChunkedArray, path: Path) -> tuple[tuple[str, ...], np.ndarray]:
    """Run labels (in order of first appearance) and each row's run index.

    A stored dictionary is decoded by value first (each chunk may carry its own dictionary, with
    entries in any order or unused); re-encoded in Arrow, so only the distinct labels ever become
    Python strings (not one per row). Labels that are equal as text (e.g. ``1`` and ``"1"``
    cannot occur in one typed column) name one run.
    """
    if pa.types.is_dictionary(runs.type):  # decoded by value: chunks may hold other, unordered
        runs = runs.cast(runs.type.value_type)  # or partly unused dictionaries
    encoded = pc.dictionary_encode(runs.combine_chunks())  # codes in order of first appearance
    labels = [str(v) for v in encoded.dictionary.to_pylist()]
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    if len(set(labels)) != len(labels):
        raise TraceSetError(f"{path}: column '{RUN}' has labels that differ only in type")
    return tuple(labels), codes


#: Converted columns are dropped from the Arrow table (their pages given back) every this many
#: bytes: a tall table's memory is freed column by column, while a wide table is not rebuilt
#: once per column (which made reading 10,000 columns take quadratic time: 5 s).
RELEASE_BYTES = 64 << 20


def _signal_values(table: pa.Table, signals: list[str], rows, path: Path | str
                   ) -> tuple[np.ndarray, pa.Table]:
    """The ``signals`` columns as one float array (rows taken by ``rows``), and ``table``
    without them."""
    pool = pa.default_memory_pool()
    values = np.empty((table.num_rows, len(signals)))
    converted: list[str] = []
    for j, name in enumerate(signals):
        values[:, j] = float_column(table, name, str(path))[rows]
        converted.append(name)
        if len(converted) * 8 * table.num_rows >= RELEASE_BYTES or j == len(signals) - 1:
            done = set(converted)  # Arrow's drop_columns looks up each name: quadratic
            table = table.select([i for i, n in enumerate(table.column_names) if n not in done])
            converted = []
            pool.release_unused()
    return values, table


def _metadata(table: pa.Table | pa.Schema, path: Path) -> dict:
    schema = table if isinstance(table, pa.Schema) else table.schema
    raw = (schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        return {}
    return loads(raw, f"{path}: schema metadata '{METADATA_KEY.decode()}'", TraceSetError)


def write(traces: TraceSet, path: Path) -> Path:
    table = to_table(traces, where=str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, local(path))
    return path


def to_table(traces: TraceSet, *, where: str) -> pa.Table:
    """The Arrow table of the file: ``run`` (dictionary-encoded), ``t``, the signals, and the
    metadata as JSON in the schema metadata. ``where`` names the destination in errors."""
    if RUN in traces.signals:
        raise TraceSetError(f"{where}: a signal is named '{RUN}', which in Parquet is the column "
                            "naming the run of each row; rename it or write a CSV directory")
    columns = {
        RUN: pa.DictionaryArray.from_arrays(  # integer codes per row, each label stored once
            np.repeat(np.arange(traces.n_runs, dtype=np.int32), traces.lengths),
            pa.array(traces.run_ids, type=pa.string())),
        TIME: traces.time,
    }
    columns.update({s: traces.values[:, j] for j, s in enumerate(traces.signals)})
    table = pa.table(columns)
    meta = json.dumps(dict(traces.metadata), sort_keys=True).encode()
    return table.replace_schema_metadata({METADATA_KEY: meta})
