"""A trace set stored as a Parquet *data set*: many partitions, read one at a time.

A data set is a folder of Parquet files (hive-style sub-folders such as ``day=3/part-0.parquet``
too; folder names are not read as columns), a glob (``runs/part-*.parquet``), or a URI that
pyarrow's filesystems open (``s3://bucket/runs/``, ``gs://…``; with fsspec installed, any fsspec
protocol). Every partition is one Parquet file in the layout of :mod:`simcred.io.parquet`
(columns ``run``, ``t`` and the signals); files whose names start with ``.`` or ``_`` are
ignored (pyarrow.dataset's rule: ``_SUCCESS``, ``_metadata``).

The set's runs are the partitions' runs in the order of the partition paths (sorted), within a
partition in order of first appearance: exactly what :func:`read_dataset` holds in memory. A
run may not be split across partitions (a partition is the unit a worker reads whole): the
second partition that names a run is refused with a one-line error naming both.
"""

from __future__ import annotations

import fnmatch
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.dataset as ds
import pyarrow.fs as pafs
import pyarrow.parquet as pq

from simcred.errors import TraceSetError
from simcred.io._columns import check_width
from simcred.traces import TIME, TraceSet, concat

GLOB_CHARACTERS = "*?["
SUFFIXES = (".parquet", ".pq")


def is_dataset(path: Any) -> bool:
    """Whether ``path`` names a Parquet data set (and not a trace set of another format).

    A URI (``scheme://…``), a glob that is not an existing path, or a folder with no CSV file
    at its top and at least one ``.parquet``/``.pq`` file at any depth.
    """
    if not isinstance(path, str | os.PathLike):
        return False
    text = os.fspath(path)
    if "://" in text:
        return True
    if any(c in text for c in GLOB_CHARACTERS) and not os.path.exists(text):
        return True
    folder = Path(text)
    if not folder.is_dir():
        return False
    if any(p.suffix.lower() == ".csv" for p in folder.iterdir()):
        return False
    return any(p.suffix.lower() in SUFFIXES and p.is_file() for p in folder.rglob("*"))


@dataclass(frozen=True, slots=True, eq=False)
class ParquetDataset:
    """The partitions of a data set and what its first partition says about all of them.

    ``files``: the partition paths (on ``filesystem``), sorted; ``signals``: the signal columns
    of the first partition, which every partition must have; ``rows``: rows per partition from
    the Parquet footers (no value read).
    """

    source: str
    filesystem: pafs.FileSystem
    files: tuple[str, ...]
    rows: tuple[int, ...]
    signals: tuple[str, ...]

    @classmethod
    def open(cls, path: str | os.PathLike) -> ParquetDataset:
        source = os.fspath(path)
        filesystem, files = _discover(source)
        rows = []
        schema = None
        for file in files:
            try:
                metadata = pq.read_metadata(file, filesystem=filesystem)
            except (pa.ArrowException, OSError) as exc:
                raise TraceSetError(f"{file}: unreadable Parquet ({_reason(exc)})") from None
            check_width(metadata.num_columns, file)  # every partition, before a value is read
            rows.append(metadata.num_rows)
            if schema is None and metadata.num_rows:
                schema = metadata.schema.to_arrow_schema()
        if schema is None:
            raise TraceSetError(f"{source}: the data set is empty (no rows in "
                                f"{len(files)} partition(s))")
        signals = tuple(n for n in schema.names if n not in ("run", TIME))
        return cls(source, filesystem, tuple(files), tuple(rows), signals)

    @property
    def n_rows(self) -> int:
        return sum(self.rows)

    def partition(self, i: int) -> TraceSet:
        """Partition ``i`` as a validated trace set whose source is the partition's path."""
        from simcred.io._columns import check_table
        from simcred.io.parquet import RUN, from_table

        file = self.files[i]
        try:
            table = check_table(pq.read_table(file, filesystem=self.filesystem), file)
        except (pa.ArrowException, OSError) as exc:
            raise TraceSetError(f"{file}: unreadable Parquet ({_reason(exc)})") from None
        names = [n for n in table.column_names if n not in (RUN, TIME)]
        if set(names) != set(self.signals):
            raise TraceSetError(f"{file}: signals {sorted(names)} differ from the data set's "
                                f"first partition: {sorted(self.signals)}")
        table = table.select([c for c in (RUN, TIME, *self.signals) if c in table.column_names])
        return from_table(table, file)

    def partitions(self) -> Iterator[tuple[int, TraceSet]]:
        """``(index, trace set)`` of every partition with rows, in order; refuses a run that a
        second partition names again."""
        seen: dict[str, int] = {}
        for i, rows in enumerate(self.rows):
            if rows == 0:
                continue
            part = self.partition(i)
            for run in part.run_ids:
                first = seen.setdefault(run, i)
                if first != i:
                    raise TraceSetError(f"{self.source}: run '{run}' is split across partitions "
                                        f"{self.files[first]} and {self.files[i]}")
            yield i, part


