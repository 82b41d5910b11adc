"""Trace sets as in-memory tables: Arrow, pandas and polars (for notebooks).

A table is the long format of :mod:`simcred.io.longformat`: a run column, a time column,
optionally an object column, and value columns; :func:`read` takes the same rules and options
(under shorter names: ``run=``, ``time=``, ``object=``). :func:`write` gives the table of a
Parquet file (:func:`simcred.io.parquet.to_table`): ``run`` (dictionary-encoded: categorical in
pandas and polars), ``t`` and the signals, so ``read(write(ts))`` is ``ts`` bit for bit.

Metadata (units, provenance, per-run facts) travels in the Arrow schema metadata ``simcred``
(JSON), in pandas as ``DataFrame.attrs["simcred"]``; polars frames carry none, so
``metadata=`` gives it.

Copies: ``t`` goes to Arrow without a copy (a read-only view of the trace set's column); the
signals are copied once, since the trace set stores rows (``values[:, j]`` is strided).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import pyarrow as pa

from simcred.errors import OptionError, TraceSetError
from simcred.io.longformat import from_table
from simcred.io.parquet import RUN, to_table
from simcred.traces import TIME, TableHandlers, TraceSet, register_tables

KINDS = ("arrow", "pandas", "polars")
ATTRS_KEY = "simcred"  # pandas DataFrame.attrs key of the metadata


def read(table: Any, kind: str = "arrow", *, run: str | None = RUN, time: str = TIME,
         object: str | None = None, signals: Sequence[str] | None = None,
         objects_as: str = "signals", missing: str = "error", object_prefix: str | None = None,
         time_scale: float = 1.0, metadata: Mapping[str, Any] | None = None,
         source: str | None = None) -> TraceSet:
    """A trace set from a long-format table (``kind``: an Arrow, pandas or polars table).

    ``run=None``: the table is one run, named ``"0"``. ``metadata`` replaces the metadata the
    table carries (Arrow schema metadata, pandas ``attrs``); ``source`` names the table in errors
    (default ``<pandas>`` etc.).

    >>> import pyarrow as pa
    >>> table = pa.table({"trip": ["a", "a", "b", "b"], "t": [0.0, 0.1, 0.0, 0.1],
    ...                   "v": [1.0, 1.5, 2.0, 2.5]})
    >>> ts = read(table, run="trip")
    >>> ts.run_ids, ts.signals, ts.column("v").tolist()
    (('a', 'b'), ('v',), [1.0, 1.5, 2.0, 2.5])
    """
    where = source or f"<{kind}>"
    arrow = _as_arrow(table, kind, where)
    traces = from_table(arrow, where=where, default_run="0", run_column=run, time_column=time,
                        object_column=object, signals=signals, objects_as=objects_as,
                        missing=missing, object_prefix=object_prefix, time_scale=time_scale)
    if metadata is None and kind == "pandas":
        metadata = table.attrs.get(ATTRS_KEY)
    if metadata is not None:
        if not isinstance(metadata, Mapping):
            raise OptionError(f"metadata must be a mapping, not {type(metadata).__name__}")
        traces = replace(traces, metadata=copy.deepcopy(dict(metadata)))
    return traces


def write(traces: TraceSet, kind: str = "arrow") -> Any:
    """The table of ``traces``: ``run``, ``t``, signals (see the module notes)."""
    _check_kind(kind)
    table = to_table(traces, where=traces.source)
    if kind == "pandas":
        frame = table.to_pandas()
        frame.attrs[ATTRS_KEY] = copy.deepcopy(dict(traces.metadata))
        return frame
    if kind == "polars":
        pl = _polars()
        if any("\0" in name for name in table.column_names):  # polars panics on them
            raise TraceSetError(f"{traces.source}: a signal name holds a NUL character, which "
                                "polars cannot take in a column name")
        return pl.from_arrow(table)
    return table


def _polars():
    try:
        import polars
    except ImportError:
        raise OptionError("polars tables need polars (pip install 'simcred[polars]')") from None
    return polars


def _check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise OptionError(f"table kind must be one of {', '.join(KINDS)}, got {kind!r}")


def _as_arrow(table: Any, kind: str, where: str) -> pa.Table:
    """``table`` as an Arrow table; a one-line error if it is not a table of ``kind``."""
    _check_kind(kind)
    if kind == "pandas":
        import pandas as pd

        if not isinstance(table, pd.DataFrame):
            raise TraceSetError(f"{where}: expected a pandas DataFrame, got "
                                f"{type(table).__name__}")
        try:
            return pa.Table.from_pandas(table, preserve_index=False)
        except (pa.ArrowException, TypeError, ValueError) as exc:
            raise TraceSetError(f"{where}: not convertible to Arrow "
                                f"({str(exc).splitlines()[0]})") from None
    if kind == "polars":
        pl = _polars()
        if not isinstance(table, pl.DataFrame):
            raise TraceSetError(f"{where}: expected a polars DataFrame, got "
                                f"{type(table).__name__}")
        return table.to_arrow()
    if not isinstance(table, pa.Table):
        raise TraceSetError(f"{where}: expected a pyarrow Table, got {type(table).__name__}")
    return table


register_tables(TableHandlers(read=read, write=write))
