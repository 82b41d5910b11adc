"""What the data allow the fit to reach: measurement noise, glitches (outliers) and reversals.

Used by :func:`~simcred.scenario.fit.fit_track` (simcred's additions to [1] sec. II-B, which
fits positions by plain least squares and says nothing about noisy or broken data):

* :func:`position_noise` estimates the noise of the positions, the floor below which more
  sections only fit noise;
* :func:`glitches` finds isolated samples that jump away from the fitted track;
* :func:`reversals` finds where the direction of travel turns around at a stop (a vehicle that
  reverses), which a forward-driving description (v ≥ 0) cannot follow.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from simcred.scenario.spline import Spline

GLITCH_SIGMAS = 8.0
"""A sample is a glitch if it sticks out of its neighbourhood by more than this many noise σ..."""
GLITCH_FLOOR = 0.1
"""... and by more than this (m): smaller jumps are left to the fit."""
GLITCH_NEIGHBOURS = 4
"""Samples on one side that predict a sample (two on each side for the centred prediction)."""
MAX_GLITCH_FRACTION = 0.05
"""At most this fraction of the samples is set aside as glitches (the largest first) ..."""
MIN_GLITCH_SAMPLES = 5
"""... and at least one on a track of this many samples or more (a short track has glitches
too: before issue 24 a track under 20 samples could set none aside)."""
MOVING_SPEED = 1.0
"""Speed (m/s) above which the direction of travel is taken from the smoothed positions."""
REVERSAL_ANGLE = 2.0 * math.pi / 3.0
"""Direction change (rad) across a stop that counts as a reversal (120°)."""

REVERSAL_WINDOW = 1.0
"""Time (s) over which the measured displacement before and after a stop gives the direction."""
REVERSAL_DISTANCE = 0.5
"""Least displacement (m) in that time on both sides of a stop for a direction to count."""

_MAD_TO_SIGMA = 1.4826
_THIRD_DIFFERENCE_VARIANCE = 20.0  # Var(x[i+3] − 3x[i+2] + 3x[i+1] − x[i]) = 20 σ² for white noise
_SUBSETS = (np.arange(-GLITCH_NEIGHBOURS, 0), np.arange(1, GLITCH_NEIGHBOURS + 1),
            np.array([-2, -1, 1, 2]))  # neighbours before, after, and on both sides


def position_noise(x: np.ndarray, y: np.ndarray) -> float:
    """Robust estimate of the RMS position noise √(σx² + σy²) (m).

    From third differences, whose variance is 20 σ² for white noise while a smooth motion
    contributes only jerk · Δt³ (millimetres at 10 Hz); σ = 1.4826 · MAD / √20 per axis. Assumes
    near-uniform sampling. 0 for fewer than 8 samples.
    """
    if len(x) < 8:
        return 0.0
    sigmas = []
    for axis in (x, y):
        d3 = np.diff(axis, n=3)
        mad = np.median(np.abs(d3 - np.median(d3)))
        sigmas.append(_MAD_TO_SIGMA * mad / math.sqrt(_THIRD_DIFFERENCE_VARIANCE))
    return float(math.hypot(*sigmas))


def spikes(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """How far each sample lies from where its neighbours put it (m).

    For each of three neighbour sets of sample i — the 4 samples before it, the 4 after it,
    and i−2, i−1, i+1, i+2 — that has at least 3 samples on the track, a quadratic in time is
    fitted to x and to y by least squares and evaluated at tᵢ; the spike is the smallest
    distance from the measured position to those predictions. A glitch is far from every
    prediction; its innocent neighbour is close to the one made without the glitch, so the
    right sample is set aside also at a track's ends (the fit, whose end bends towards a
    displaced end sample, is not asked). ``inf`` where no set has 3 samples (n < 4).
    """
    best = np.full(len(t), np.inf)
    for jj, w, usable, c0 in _predictors(np.asarray(t, dtype=np.float64)):
        px = np.einsum("nk,nk->n", c0, (w * x[jj])[usable])
        py = np.einsum("nk,nk->n", c0, (w * y[jj])[usable])
        distance = np.hypot(px - x[usable], py - y[usable])
        best[usable] = np.minimum(best[usable], distance)
    return best


def _predictors(t: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    """Per neighbour set of :func:`spikes`: the neighbours' indices, their weights, the samples
    with 3 neighbours, and the rows that evaluate the quadratic at tᵢ. They depend on the times
    alone: cached for recent times (a variation campaign refits at the same times), the same
    numbers as computed anew."""
    if t.size > _CACHED_SAMPLES:
        return _predictors_of(t)
    return _predictors_cached(t.tobytes())


_CACHED_SAMPLES = 1 << 16


@lru_cache(maxsize=16)
def _predictors_cached(times: bytes) -> tuple[tuple[np.ndarray, ...], ...]:
    return _predictors_of(np.frombuffer(times))


def _predictors_of(t: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    n = len(t)
    out = []
    for offsets in _SUBSETS:
        j = np.arange(n)[:, None] + offsets  # (n, k)
        valid = (j >= 0) & (j < n)
        jj = np.clip(j, 0, n - 1)
        dt = np.where(valid, t[jj] - t[:, None], 0.0)
        scale = np.maximum(np.abs(dt).max(axis=1, keepdims=True), 1e-12)
        s = dt / scale
        w = valid.astype(float)
        design = np.stack([w, w * s, w * s * s], axis=-1)  # (n, k, 3), rows of absent samples 0
        usable = valid.sum(axis=1) >= 3
        c0 = np.linalg.pinv(design[usable])[:, 0, :]  # the quadratic's value at tᵢ
        for array in (jj, w, usable, c0):
            array.setflags(write=False)
        out.append((jj, w, usable, c0))
    return tuple(out)


def glitches(t: np.ndarray, x: np.ndarray, y: np.ndarray, noise: float) -> np.ndarray:
    """Samples that stick out of their neighbours (boolean mask).

    A sample is a glitch if its :func:`spikes` value exceeds max(8 σ, 0.1 m), σ = noise / √2 per
    axis; the largest first, at most 5 % of the samples but at least one on a track of
    :data:`MIN_GLITCH_SAMPLES` or more (none on shorter tracks).
    """
    n = len(t)
    mask = np.zeros(n, dtype=bool)
    if n < MIN_GLITCH_SAMPLES:
        return mask
    spike = spikes(t, x, y)
    cutoff = max(GLITCH_SIGMAS * noise / math.sqrt(2.0), GLITCH_FLOOR)
    candidates = np.flatnonzero(np.isfinite(spike) & (spike > cutoff))
    keep = max(1, int(MAX_GLITCH_FRACTION * n))
    mask[candidates[np.argsort(-spike[candidates], kind="stable")[:keep]]] = True
    return mask


def reversals(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[float, ...]:
    """Times where the direction of travel turns by more than 120° across a stop.

    Stops are where the speed of the positions smoothed by least-squares cubic splines (one
    section per second) is below 1 m/s between two stretches above it. The direction before a
    stop is the measured displacement over the 1 s before it, the direction after is that over
    the 1 s after it (both at least 0.5 m, else the stop is not judged: the smoothed speed can
    overshoot after a hard stop); if they differ by more than 120°, the object reversed and the
    middle of the stop is reported. A U-turn keeps moving while it turns and is not a reversal.
    """
    t0, t1 = float(t[0]), float(t[-1])
    sections = max(1, min(math.ceil(t1 - t0 - 1e-9), (len(t) - 4) // 2))
    dx = Spline.least_squares(t, x, t0=t0, t1=t1, sections=sections).derivative(t)
    dy = Spline.least_squares(t, y, t0=t0, t1=t1, sections=sections).derivative(t)
    moving = np.hypot(dx, dy) > MOVING_SPEED
    edges = np.flatnonzero(np.diff(moving.astype(np.int8)))
    stops, starts = edges[moving[edges]], edges[~moving[edges]]
    out = []
    for before in stops:  # last moving sample before a stop
        later = starts[starts > before]
        if not later.size:
            break
        after = later[0] + 1  # first moving sample after it
        came = _chord(t, x, y, t[before] - REVERSAL_WINDOW, t[before])
        went = _chord(t, x, y, t[after], t[after] + REVERSAL_WINDOW)
        if min(np.hypot(*came), np.hypot(*went)) < REVERSAL_DISTANCE:
            continue  # too little motion on one side to tell a direction
        turn = math.atan2(came[0] * went[1] - came[1] * went[0],
                          came[0] * went[0] + came[1] * went[1])
        if abs(turn) > REVERSAL_ANGLE:
            out.append(float(0.5 * (t[before] + t[after])))
    return tuple(out)


def _chord(t: np.ndarray, x: np.ndarray, y: np.ndarray, start: float, end: float
           ) -> tuple[float, float]:
    """Measured displacement from ``start`` to ``end`` (clamped to the track, interpolated)."""
    a, b = np.clip([start, end], t[0], t[-1])
    return (float(np.interp(b, t, x) - np.interp(a, t, x)),
            float(np.interp(b, t, y) - np.interp(a, t, y)))
