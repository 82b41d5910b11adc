"""Turning an Arrow table into validated float columns, shared by the CSV and Parquet readers."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from simcred.errors import TraceSetError


def float_column(table: pa.Table, name: str, where: str) -> np.ndarray:
    """Column ``name`` as float64; a one-line error naming ``where`` if missing, empty or text."""
    if name not in table.column_names:
        raise TraceSetError(f"{where}: no column '{name}' (columns are: "
                            f"{', '.join(table.column_names)})")
    column = table.column(name)
    if pa.types.is_null(column.type) and len(column) == 0:  # a CSV file with a header only
        return np.empty(0)
    numeric = pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
    if not (numeric or pa.types.is_null(column.type)):  # null type: every value is missing
        raise TraceSetError(f"{where}: column '{name}' is not numeric (type {column.type})")
    if column.null_count:
        row = int(np.flatnonzero(column.is_null().to_numpy(zero_copy_only=False))[0]) + 1
        raise TraceSetError(f"{where}: column '{name}', row {row}: value is missing")
    return column.to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
