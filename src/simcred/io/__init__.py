"""Reading and writing trace sets in every supported format.

:func:`read` and :func:`write` dispatch on the path (see :mod:`simcred.io.formats`): a CSV
directory, a Parquet file, a long-format CSV/Parquet file, SUMO FCD XML, CommonRoad XML, ASAM OSI,
a highD-family folder, ASAM MDF4, a ROS 2 bag. :func:`read_source` reads those and the data
sets (A9, measurement, OpenACC) by name, :func:`detect_source` names what a path is for a role
(:mod:`simcred.io.sources`). :mod:`simcred.io.frames` turns trace sets into
Arrow, pandas and polars tables and back.
"""

from __future__ import annotations

from pathlib import Path

from simcred.io.formats import FORMATS, PARQUET_SUFFIXES, detect, read, write
from simcred.io.sources import DATASETS, detect_source, read_source
from simcred.traces import FileHandlers, TraceSet, register_files


def read_traceset(path: str | Path, **options) -> TraceSet:
    """Read a trace set in any supported format (the same as :func:`read`)."""
    return read(path, **options)


def write_traceset(traces: TraceSet, path: str | Path, **options) -> Path:
    """Write ``traces``: Parquet for ``.parquet``/``.pq``, long CSV for ``.csv``, OSI for
    ``.osi``/``.mcap``, else a CSV directory (the same as :func:`write`)."""
    return write(traces, path, **options)


# TraceSet.read / TraceSet.write reach files through these (the core does not import io).
register_files(FileHandlers(read=read_traceset, write=write_traceset))
# TraceSet.from_arrow / to_pandas / ... reach tables through simcred.io.frames (registers itself)
import simcred.io.frames  # noqa: E402, F401

__all__ = ["DATASETS", "FORMATS", "PARQUET_SUFFIXES", "detect", "detect_source", "read",
           "read_source", "read_traceset", "write", "write_traceset"]
