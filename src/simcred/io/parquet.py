"""A trace set as one Parquet file: columns ``run``, ``t`` and the signals.

Rows of a run need not be contiguous; runs are ordered by first appearance and rows keep their
order within a run. Metadata lives in the schema metadata under the key ``simcred``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from simcred.errors import TraceSetError
from simcred.io._columns import float_column
from simcred.traces import TIME, TraceSet

RUN = "run"
METADATA_KEY = b"simcred"


def read(path: Path) -> TraceSet:
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise TraceSetError(f"{path}: unreadable Parquet ({reason})") from None
    if table.num_rows == 0:
        raise TraceSetError(f"{path}: the trace set is empty (no rows)")
    if RUN not in table.column_names:
        raise TraceSetError(f"{path}: no column '{RUN}' naming the run of each row")
    runs = table.column(RUN)
    if runs.null_count:
        raise TraceSetError(f"{path}: column '{RUN}' has missing values")
    run_labels = np.asarray(runs.to_pylist(), dtype=object).astype(str)
    ids, first, inverse = np.unique(run_labels, return_index=True, return_inverse=True)
    order_of_run = np.argsort(np.argsort(first, kind="stable"), kind="stable")
    rows = np.argsort(order_of_run[inverse], kind="stable")
    signals = [n for n in table.column_names if n not in (RUN, TIME)]
    values = np.empty((table.num_rows, len(signals)))
    for j, name in enumerate(signals):
        values[:, j] = float_column(table, name, str(path))[rows]
    lengths = np.bincount(order_of_run[inverse], minlength=len(ids))
    return TraceSet(
        signals=tuple(signals),
        time=float_column(table, TIME, str(path))[rows],
        values=values,
        offsets=np.concatenate([[0], np.cumsum(lengths)]),
        run_ids=tuple(ids[np.argsort(first, kind="stable")]),
        metadata=_metadata(table, path),
        source=str(path),
    )


def _metadata(table: pa.Table, path: Path) -> dict:
    raw = (table.schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        return {}
    try:
        return json.loads(raw)
    except ValueError:
        key = METADATA_KEY.decode()
        raise TraceSetError(f"{path}: schema metadata '{key}' is not JSON") from None


def write(traces: TraceSet, path: Path) -> Path:
    if RUN in traces.signals:
        raise TraceSetError(f"{path}: a signal is named '{RUN}', which in Parquet is the column "
                            "naming the run of each row; rename it or write a CSV directory")
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = {
        RUN: pa.array(np.repeat(np.asarray(traces.run_ids, dtype=object), traces.lengths),
                      type=pa.string()),
        TIME: traces.time,
    }
    columns.update({s: traces.values[:, j] for j, s in enumerate(traces.signals)})
    table = pa.table(columns)
    meta = json.dumps(dict(traces.metadata), sort_keys=True).encode()
    table = table.replace_schema_metadata({METADATA_KEY: meta})
    pq.write_table(table, path)
    return path
