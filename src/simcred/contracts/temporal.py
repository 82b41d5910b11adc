"""Bounded temporal operators over recorded runs, vectorised with numpy (monitors only).

Discrete-time semantics over the samples of each run (the semantics of rtamt's discrete-time
STL, which the tests check sample by sample on random formulas and signals), with bounds in
seconds measured on the run's time column:

* ``always[a, b] φ`` at t: φ at every sample of the run with time in [t + a, t + b]
  (robustness: the minimum; an empty window — past the end of the run — is true, +inf);
* ``eventually[a, b] φ``: at some sample in [t + a, t + b] (maximum; empty: false, -inf);
* ``historically[a, b] φ`` / ``once[a, b] φ``: the same over [t - b, t - a];
* ``previous φ``: φ at the previous sample of the run (true, +inf, at a run's first sample);
* ``φ until[a, b] ψ``: some sample j in [t + a, t + b] has ψ, and φ holds at every sample from
  t up to (excluding) j; robustness max_j min(ψ(j), min_{t <= k < j} φ(k));
* ``φ since[a, b] ψ``: some j in [t - b, t - a] has ψ, and φ holds after j up to t.

Windows are found per sample by ``searchsorted`` on the times (non-uniform sampling allowed);
window minima and maxima come from a sparse table (O(n log w) time and memory for windows of up
to w samples), and until/since from a loop over window offsets, vectorised over all samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Timeline:
    """Sample times of all rows (runs concatenated) and the run offsets (n_runs + 1)."""

    time: np.ndarray
    offsets: np.ndarray

    @classmethod
    def single(cls, time) -> Timeline:
        time = np.asarray(time, dtype=float)
        return cls(time, np.array([0, len(time)]))

    def run_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """First row and one past the last row of the run of every row."""
        lengths = np.diff(self.offsets)
        return np.repeat(self.offsets[:-1], lengths), np.repeat(self.offsets[1:], lengths)

    def window(self, lo: float, hi: float, *, past: bool) -> tuple[np.ndarray, np.ndarray]:
        """Rows [start, stop) of every row's window within its run."""
        first, last = self.run_bounds()
        n = len(self.time)
        start, stop = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        for r in range(len(self.offsets) - 1):
            a, b = int(self.offsets[r]), int(self.offsets[r + 1])
            t = self.time[a:b]
            low, high = (t - hi, t - lo) if past else (t + lo, t + hi)
            start[a:b] = a + np.searchsorted(t, low - _EPS * np.abs(low), side="left")
            stop[a:b] = a + np.searchsorted(t, high + _EPS * np.abs(high), side="right")
        return np.clip(start, first, last), np.clip(stop, first, last)


_EPS = 1e-12  # relative slack so that t + 0.1 finds a sample recorded at 0.1 * k


def window_reduce(values: np.ndarray, start: np.ndarray, stop: np.ndarray, *, maximum: bool,
                  empty) -> np.ndarray:
    """min (or max) of ``values[start:stop]`` for every row; ``empty`` where the window is
    empty. Sparse table: level k holds the reduction over 2^k consecutive rows."""
    values = np.asarray(values)
    combine = np.maximum if maximum else np.minimum
    length = stop - start
    out = np.full(len(values), empty, dtype=np.result_type(values, type(empty)))
    ok = length > 0
    if not ok.any():
        return out
    widest = int(length.max())
    levels = [values]
    while (1 << len(levels)) <= widest:
        prev, step = levels[-1], 1 << (len(levels) - 1)
        nxt = prev.copy()
        nxt[:len(prev) - step] = combine(prev[:len(prev) - step], prev[step:])
        levels.append(nxt)
    k = np.zeros(len(values), dtype=np.int64)
    k[ok] = np.floor(np.log2(length[ok])).astype(np.int64)
    for level in np.unique(k[ok]):
        rows = ok & (k == level)
        table = levels[level]
        left, right = start[rows], stop[rows] - (1 << int(level))
        out[rows] = combine(table[left], table[right])
    return out


def previous(values: np.ndarray, timeline: Timeline, *, first):
    """``values`` shifted by one sample within each run; ``first`` at each run's first row."""
    values = np.asarray(values)
    out = np.empty(len(values), dtype=np.result_type(values, type(first)))
    out[1:] = values[:-1]
    out[timeline.offsets[:-1][np.diff(timeline.offsets) > 0]] = first
    return out


def until(phi: np.ndarray, psi: np.ndarray, start: np.ndarray, stop: np.ndarray, *,
          past: bool, boolean: bool) -> np.ndarray:
    """max over j in the window of min(psi(j), min of phi strictly between j and the row, and
    at the row itself: rows [i, j) for until, (j, i] for since)."""
    n = len(phi)
    rows = np.arange(n)
    lo_off = int((rows - stop + 1).min()) if past else int((start - rows).min())
    hi_off = int((rows - start).max()) if past else int((stop - 1 - rows).max())
    worst, best = (True, False) if boolean else (np.inf, -np.inf)
    and_, or_ = (np.logical_and, np.logical_or) if boolean else (np.minimum, np.maximum)
    out = np.full(n, best)
    running = np.full(n, worst)  # min of phi over the rows passed so far
    for d in range(0, max(hi_off, 0) + 1):
        j = rows - d if past else rows + d
        inside = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        in_window = inside & (jj >= start) & (jj < stop)
        if d >= max(lo_off, 0):
            candidate = and_(psi[jj], running)
            out = np.where(in_window, or_(out, candidate), out)
        # phi at j joins the running minimum for the next offset (j is excluded for j itself
        # in until; for since the row itself is included, j is excluded)
        step_row = jj
        running = np.where(inside, and_(running, phi[step_row]), running)
    return out
