"""Sample periods: both sets must share one, or be resampled to a common one.

A chain's transition law depends on the sample period (at 0.1 s most transitions are self-loops,
at 1 s few are), so two sets recorded at different periods differ for that reason alone. simcred
refuses such a pair unless the user asks for a common period, to which every run is resampled by
linear interpolation between its samples (``numpy.interp``), starting at the run's first time
stamp and ending at or before its last.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

from simcred.errors import OptionError
from simcred.limits import check_count
from simcred.traces import TraceSet, spans

#: Relative difference of median sample periods above which two sets count as different.
PERIOD_RTOL = 1e-3


def within_run_steps(traces: TraceSet) -> np.ndarray:
    """Every time step inside a run (the step across a boundary between two runs is none)."""
    within = np.ones(max(traces.n_rows - 1, 0), dtype=bool)
    within[traces.offsets[1:-1] - 1] = False
    return np.diff(traces.time)[within]


def sample_period(traces: TraceSet) -> float:
    """Median time step within runs: ``numpy.median`` of :func:`within_run_steps`, taken on one
    array of all steps (the steps across run boundaries set to +inf sort past every rank the
    median reads), partitioned in place."""
    steps = np.diff(traces.time)
    steps[traces.offsets[1:-1] - 1] = np.inf
    count = len(steps) - (traces.n_runs - 1)
    if count <= 0:
        return math.nan  # runs of one sample
    middle = np.unique([(count - 1) // 2, count // 2])  # one rank for an odd count, two else
    steps.partition(middle)
    return float(np.mean(steps[middle]))


def check_periods(sources: Sequence[str], periods: Sequence[float]) -> None:
    """One-line error if the sets' median sample periods differ by more than PERIOD_RTOL."""
    for source, period in zip(sources[1:], periods[1:], strict=True):
        if abs(period - periods[0]) > PERIOD_RTOL * max(period, periods[0]):
            raise OptionError(
                f"sample periods differ: {sources[0]} {periods[0]:.6g} s, {source} "
                f"{period:.6g} s; resample both to one period with --resample DT")


def check_resample(dt: float | None) -> float | None:
    if dt is None:
        return None
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not math.isfinite(dt) \
            or dt <= 0:
        raise OptionError(f"resample period must be a positive number of seconds, got {dt!r}")
    return float(dt)


def resample(traces: TraceSet, dt: float) -> TraceSet:
    """Every run linearly interpolated to ``t0, t0 + dt, …`` (up to its last time stamp).

    The grid's size is checked against the step and row limits before anything is allocated.
    """
    durations = traces.time[traces.offsets[1:] - 1] - traces.time[traces.offsets[:-1]]
    steps = np.floor(durations / dt + 1e-9) + 1
    longest = int(np.argmax(steps))
    check_count(int(steps[longest]), "steps",
                f"resample period {dt:g} s: steps of run '{traces.run_ids[longest]}'")
    check_count(int(steps.sum()), "rows", f"resample period {dt:g} s: rows of {traces.source}")
    counts = steps.astype(np.int64)
    step, offsets = spans(np.zeros_like(counts), counts)  # each run's steps 0, 1, ...
    times, values = [], []
    for i in range(traces.n_runs):
        lo, hi = traces.offsets[i], traces.offsets[i + 1]
        t = traces.time[lo:hi]
        grid = t[0] + dt * step[offsets[i]:offsets[i + 1]]
        if len(grid) < 2:
            raise OptionError(f"{traces.source}: run '{traces.run_ids[i]}' lasts "
                              f"{t[-1] - t[0]:.6g} s, less than one resample period {dt:g} s")
        times.append(grid)
        values.append(np.column_stack([np.interp(grid, t, traces.values[lo:hi, j])
                                       for j in range(len(traces.signals))]))
    return TraceSet(traces.signals, np.concatenate(times), np.vstack(values), offsets,
                    traces.run_ids, traces.metadata, traces.source)