def read_dataset(path: str | os.PathLike) -> TraceSet:
    """The whole data set in memory (the runs of all partitions, in order); for sets that fit.

    :func:`simcred.compare.compare` reads a data set out of core instead.
    """
    dataset = ParquetDataset.open(path)
    parts = [part for _, part in dataset.partitions()]
    return concat(parts, source=dataset.source, metadata=parts[0].metadata)


def _discover(source: str) -> tuple[pafs.FileSystem, list[str]]:
    """The filesystem and the sorted partition files of a folder, glob or URI."""
    try:
        filesystem, base = _filesystem(source)
    except (pa.ArrowException, OSError, ValueError, ImportError) as exc:
        raise TraceSetError(f"{source}: cannot open the data set ({_reason(exc)})") from None
    try:
        if any(c in base for c in GLOB_CHARACTERS) and not _exists(filesystem, base):
            files = _glob(filesystem, base)
        else:
            info = filesystem.get_file_info(base)
            if info.type == pafs.FileType.NotFound:
                raise TraceSetError(f"{source}: no such file or directory")
            dataset = ds.dataset(base, filesystem=filesystem, format="parquet",
                                 exclude_invalid_files=False)
            files = [f for f in dataset.files if f.lower().endswith(SUFFIXES)]
    except (pa.ArrowException, OSError) as exc:
        raise TraceSetError(f"{source}: cannot list the data set ({_reason(exc)})") from None
    if not files:
        raise TraceSetError(f"{source}: no Parquet partitions (.parquet/.pq files) found")
    return filesystem, sorted(files)


def _filesystem(source: str) -> tuple[pafs.FileSystem, str]:
    if "://" not in source:
        return pafs.LocalFileSystem(), os.path.abspath(source)
    try:
        return pafs.FileSystem.from_uri(source)
    except (pa.ArrowException, ValueError):
        import fsspec  # any other protocol: through fsspec, if installed
        from pyarrow.fs import FSSpecHandler, PyFileSystem

        fs, base = fsspec.core.url_to_fs(source)
        return PyFileSystem(FSSpecHandler(fs)), base


def _exists(filesystem: pafs.FileSystem, path: str) -> bool:
    return filesystem.get_file_info(path).type != pafs.FileType.NotFound


def _glob(filesystem: pafs.FileSystem, pattern: str) -> list[str]:
    """Files matching ``pattern`` below the pattern's longest folder without glob characters
    (``*`` also matches across ``/``), hidden names (``.``, ``_``) left out as pyarrow does."""
    parts = pattern.split("/")
    fixed = next(i for i, p in enumerate(parts) if any(c in p for c in GLOB_CHARACTERS))
    base = "/".join(parts[:fixed]) or "/"
    if not _exists(filesystem, base):
        return []
    infos = filesystem.get_file_info(pafs.FileSelector(base, recursive=True))
    return [i.path for i in infos if i.type == pafs.FileType.File
            and fnmatch.fnmatchcase(i.path, pattern)
            and not i.base_name.startswith((".", "_"))]


def _reason(exc: BaseException) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
