"""Reading and writing trace sets: a directory of CSV files (one per run) or one Parquet file."""

from __future__ import annotations

from pathlib import Path

from simcred.errors import TraceSetError
from simcred.io import csvdir, parquet
from simcred.traces import FileHandlers, TraceSet, register_files

PARQUET_SUFFIXES = (".parquet", ".pq")


def read_traceset(path: str | Path) -> TraceSet:
    """Read a trace set: a directory is a CSV directory, a ``.parquet``/``.pq`` file is Parquet."""
    path = Path(path)
    if path.is_dir():
        return csvdir.read(path)
    if path.suffix.lower() in PARQUET_SUFFIXES and path.is_file():
        return parquet.read(path)
    if not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    raise TraceSetError(f"{path}: not a trace set (expected a directory of CSV files or a "
                        f"{'/'.join(PARQUET_SUFFIXES)} file)")


def write_traceset(traces: TraceSet, path: str | Path) -> Path:
    """Write ``traces``: Parquet for a ``.parquet``/``.pq`` suffix, else a CSV directory."""
    path = Path(path)
    if path.suffix.lower() in PARQUET_SUFFIXES:
        return parquet.write(traces, path)
    return csvdir.write(traces, path)


register_files(FileHandlers(read=read_traceset, write=write_traceset))

__all__ = ["read_traceset", "write_traceset"]
