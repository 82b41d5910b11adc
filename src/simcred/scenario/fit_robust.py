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
    Assessment of Automated Driving (seed 002), sec. II-B.
"""

from __future__ import annotations

import math

import numpy as np

from simcred.scenario.spline import Spline

GLITCH_SIGMAS = 8.0
"""A sample is a glitch if it sticks out of its neighbourhood by more than this many noise σ..."""
GLITCH_FLOOR = 0.1
"""... and by more than this (m): smaller jumps are left to the fit."""
GLITCH_NEIGHBOURS = 3
"""Samples on each side that define a sample's neighbourhood."""
MAX_GLITCH_FRACTION = 0.05
"""At most this fraction of the samples is set aside as glitches (the largest first)."""
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


def glitches(residuals: np.ndarray, noise: float) -> np.ndarray:
    """Samples whose residual sticks out of their neighbours' (boolean mask).

    Parameters
    ----------
    residuals : ndarray, shape (n, 2)
        Fitted minus measured position per sample.
    noise : float
        RMS position noise (m), :func:`position_noise`.

    Notes
    -----
    The spike of sample i is |rᵢ − median(rⱼ : 0 < |i − j| ≤ 3)| (component-wise median). A
    smooth misfit (too few sections) moves the residual smoothly and has small spikes; a glitch
    has a spike of its own size. A sample is a glitch if its spike exceeds
    max(8 σ, 0.1 m, 8 · median error) with σ = noise / √2 per axis (the last term: while the fit
    is still coarse, nothing is called a glitch), at most 5 % of the samples (the largest).
    """
    n = len(residuals)
    offsets = np.r_[-GLITCH_NEIGHBOURS:0, 1:GLITCH_NEIGHBOURS + 1]
    padded = np.full((n + 2 * GLITCH_NEIGHBOURS, 2), np.nan)
    padded[GLITCH_NEIGHBOURS:GLITCH_NEIGHBOURS + n] = residuals
    neighbours = padded[np.arange(n)[:, None] + GLITCH_NEIGHBOURS + offsets]  # (n, 6, 2)
    spikes = np.hypot(*(residuals - np.nanmedian(neighbours, axis=1)).T)
    errors = np.hypot(residuals[:, 0], residuals[:, 1])
    cutoff = max(GLITCH_SIGMAS * noise / math.sqrt(2.0), GLITCH_FLOOR,
                 GLITCH_SIGMAS * float(np.median(errors)))
    candidates = np.flatnonzero(spikes > cutoff)
    keep = int(MAX_GLITCH_FRACTION * n)
    chosen = candidates[np.argsort(-spikes[candidates], kind="stable")[:keep]]
    mask = np.zeros(n, dtype=bool)
    mask[chosen] = True
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
