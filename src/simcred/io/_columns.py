"""Turning an Arrow table into validated float columns, shared by the CSV and Parquet readers,
and the column limit every tabular format enforces."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa

from simcred.errors import TraceSetError

#: Columns a trace-set table may have (CSV header, Parquet schema, long CSV): wider tables are
#: refused before their values are read.
MAX_COLUMNS = 10_000


def check_width(count: int, where: str) -> None:
    """One line naming ``where`` if a table has more than :data:`MAX_COLUMNS` columns."""
    if count > MAX_COLUMNS:
        raise TraceSetError(f"{where}: {count} columns, more than {MAX_COLUMNS} (the limit of "
                            "simcred.io._columns.MAX_COLUMNS)")


def parquet_table(path: Path) -> pa.Table:
    """The Parquet file at ``path`` as a table: its width checked on the schema before any value
    is read, each column name once (:func:`check_table`). Arrow's errors are the caller's."""
    import pyarrow.parquet as pq

    from simcred.io._paths import local

    check_width(len(pq.read_schema(local(path))), str(path))
    return check_table(pq.read_table(local(path)), str(path))


def check_signals(count: int, where: str) -> None:
    """One line naming ``where`` if a trace set of ``count`` signals would be wider than
    :data:`MAX_COLUMNS` as a table (its time column and the signals): the limit of the formats
    whose signals are not a file's columns (objects turned into signals, MDF channels, ROS
    fields), checked before the values are put together."""
    check_width(count + 1, where)


def check_csv_header(names: Sequence[str], where: str) -> None:
    """One line for a column name a CSV header cannot hold unquoted (a comma, a quote or a line
    break), before a CSV writer starts."""
    for name in names:
        if any(c in name for c in ',"\r\n'):
            raise TraceSetError(f"{where}: column {name!r} cannot be a CSV header cell (a comma, "
                                "a quote or a line break): write Parquet")


def check_table(table: pa.Table, where: str) -> pa.Table:
    """``table`` if it has at most :data:`MAX_COLUMNS` columns, each name once; else one line."""
    check_width(table.num_columns, where)
    names = table.column_names
    if len(set(names)) != len(names):
        seen: set[str] = set()
        twice = next(n for n in names if n in seen or seen.add(n))
        raise TraceSetError(f"{where}: column '{twice}' appears more than once")
    return table


def float_column(table: pa.Table, name: str, where: str) -> np.ndarray:
    """Column ``name`` as float64; a one-line error naming ``where`` if missing, duplicated,
    empty or text. A dictionary-encoded (categorical) column is decoded by value.

    The name is looked up in the schema's hash index, so reading every column of a wide table
    takes linear time (listing ``table.column_names`` per column made it quadratic).
    """
    index = table.schema.get_field_index(name)
    if index < 0:  # missing or duplicated: the slow path builds the message
        if name in table.column_names:
            raise TraceSetError(f"{where}: column '{name}' appears more than once")
        raise TraceSetError(f"{where}: no column '{name}' (columns are: "
                            f"{', '.join(table.column_names)})")
    column = table.column(index)
    if pa.types.is_dictionary(column.type):  # each chunk may carry its own dictionary
        column = column.cast(column.type.value_type)
    if pa.types.is_null(column.type) and len(column) == 0:  # a CSV file with a header only
        return np.empty(0)
    numeric = pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
    if not (numeric or pa.types.is_null(column.type)):  # null type: every value is missing
        raise TraceSetError(f"{where}: column '{name}' is not numeric (type {column.type})")
    if column.null_count:
        row = int(np.flatnonzero(column.is_null().to_numpy(zero_copy_only=False))[0]) + 1
        raise TraceSetError(f"{where}: column '{name}', row {row}: value is missing")
    return column.to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
