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

Windows are computed once per run in sample indices: on a uniformly sampled run (the period an
exact rational, found from the time column: ``0.1`` is 1/10, epoch time stamps at 1 kHz give
1/1000) a window [a, b] is the samples ceil(a/period) … floor(b/period) away, in exact
arithmetic, as in rtamt's discrete-time STL — no floating-point time enters, so ``once[0.3,
0.3]`` at t = 0.3 finds t = 0 and time stamps of 1.7·10⁹ s do not widen a window. A run that is
not uniformly sampled uses ``searchsorted`` on its times relative to its first sample, with a
slack of 10⁻⁶ of its smallest step. Window minima and maxima come from a sparse table (O(n log w)
time and memory for windows of up to w samples); until/since on a uniformly sampled run in
O(n log w) by a block decomposition (:func:`_until_samples`), on any other run in O(n log w)
time and O(n) memory by composing clamps over aligned blocks (:func:`_until_windows`); the loop
over window offsets (:func:`_until_offsets`, O(n·w), the path before) stays as the reference of
the tests and benchmarks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

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

    def runs(self):
        """(first row, one past the last row, sampling period or None) of every run."""
        for r in range(len(self.offsets) - 1):
            a, b = int(self.offsets[r]), int(self.offsets[r + 1])
            yield a, b, uniform_step(self.time[a:b])

    def window(self, lo, hi, *, past: bool) -> tuple[np.ndarray, np.ndarray]:
        """Rows [start, stop) of every row's window within its run (module docs: in sample
        indices on a uniformly sampled run, else on times relative to the run's start)."""
        lo, hi = Fraction(lo), Fraction(hi)
        n = len(self.time)
        start, stop = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
        for a, b, step in self.runs():
            if b == a:
                continue
            rel = self.time[a:b] - self.time[a]  # exact in floating point (Sterbenz)
            rows = np.arange(b - a)
            if step is not None:  # offsets in samples, exact rationals
                first, last = math.ceil(lo / step), math.floor(hi / step)
                low, high = (rows - last, rows - first + 1) if past else \
                    (rows + first, rows + last + 1)
            else:
                positive = np.diff(rel)[np.diff(rel) > 0]
                slack = 1e-6 * float(positive.min()) if len(positive) else 0.0
                edges = (rel - float(hi), rel - float(lo)) if past else \
                    (rel + float(lo), rel + float(hi))
                low = np.searchsorted(rel, edges[0] - slack, side="left")
                high = np.searchsorted(rel, edges[1] + slack, side="right")
            start[a:b] = a + np.clip(low, 0, b - a)
            stop[a:b] = a + np.clip(high, 0, b - a)
        return start, np.maximum(stop, start)


def uniform_step(time: np.ndarray) -> Fraction | None:
    """The sampling period of a run as an exact rational — the simplest rational consistent
    with the time stamps' rounding (``0.1`` is 1/10; epoch time stamps at 1 kHz, 2.4·10⁻⁷ s apart
    in floating point, give 1/1000) — or None if the run is not uniformly sampled: every sample
    within 10⁻⁶ of a period (plus the rounding of its time stamp) of ``t0 + k·period``."""
    if len(time) < 2:
        return None
    span = Fraction(float(time[-1] - time[0]))
    rounding = Fraction(4 * float(np.spacing(np.abs(time).max())))
    if span <= rounding:
        return None
    step = simplest_between((span - rounding) / (len(time) - 1),
                            (span + rounding) / (len(time) - 1))
    ideal = np.arange(len(time)) * float(step)
    if np.abs((time - time[0]) - ideal).max() > 1e-6 * float(step) + 2 * float(rounding):
        return None
    return step


def simplest_between(lo: Fraction, hi: Fraction) -> Fraction:
    """The rational with the smallest denominator in [lo, hi] (0 <= lo <= hi; continued
    fractions)."""
    whole = math.floor(lo)
    if lo == whole:
        return Fraction(whole)
    if whole + 1 <= hi:
        return Fraction(whole + 1)
    return whole + 1 / simplest_between(1 / (hi - whole), 1 / (lo - whole))


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


