"""Whether a fitted track's acceleration is supported by the positions it was fitted to.

A fit can reach its position threshold while its speed spline swings: on a short noisy track
a cubic speed section bends its ends to follow the noise (a vehicle at constant 12 m/s with
3 cm noise, 10 samples: |v̇| up to 9 m/s² "reaching" 2 cm). The positions then do not carry
that acceleration. :func:`unsupported_acceleration` measures by how much the track's
acceleration leaves what the positions support:

* around each sample, the samples within :data:`WINDOW` / 2 (at least
  :data:`MIN_WINDOW_SAMPLES`, else the whole track) are fitted by a quadratic in time per axis
  (least squares); its tangential acceleration at the sample, (v · a) / |v|, is the
  **local acceleration** and 2 √(Var c₂) its standard error, with the position noise σ per
  axis (Var c₂ = σ² [(XᵀX)⁻¹]₂₂);
* the excess at the sample is |v̇_fit − a_local| − 3 SE; the result is the largest excess
  (m/s², ≤ 0 when everything is supported).

σ is the larger of the estimated noise and the fit's RMSE, each per axis (/√2): on a short
track the noise estimate is 0, and the RMSE bounds what the positions can resolve. A fit whose
excess exceeds :data:`PHANTOM_MARGIN` carries a **phantom acceleration** (flagged in
:class:`~simcred.scenario.fit_result.TrackFit`, ``phantom_acceleration``). The local quadratic
averages over :data:`WINDOW`; a real jerk of j m/s³ departs from that average by up to about
j · WINDOW / 2, so a hard braking onset with j > 4 m/s³ can be flagged too (it is a flag, read
with the fit, not a refusal).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from simcred.scenario.description import ObjectTrack

WINDOW = 1.0  # s
MIN_WINDOW_SAMPLES = 5
PHANTOM_MARGIN = 2.0  # m/s² of unsupported acceleration that flag a fit
_SIGMAS = 3.0


def local_acceleration(t: np.ndarray, x: np.ndarray, y: np.ndarray, noise: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Tangential acceleration of a local quadratic around each sample and its standard error
    (module docstring), NaN where fewer than 3 samples exist.

    Samples whose windows hold as many samples are fitted together (stacked normal equations,
    the same numbers as one window at a time: :func:`_local_acceleration_loop`, tested); times
    that do not increase strictly take that loop."""
    n = len(t)
    accel, error = np.full(n, np.nan), np.full(n, np.nan)
    if n < 3:
        return accel, error
    if not (np.diff(t) > 0).all():
        return _local_acceleration_loop(t, x, y, noise)
    sigma = noise / math.sqrt(2.0)
    for rows, near, inverse, project in _windows(np.asarray(t, dtype=np.float64)):
        cx = (project @ x[near][..., None])[..., 0]
        cy = (project @ y[near][..., None])[..., 0]
        # math.hypot as in the loop (np.hypot may round differently); the rest elementwise,
        # the same operations in the same order.
        speed = np.array([math.hypot(a, b) for a, b in zip(cx[:, 1].tolist(),
                                                           cy[:, 1].tolist(), strict=True)])
        ok = ~(speed < 1e-6)  # NaN too, as in the loop
        j, i = np.flatnonzero(ok), rows[ok]
        accel[i] = 2 * (cx[j, 1] * cx[j, 2] + cy[j, 1] * cy[j, 2]) / speed[j]
        error[i] = 2 * sigma * np.sqrt(np.maximum(inverse[j, 2, 2], 0.0))
    return accel, error


_CACHED_SAMPLES = 1 << 16


def _windows(t: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    """Per window size: the samples, their windows, (XᵀX)⁻¹ and (XᵀX)⁻¹Xᵀ. They depend on the
    times alone: cached for recent times (a variation campaign refits at the same times), the
    same numbers as computed anew."""
    if t.size > _CACHED_SAMPLES:
        return _windows_of(t)
    return _windows_cached(t.tobytes())


@lru_cache(maxsize=16)
def _windows_cached(times: bytes) -> tuple[tuple[np.ndarray, ...], ...]:
    return _windows_of(np.frombuffer(times))


def _windows_of(t: np.ndarray) -> tuple[tuple[np.ndarray, ...], ...]:
    n = len(t)
    half = WINDOW / 2 + 1e-9
    lo = np.searchsorted(t, t - half - 1e-6)
    hi = np.searchsorted(t, t + half + 1e-6, side="right")
    width = int((hi - lo).max())
    start, count = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    step = max(1, (1 << 20) // width)    # windows are contiguous: find their bounds in bands
    for i in range(0, n, step):
        j = slice(i, i + step)
        band = lo[j, None] + np.arange(width)
        inside = (band < hi[j, None]) & (np.abs(t[np.minimum(band, n - 1)] - t[j, None]) <= half)
        count[j] = inside.sum(axis=1)
        start[j] = lo[j] + np.argmax(inside, axis=1)
    whole = count < MIN_WINDOW_SAMPLES
    count[whole], start[whole] = n, 0
    out = []
    for k in np.unique(count):
        rows = np.flatnonzero(count == k)
        near = start[rows, None] + np.arange(k)
        tau = t[near] - t[rows, None]
        design = np.stack([np.ones_like(tau), tau, tau * tau], axis=-1)
        transposed = design.transpose(0, 2, 1)
        inverse = np.linalg.pinv(transposed @ design)
        project = inverse @ transposed
        for array in (rows, near, inverse, project):
            array.setflags(write=False)
        out.append((rows, near, inverse, project))
    return tuple(out)


def _local_acceleration_loop(t: np.ndarray, x: np.ndarray, y: np.ndarray, noise: float
                             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`local_acceleration` one window at a time (any order of times)."""
    n = len(t)
    accel, error = np.full(n, np.nan), np.full(n, np.nan)
    if n < 3:
        return accel, error
    sigma = noise / math.sqrt(2.0)
    for i in range(n):
        near = np.flatnonzero(np.abs(t - t[i]) <= WINDOW / 2 + 1e-9)
        if len(near) < MIN_WINDOW_SAMPLES:
            near = np.arange(n)
        tau = t[near] - t[i]
        design = np.column_stack([np.ones_like(tau), tau, tau * tau])
        inverse = np.linalg.pinv(design.T @ design)
        cx = inverse @ design.T @ x[near]
        cy = inverse @ design.T @ y[near]
        speed = math.hypot(cx[1], cy[1])
        if speed < 1e-6:
            continue
        accel[i] = 2 * (cx[1] * cx[2] + cy[1] * cy[2]) / speed
        error[i] = 2 * sigma * math.sqrt(max(inverse[2, 2], 0.0))
    return accel, error


def unsupported_acceleration(track: ObjectTrack, t: np.ndarray, x: np.ndarray, y: np.ndarray,
                             noise: float) -> float:
    """The largest excess of the track's v̇ over the positions' local acceleration (m/s²)."""
    accel, error = local_acceleration(t, x, y, noise)
    ok = np.isfinite(accel)
    if not ok.any():
        return 0.0
    fitted = track.speed.derivative(t[ok])
    return float(np.max(np.abs(fitted - accel[ok]) - _SIGMAS * error[ok]))
