"""A Parquet trace set read for a comparison that needs no time stamps (issue 25, memory).

``compare(path_a, path_b)`` reads a file whose rows are grouped by run (as simcred writes
Parquet) row group by row group without keeping its time column (8 bytes a row): what the
comparison needs of the time stamps is taken while they stream past, as the out-of-core path
does (:mod:`simcred.compare.outofcore`):

* the checks :class:`~simcred.traces.TraceSet` makes of them (finite, strictly increasing within
  runs; any failure reads the file again as a TraceSet, which raises its own error);
* their part of the content hash (``TraceSet.digest``: signals and run ids, offsets, time,
  values, in that order; the values are held, so they come last);
* the median time step within runs (the sample-period check): a
  :class:`~simcred.compare.quantiles.Sketch` of the steps in the first pass, their exact middle
  order statistics from a second pass over the time column (``quantiles.median_from``).

Sets that need time stamps (time windows, resampling, the response test) are read whole.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from simcred.compare.facts import SetFacts
from simcred.compare.quantiles import Brackets, Sketch, Tally, median_from
from simcred.compare.result import InputInfo
from simcred.errors import TraceSetError
from simcred.traces import TIME, TraceSet


@dataclass(frozen=True, slots=True, eq=False)
class TimelessSet:
    """A trace set without its time column: what a comparison reads of it."""

    source: str
    signals: tuple[str, ...]
    values: np.ndarray
    offsets: np.ndarray
    metadata: dict
    info: InputInfo
    period: float

    @property
    def n_runs(self) -> int:
        return len(self.offsets) - 1

    @property
    def units(self) -> dict[str, str]:
        return TraceSet.units.fget(self)  # the same checks of metadata["units"]

    def facts(self) -> SetFacts:
        return SetFacts(self.source, self.signals, self.n_runs, self.units, self.period)

    def features(self, names: tuple[str, ...]) -> np.ndarray:
        """The signals' own array when ``names`` are all of them in order, else the columns."""
        if names == self.signals:
            return self.values
        return self.values[:, [self.signals.index(n) for n in names]]


def read_timeless(path: str | Path) -> TimelessSet | None:
    """The set in ``path`` without its time column, or None: not a Parquet file grouped by run,
    or anything a TraceSet would refuse (reading it as one then raises the error)."""
    from simcred.io.formats import grouped_parquet

    grouped = grouped_parquet(path)
    if grouped is None:
        return None
    digest = hashlib.sha256(json.dumps([grouped.signals, grouped.run_ids]).encode())
    digest.update(np.ascontiguousarray(grouped.offsets, dtype=np.int64))
    values = np.empty((grouped.n_rows, len(grouped.signals)))
    steps, sketch = _StepReader(grouped.offsets), [Sketch.empty(1)]

    def first_pass(lo: int, table: pa.Table) -> None:
        time = grouped.column(table, TIME)
        digest.update(np.ascontiguousarray(time))
        within = steps.within(time, lo)
        if within is None or not np.isfinite(time).all():
            raise TraceSetError("not a trace set's time column")  # read whole: its own error
        if len(within):
            sketch[0] = sketch[0].merge(Sketch.of(within, cap=1))
        grouped.place(table, values, lo)

    try:
        grouped.each_row_group(first_pass)
        if (np.diff(grouped.offsets) < 2).any() or not np.isfinite(values).all():
            return None
        period = _period(grouped, sketch[0])
    except (TraceSetError, pa.ArrowException, OSError, ValueError):
        return None
    digest.update(values)
    source = str(grouped.path)
    info = InputInfo(source, "sha256:" + digest.hexdigest(), len(grouped.offsets) - 1,
                     grouped.n_rows)
    return TimelessSet(source, grouped.signals, values, grouped.offsets, grouped.metadata,
                       info, period)


def _period(grouped: Any, sketch: Sketch) -> float:
    """The median step within runs: the sketch's middle ranks placed by a second pass."""
    if sketch.count == 0:
        return math.nan

    def tallied(brackets: Brackets) -> Tally:
        steps, tally = _StepReader(grouped.offsets), [brackets.empty_tally()]

        def second_pass(lo: int, table: pa.Table) -> None:
            time = grouped.column(table, TIME)
            tally[0] = tally[0].merge(brackets.tally(steps.within(time, lo)))

        grouped.each_row_group(second_pass, [TIME])
        return tally[0]

    return median_from(sketch, tallied)


class _StepReader:
    """The time steps within runs of consecutive chunks of the time column (a run may go on
    into the next chunk: the chunk's last time stamp is carried over)."""

    def __init__(self, offsets: np.ndarray) -> None:
        self.starts = offsets[1:-1]  # rows that begin a run (after the first)
        self.last: np.ndarray = np.empty(0)

    def within(self, time: np.ndarray, lo: int) -> np.ndarray | None:
        """The steps into rows ``lo + 1 ..`` of this chunk (from ``lo`` when a chunk came
        before) that lie within a run; None where time does not increase within a run."""
        joined = np.concatenate([self.last, time])
        first = lo - len(self.last)  # the row of joined[0]
        if len(time):  # not a view: it would keep the chunk's buffer
            self.last = time[-1:].copy()
        keep = np.ones(max(len(joined) - 1, 0), dtype=bool)
        begins = self.starts[(self.starts > first) & (self.starts < first + len(joined))]
        keep[begins - first - 1] = False  # the step into a run's first row is none
        if not (joined[1:] > joined[:-1])[keep].all():
            return None
        return np.diff(joined)[keep]