def until(phi: np.ndarray, psi: np.ndarray, timeline: Timeline, lo, hi, *, past: bool,
          boolean: bool) -> np.ndarray:
    """``phi until[lo, hi] psi`` (``since`` if ``past``): max over j in the window of
    min(psi(j), min of phi over the rows from the row up to j, j excluded: [i, j) for until,
    (j, i] for since). On a uniformly sampled run O(n log w) (:func:`_until_samples`; since is
    until on the reversed run); otherwise also O(n log w) (:func:`_until_windows`)."""
    if boolean:  # the same lattice on ±1
        signed = until(np.where(phi, 1.0, -1.0), np.where(psi, 1.0, -1.0), timeline, lo, hi,
                       past=past, boolean=False)
        return signed > 0
    phi, psi = np.asarray(phi, dtype=float), np.asarray(psi, dtype=float)
    out = np.full(len(phi), -np.inf)
    lo, hi = Fraction(lo), Fraction(hi)
    for a, b, step in timeline.runs():
        if b == a:
            continue
        if step is None:
            part = Timeline.single(timeline.time[a:b])
            start, stop = part.window(lo, hi, past=past)
            out[a:b] = _until_windows(phi[a:b], psi[a:b], start, stop, past=past)
            continue
        first, last = math.ceil(lo / step), math.floor(hi / step)
        if past:
            out[a:b] = _until_samples(phi[a:b][::-1], psi[a:b][::-1], first, last)[::-1]
        else:
            out[a:b] = _until_samples(phi[a:b], psi[a:b], first, last)
    return out


def _until_samples(phi: np.ndarray, psi: np.ndarray, first: int, last: int) -> np.ndarray:
    """Robustness of until with the window [i + first, i + last] in samples, for one run.

    ρ(i) = min(min φ[i, i + first), ρ₀(i + first)) with ρ₀ the until over [i, i + w],
    w = last - first (the rows before i + first are passed by every j). ρ₀ in blocks of L = w + 1
    samples: for i in block k the window spans the rest of block k and the start of block k + 1.
    Within block k: U(i) = max(ψ(i), min(φ(i), U(i + 1))) — a composition of clamps x ↦
    max(ψ, min(φ, x)), which compose to clamps, so a doubling scan gives all of them in
    O(L log L) per block. Into block k + 1 up to i + w: min(min φ[i, end of block k],
    prefix max over block k + 1 of min(ψ(j), min φ[start, j))). Padding past the run is -inf.
    """
    n = len(phi)
    out = np.full(n, -np.inf)
    if last < first or first >= n:
        return out
    width = last - first
    core = _until_from_here(phi, psi, width)
    head = window_reduce(phi, np.arange(n), np.minimum(np.arange(n) + first, n), maximum=False,
                         empty=np.inf) if first else np.full(n, np.inf)
    rows = np.arange(n - first)
    out[rows] = np.minimum(head[rows], core[rows + first])
    return out


