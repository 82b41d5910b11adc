"""TraceSet: many runs of one model (or one reality), stored columnar.

A run is a table with a time column ``t`` (seconds, strictly increasing) and named float signals.
All runs' rows are concatenated into one ``(rows, signals)`` array; ``offsets[i]:offsets[i + 1]``
are the rows of run ``i``. Several objects use dotted signal names (``ego.x``, ``cyclist.y``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import simcred._display as _display
from simcred.errors import TraceSetError

TIME = "t"
#: Metadata key of per-run facts: ``metadata[RUN_INFO][run_id]`` is a JSON-able mapping.
RUN_INFO = "run_info"


@dataclass(frozen=True, slots=True)
class FileHandlers:
    """How :meth:`TraceSet.read` and :meth:`TraceSet.write` reach files.

    The core does not import :mod:`simcred.io` (layers import one way, docs/architecture.md);
    ``simcred.io`` registers its suffix-dispatching reader and writer here when it is imported,
    and the package root ``simcred`` imports ``simcred.io``, so they are always registered.
    """

    read: Callable[..., TraceSet]  # (path, **options)
    write: Callable[..., Path]  # (traces, path, **options)


_handlers: dict[str, Any] = {}


def register_files(handlers: FileHandlers) -> None:
    """Register the file formats of :meth:`TraceSet.read` / :meth:`TraceSet.write` (io does)."""
    _handlers["files"] = handlers


@dataclass(frozen=True, slots=True)
class TableHandlers:
    """How the ``from_*`` / ``to_*`` table methods of :class:`TraceSet` reach Arrow, pandas and
    polars (registered by :mod:`simcred.io.frames`, as :class:`FileHandlers` are)."""

    read: Callable[..., TraceSet]  # (table, kind, **options); kind: "arrow", "pandas", "polars"
    write: Callable[..., Any]  # (traces, kind)


def register_tables(handlers: TableHandlers) -> None:
    """Register the table conversions of :meth:`TraceSet.from_arrow` and friends (io does)."""
    _handlers["tables"] = handlers


def _tables() -> TableHandlers:
    try:
        return _handlers["tables"]  # type: ignore[return-value]
    except KeyError:  # pragma: no cover - simcred/__init__ imports simcred.io
        raise RuntimeError("no TraceSet table conversions registered: import simcred.io") from None


def _files() -> FileHandlers:
    try:
        return _handlers["files"]
    except KeyError:  # pragma: no cover - simcred/__init__ imports simcred.io
        raise RuntimeError("no TraceSet file formats registered: import simcred.io") from None


def _writable_anywhere(array: np.ndarray) -> bool:
    """Whether ``array`` or an array whose memory it views can still be written."""
    while isinstance(array, np.ndarray):
        if array.flags.writeable:
            return True
        array = array.base
    return False


def _kept(given: Any, dtype: type) -> np.ndarray:
    """The read-only C-contiguous ``dtype`` array a TraceSet keeps for ``given``.

    A new array (a list, another dtype, a strided view) is converted once and frozen. An array
    used as is would be shared: it is kept only when no one can write it (read-only, and so is
    all memory under it: another TraceSet's columns, :func:`handed_over` arrays, Arrow
    buffers); a caller's writable array is copied, so the caller's array stays writable and
    later writes to it do not reach the set.
    """
    array = np.ascontiguousarray(given, dtype=dtype)
    shared = (np.may_share_memory(array, given) if isinstance(given, np.ndarray)
              else array.base is not None)  # an array-like's own buffer
    if shared:
        if not _writable_anywhere(array):
            return array
        array = array.copy()
    array.setflags(write=False)
    return array


def handed_over(array: np.ndarray) -> np.ndarray:
    """``array``, made read-only with the memory under it, for a TraceSet to keep uncopied.

    Only for arrays built to be handed to a :class:`TraceSet` that nothing else writes: a
    TraceSet copies writable arrays (they are its caller's), so a constructor of fresh
    columns hands them over instead of having them copied.
    """
    view: Any = array
    while isinstance(view, np.ndarray):
        view.setflags(write=False)
        view = view.base
    return array


@dataclass(frozen=True, slots=True, eq=False)
class TraceSet:
    """A set of runs: columnar storage of concatenated rows plus run offsets.

    Parameters
    ----------
    signals : tuple of str
        Signal names, in column order (the time column ``t`` is kept apart).
    time : ndarray, shape (rows,)
        Time stamps of all runs, concatenated.
    values : ndarray, shape (rows, len(signals))
        Signal values of all runs, concatenated.
    offsets : ndarray, shape (runs + 1,)
        Run ``i`` is ``rows offsets[i]:offsets[i + 1]``.
    run_ids : tuple of str
        One unique name per run (CSV file stem, Parquet ``run`` value).
    metadata : mapping
        JSON-serialisable provenance: source, model, parameters, seed.
    source : str
        Where the set came from (a path), used to name the culprit in errors.
    run_sources : tuple of str
        Per run, the file it came from when runs are separate files (CSV directory), else empty.

    Notes
    -----
    Construction validates everything a comparison relies on: at least one run, at least two steps
    per run, finite values, strictly increasing time. Errors are one line naming the file, run,
    column and row (1-based data row, header excluded). Equality is identity; use
    :meth:`equals` for content equality. The arrays are read-only; a caller's writable array is
    copied (it stays writable, and writing it later does not change the set), a read-only one is
    kept as it is (builders of fresh columns pass them through :func:`handed_over`).
    """

    signals: tuple[str, ...]
    time: np.ndarray
    values: np.ndarray
    offsets: np.ndarray
    run_ids: tuple[str, ...]
    metadata: Mapping[str, Any] = field(default_factory=dict)
    source: str = "<memory>"
    run_sources: tuple[str, ...] = ()
    _digest: str | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        for name, given, dtype in (
            ("time", self.time, np.float64),
            ("values", self.values, np.float64),
            ("offsets", self.offsets, np.int64),
        ):
            object.__setattr__(self, name, _kept(given, dtype))
        object.__setattr__(self, "signals", tuple(self.signals))
        object.__setattr__(self, "run_ids", tuple(str(r) for r in self.run_ids))
        object.__setattr__(self, "run_sources", tuple(self.run_sources))
        self._validate()

    def __sizeof__(self) -> int:
        """Bytes held, arrays included: what Dask (``sys.getsizeof``) counts when it moves or
        spills a set, and places tasks near it."""
        strings = sum(len(r) for r in self.run_ids) + sum(len(r) for r in self.run_sources)
        return object.__sizeof__(self) + self.time.nbytes + self.values.nbytes \
            + self.offsets.nbytes + strings

    # -- construction -------------------------------------------------------------------------

    @classmethod
    def from_runs(
        cls,
        runs: Sequence[Mapping[str, Any]],
        *,
        run_ids: Sequence[str] | None = None,
        metadata: Mapping[str, Any] | None = None,
        source: str = "<memory>",
    ) -> TraceSet:
        """Build from one mapping per run: ``{"t": [...], "x": [...], ...}``.

        Every run must have the same signal names; column order follows the first run.

        >>> ts = TraceSet.from_runs([{"t": [0, 1], "x": [0.0, 1.0]}, {"t": [0, 1], "x": [2, 3]}])
        >>> ts.n_runs, ts.signals, ts.column("x").tolist()
        (2, ('x',), [0.0, 1.0, 2.0, 3.0])
        """
        if len(runs) == 0:
            raise TraceSetError(f"{source}: the trace set is empty (no runs)")
        ids = [str(i) for i in range(len(runs))] if run_ids is None else [str(r) for r in run_ids]
        first = [k for k in runs[0] if k != TIME]
        for rid, run in zip(ids, runs, strict=True):
            if TIME not in run:
                raise TraceSetError(f"{source}: run '{rid}' has no time column '{TIME}'")
            _check_same_signals(first, [k for k in run if k != TIME], f"{source}: run '{rid}'")
        lengths = [len(np.asarray(run[TIME])) for run in runs]
        offsets = np.concatenate([[0], np.cumsum(lengths)])
        time = np.concatenate([np.asarray(run[TIME], dtype=np.float64) for run in runs])
        values = np.empty((len(time), len(first)))
        for j, name in enumerate(first):
            values[:, j] = np.concatenate([np.asarray(run[name], dtype=np.float64) for run in runs])
        return cls(tuple(first), handed_over(time), handed_over(values), offsets, tuple(ids),
                   dict(metadata or {}), source)

    # -- access -------------------------------------------------------------------------------

    @property
    def n_runs(self) -> int:
        return len(self.offsets) - 1

    @property
    def n_rows(self) -> int:
        return len(self.time)

    @property
    def lengths(self) -> np.ndarray:
        """Number of steps of every run."""
        return np.diff(self.offsets)

    def __len__(self) -> int:
        return self.n_runs

    def __repr__(self) -> str:
        return (
            f"TraceSet({self.source!r}, runs={self.n_runs}, rows={self.n_rows}, "
            f"signals={list(self.signals)})"
        )

    def _repr_html_(self) -> str:
        """Notebook display: a summary table and a figure (:mod:`simcred.report.notebook`)."""
        return _display.html(self)

    @property
    def units(self) -> dict[str, str]:
        """Unit per signal, from ``metadata["units"]`` (e.g. ``{"ego.v": "m/s"}``).

        Kept in ``traceset.json`` (CSV directory) or the Parquet schema metadata, like all
        metadata; signals without an entry have no known unit.
        """
        raw = self.metadata.get("units", {})
        if not isinstance(raw, Mapping) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in raw.items()):
            raise TraceSetError(f"{self.source}: metadata 'units' must map signal names to "
                                "unit strings")
        return dict(raw)

    def column(self, name: str) -> np.ndarray:
        """All rows of one signal (or of ``t``), concatenated over runs."""
        if name == TIME:
            return self.time
        return self.values[:, self._index(name)]

    def features(self, names: Sequence[str]) -> np.ndarray:
        """The ``(rows, len(names))`` array of the named signals, in that order."""
        return self.values[:, [self._index(n) for n in names]]

    def run(self, i: int) -> dict[str, np.ndarray]:
        """Run ``i`` as a mapping ``{"t": ..., signal: ...}`` of read-only views."""
        lo, hi = self.offsets[i], self.offsets[i + 1]
        out = {TIME: self.time[lo:hi]}
        out.update({s: self.values[lo:hi, j] for j, s in enumerate(self.signals)})
        return out

    def _index(self, name: str) -> int:
        try:
            return self.signals.index(name)
        except ValueError:
            known = ", ".join(self.signals)
            raise TraceSetError(
                f"{self.source}: unknown signal '{name}' (signals are: {known})"
            ) from None

    # -- identity -----------------------------------------------------------------------------

    def digest(self) -> str:
        """SHA-256 of the content (signals, run ids, offsets, time, values), not the metadata."""
        if self._digest is None:
            object.__setattr__(self, "_digest", self._compute_digest())
        return self._digest

    def _compute_digest(self) -> str:
        h = hashlib.sha256()
        h.update(json.dumps([self.signals, self.run_ids]).encode())
        for array in (self.offsets, self.time, self.values):
            h.update(np.ascontiguousarray(array))  # its buffer: the bytes, without a copy
        return "sha256:" + h.hexdigest()

    def equals(self, other: TraceSet) -> bool:
        """Exact content equality (bitwise floats), metadata included."""
        return (
            self.signals == other.signals
            and self.run_ids == other.run_ids
            and np.array_equal(self.offsets, other.offsets)
            and np.array_equal(self.time, other.time)
            and np.array_equal(self.values, other.values)
            and dict(self.metadata) == dict(other.metadata)
        )

    # -- files --------------------------------------------------------------------------------

    @classmethod
    def read(cls, path: str | Path, **options: Any) -> TraceSet:
        """Read any supported format (CSV directory, Parquet, long format, SUMO FCD, CommonRoad,
        OSI, highD family, MDF4, ROS 2 bags); ``options`` such as ``run_column=`` go to the
        reader (:func:`simcred.io.read`, registered with :func:`register_files`: the core does
        not import io)."""
        return _files().read(path, **options)

    def write(self, path: str | Path, **options: Any) -> Path:
        """Write in the format ``path`` implies (:func:`simcred.io.write`): a CSV directory,
        Parquet for ``.parquet``/``.pq``, a long CSV for ``.csv``, OSI for ``.osi``/``.mcap``."""
        return _files().write(self, path, **options)

    # -- tables (simcred.io.frames) -----------------------------------------------------------

    @classmethod
    def from_arrow(cls, table: Any, **options: Any) -> TraceSet:
        """A trace set from a ``pyarrow.Table`` in long format (:func:`simcred.io.frames.read`:
        ``run=``, ``time=``, ``object=`` name the key columns; ``metadata=``, ``source=``)."""
        return _tables().read(table, "arrow", **options)

    @classmethod
    def from_pandas(cls, frame: Any, **options: Any) -> TraceSet:
        """A trace set from a ``pandas.DataFrame`` in long format (as :meth:`from_arrow`; the
        metadata defaults to ``frame.attrs["simcred"]``, which :meth:`to_pandas` sets)."""
        return _tables().read(frame, "pandas", **options)

    @classmethod
    def from_polars(cls, frame: Any, **options: Any) -> TraceSet:
        """A trace set from a ``polars.DataFrame`` in long format (as :meth:`from_arrow`)."""
        return _tables().read(frame, "polars", **options)

    def to_arrow(self) -> Any:
        """The ``pyarrow.Table`` ``run``, ``t``, signals; metadata in the schema metadata."""
        return _tables().write(self, "arrow")

    def to_pandas(self) -> Any:
        """The ``pandas.DataFrame`` ``run`` (categorical), ``t``, signals; metadata in
        ``attrs["simcred"]``."""
        return _tables().write(self, "pandas")

    def to_polars(self) -> Any:
        """The ``polars.DataFrame`` ``run`` (categorical), ``t``, signals (no metadata)."""
        return _tables().write(self, "polars")

    # -- validation ---------------------------------------------------------------------------

    def _where(self, run: int) -> str:
        if self.run_sources:
            return self.run_sources[run]
        return f"{self.source}: run '{self.run_ids[run]}'"

    def _validate(self) -> None:
        src = self.source
        if not isinstance(self.metadata, Mapping):  # e.g. a JSON list stored by another tool
            raise TraceSetError(f"{src}: metadata must be a JSON object, not "
                                f"{type(self.metadata).__name__}")
        if self.n_runs < 1 or self.n_rows == 0:
            raise TraceSetError(f"{src}: the trace set is empty (no runs)")
        if TIME in self.signals:
            raise TraceSetError(f"{src}: '{TIME}' is the time column, not a signal")
        if len(set(self.signals)) != len(self.signals):
            raise TraceSetError(f"{src}: duplicate signal names {list(self.signals)}")
        if self.values.shape != (self.n_rows, len(self.signals)):
            raise TraceSetError(f"{src}: values have shape {self.values.shape}, "
                                f"expected ({self.n_rows}, {len(self.signals)})")
        if len(self.run_ids) != self.n_runs or len(set(self.run_ids)) != self.n_runs:
            raise TraceSetError(f"{src}: run ids must be unique, one per run")
        if self.offsets[0] != 0 or self.offsets[-1] != self.n_rows:
            raise TraceSetError(f"{src}: offsets must start at 0 and end at the row count")
        short = np.flatnonzero(self.lengths < 2)
        if short.size:
            i = int(short[0])
            raise TraceSetError(f"{self._where(i)}: run has {self.lengths[i]} step(s); "
                                "at least 2 are needed for a transition")
        self._validate_finite()
        self._validate_time()

    def _validate_finite(self) -> None:
        for j, name in enumerate((TIME, *self.signals)):
            col = self.time if j == 0 else self.values[:, j - 1]
            bad = np.flatnonzero(~np.isfinite(col))
            if bad.size:
                row = int(bad[0])
                run = int(np.searchsorted(self.offsets, row, side="right") - 1)
                raise TraceSetError(
                    f"{self._where(run)}: column '{name}', row {row - self.offsets[run] + 1}: "
                    f"value is {col[row]} (values must be finite)"
                )

    def _validate_time(self) -> None:
        step_ok = self.time[1:] > self.time[:-1]  # not np.diff: t[i+1] - t[i] may overflow
        step_ok[self.offsets[1:-1] - 1] = True  # a new run may restart its clock
        bad = np.flatnonzero(~step_ok)
        if bad.size:
            row = int(bad[0]) + 1
            run = int(np.searchsorted(self.offsets, row, side="right") - 1)
            raise TraceSetError(
                f"{self._where(run)}: column '{TIME}' is not strictly increasing at row "
                f"{row - self.offsets[run] + 1} (t={float(self.time[row])!r} after "
                f"{float(self.time[row - 1])!r})"
            )


def _check_same_signals(expected: Sequence[str], got: Sequence[str], where: str) -> None:
    if set(expected) == set(got) and len(got) == len(expected):
        return
    missing = sorted(set(expected) - set(got))
    extra = sorted(set(got) - set(expected))
    raise TraceSetError(
        f"{where}: signal names differ from the first run (missing {missing}, extra {extra})"
    )


def concat(parts: Sequence[TraceSet], *, source: str | None = None,
           metadata: Mapping[str, Any] | None = None) -> TraceSet:
    """The runs of ``parts`` one after the other (same signals, in the same order; unique ids)."""
    if not parts:
        raise TraceSetError("nothing to concatenate: no trace sets")
    first = parts[0]
    for part in parts[1:]:
        if part.signals != first.signals:
            raise TraceSetError(f"{part.source}: signals {list(part.signals)} differ from "
                                f"{first.source}: {list(first.signals)}")
    sizes = np.cumsum([0] + [p.n_rows for p in parts[:-1]])
    return TraceSet(
        signals=first.signals,
        time=handed_over(np.concatenate([p.time for p in parts])),
        values=handed_over(np.concatenate([p.values for p in parts])),
        offsets=np.concatenate([[0]] + [p.offsets[1:] + s for p, s in zip(parts, sizes,
                                                                           strict=True)]),
        run_ids=tuple(r for p in parts for r in p.run_ids),
        metadata=dict(first.metadata if metadata is None else metadata),
        source=first.source if source is None else source,
    )


def spans(starts: Any, ends: Any) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the ranges ``starts[i] .. ends[i]-1``, one after the other, and the offsets
    of the runs they make: how every subset of a set's rows is cut (:func:`take`, a crop, a
    cell's segments, a reader's tracks).

    >>> rows, offsets = spans([4, 0], [6, 1])
    >>> rows.tolist(), offsets.tolist()
    ([4, 5, 0], [0, 2, 3])
    """
    starts, ends = np.asarray(starts, dtype=np.int64), np.asarray(ends, dtype=np.int64)
    rows = np.concatenate([np.arange(a, b) for a, b in zip(starts, ends, strict=True)])
    return rows, np.concatenate([[0], np.cumsum(ends - starts)])


def take(traces: TraceSet, runs: Sequence[int], *, source: str | None = None) -> TraceSet:
    """The runs ``runs`` (indices, in that order, no repeats) of ``traces`` as a new set.

    Per-run metadata under :data:`RUN_INFO` keeps only the taken runs; other metadata is kept.
    """
    index = np.asarray(runs, dtype=np.int64).reshape(-1)
    if index.size == 0:
        raise TraceSetError(f"{traces.source}: no runs to take")
    if len(np.unique(index)) != index.size or index.min() < 0 or index.max() >= traces.n_runs:
        raise TraceSetError(f"{traces.source}: run indices must be distinct and in "
                            f"[0, {traces.n_runs}), got {index.tolist()[:5]}...")
    rows, offsets = spans(traces.offsets[index], traces.offsets[index + 1])
    ids = tuple(traces.run_ids[i] for i in index)
    metadata = dict(traces.metadata)
    if isinstance(metadata.get(RUN_INFO), Mapping):
        metadata[RUN_INFO] = {r: metadata[RUN_INFO][r] for r in ids if r in metadata[RUN_INFO]}
    return TraceSet(
        signals=traces.signals,
        time=handed_over(traces.time[rows]),
        values=handed_over(traces.values[rows]),
        offsets=offsets,
        run_ids=ids,
        metadata=metadata,
        source=traces.source if source is None else source,
        run_sources=tuple(traces.run_sources[i] for i in index) if traces.run_sources else (),
    )