def _until_from_here(phi: np.ndarray, psi: np.ndarray, width: int) -> np.ndarray:
    """max over j in [i, i + width] of min(ψ(j), min φ[i, j)) for every i (module docs)."""
    n, size = len(phi), width + 1
    blocks = -(-n // size) + 1  # one more block: the window of the last one reaches into it
    pad = blocks * size - n
    f = np.concatenate([phi, np.full(pad, -np.inf)]).reshape(blocks, size)
    g = np.concatenate([psi, np.full(pad, -np.inf)]).reshape(blocks, size)
    # within the block: compose the clamps [ψ, max(φ, ψ)] from i to the block's end
    low, high = g.copy(), np.maximum(f, g)
    d = 1
    while d < size:
        inner_low, inner_high = low[:, d:], high[:, d:]
        outer_low, outer_high = low[:, :-d], high[:, :-d]
        low[:, :-d] = np.clip(inner_low, outer_low, outer_high)
        high[:, :-d] = np.clip(inner_high, outer_low, outer_high)
        d *= 2
    here = low  # the clamps applied to -inf (nothing after the block's end)
    # into the next block
    rest_min = np.minimum.accumulate(f[:, ::-1], axis=1)[:, ::-1]  # min φ[i, end of block]
    before = np.concatenate([np.full((blocks, 1), np.inf),
                             np.minimum.accumulate(f, axis=1)[:, :-1]], axis=1)
    reach = np.maximum.accumulate(np.minimum(g, before), axis=1)  # prefix max in the block
    onward = np.full((blocks, size), -np.inf)
    onward[:-1, 1:] = np.minimum(rest_min[:-1, 1:], reach[1:, :-1])
    return np.maximum(here, onward).reshape(-1)[:n]


def _until_windows(phi: np.ndarray, psi: np.ndarray, start: np.ndarray, stop: np.ndarray, *,
                   past: bool) -> np.ndarray:
    """Until (since if ``past``) with any windows [start, stop) in rows of one run, such as
    the windows of a non-uniformly sampled run, in O(n log w) (w: the widest window).

    ρ(i) = min(min φ[i, s), G(s, e)) for the window [s, e) of row i (s >= i; since: until on
    the reversed run), where G(s, e) = max over j in [s, e) of min(ψ(j), min φ[s, j)) is the
    composition c_s ∘ … ∘ c_{e-1} of the clamps c_j(x) = max(ψ(j), min(φ(j), x)) applied to -inf
    (:func:`_until_from_here`). Clamps compose associatively, so G comes from one suffix
    composition and one prefix value at the level where s and e - 1 fall in adjacent aligned
    blocks (:func:`_clamp_levels`)."""
    n = len(phi)
    if past:  # since: until on the reversed run, windows mirrored
        return _until_windows(phi[::-1], psi[::-1], n - stop[::-1], n - start[::-1],
                              past=False)[::-1]
    rows = np.arange(n)
    start = np.maximum(start, rows)  # rows before i (equal time stamps) pass no φ: as before
    ok = stop > start
    out = np.full(n, -np.inf)
    if not ok.any():
        return out
    left, right = start[ok], stop[ok] - 1
    top = int((right - left).max()).bit_length()  # right - left < 2^top
    differ = np.bitwise_xor(left, right)
    level = np.zeros(len(left), dtype=np.int64)
    level[differ > 0] = np.floor(np.log2(differ[differ > 0])).astype(np.int64)
    level = np.minimum(level, top)
    reached = np.empty(len(left))
    for h, low, high, prefix in _clamp_levels(phi, psi, top):
        pick = level == h
        reached[pick] = _clip(prefix[right[pick]], low[left[pick]], high[left[pick]])
    head = window_reduce(phi, rows, start, maximum=False, empty=np.inf)
    out[ok] = np.minimum(head[ok], reached)
    return out


def _clamp_levels(phi: np.ndarray, psi: np.ndarray, top: int):
    """For h = 0 … ``top``, with the rows in aligned blocks of 2^h: (h, low, high, prefix) where
    [low, high] is the clamp composed from each row to the end of its block and prefix the
    clamps composed from the start of its block to the row, applied to -inf. One pass per
    level: a row in the left half of a block of 2^h extends its suffix by the whole right half
    (the suffix at the right half's first row); a row in the right half composes the whole left
    half in front of its prefix."""
    size = 1 << top
    pad = -len(phi) % size
    low = np.concatenate([psi, np.full(pad, -np.inf)])
    high = np.concatenate([np.maximum(phi, psi), np.full(pad, np.inf)])  # padding: identity
    prefix = low.copy()
    yield 0, low, high, prefix
    for h in range(1, top + 1):
        half = 1 << (h - 1)
        lo3, hi3, pre3 = (a.reshape(-1, 2, half) for a in (low, high, prefix))
        left_lo, left_hi = lo3[:, 0], hi3[:, 0]
        pre3[:, 1] = _clip(pre3[:, 1], left_lo[:, :1], left_hi[:, :1])  # the whole left half
        new_lo = _clip(lo3[:, 1, :1], left_lo, left_hi)  # then the whole right half
        new_hi = _clip(hi3[:, 1, :1], left_lo, left_hi)
        lo3[:, 0], hi3[:, 0] = new_lo, new_hi
        yield h, low, high, prefix


def _clip(x: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The clamp [low, high] applied to x (np.clip, without its checks: 3× faster here)."""
    return np.minimum(np.maximum(x, low), high)


def _until_offsets(phi: np.ndarray, psi: np.ndarray, start: np.ndarray, stop: np.ndarray, *,
                   past: bool) -> np.ndarray:
    """The reference for any windows ``start``/``stop`` in rows: a loop over window offsets,
    vectorised over all rows (O(n·w); the path for non-uniform sampling before issue 28, kept
    for the tests and the benchmark)."""
    n = len(phi)
    rows = np.arange(n)
    lo_off = int((rows - stop + 1).min()) if past else int((start - rows).min())
    hi_off = int((rows - start).max()) if past else int((stop - 1 - rows).max())
    out = np.full(n, -np.inf)
    running = np.full(n, np.inf)  # min of phi over the rows passed so far
    for d in range(0, max(hi_off, 0) + 1):
        j = rows - d if past else rows + d
        inside = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        in_window = inside & (jj >= start) & (jj < stop)
        if d >= max(lo_off, 0):
            out = np.where(in_window, np.maximum(out, np.minimum(psi[jj], running)), out)
        running = np.where(inside, np.minimum(running, phi[jj]), running)
    return out
