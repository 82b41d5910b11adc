"""Regularisation that keeps the position fit physically plausible (simcred's, not [1]'s).

[1] sec. II-B fits v(t), θ(t) to positions only. On real tracks (noise, glitches, standstill)
the unconstrained fit chases the data into descriptions no vehicle can drive: v < 0, |v̇| of
hundreds of m/s², a heading spinning while the vehicle stands. :class:`FitConstraints` adds
residual rows, (piecewise) linear in the spline coefficients (so that Levenberg–Marquardt
converges about as fast as without them), on a grid of check times:

* **speed floor**: W_v · min(c_v,k − min_speed, 0) for every speed coefficient (W_v = 100), a
  one-sided hinge on the coefficients (its square is smooth): by the B-spline's convex-hull
  property, coefficients ≥ 0 give v(t) ≥ 0 at every time;
* **standstill**: where the smoothed measured speed v̂ is low, W · s(t) · θ̇(t) with
  s = 1 / (1 + (v̂ / 0.5 m/s)⁴) (W = 10): the heading is frozen while the vehicle stands;
  positions there hardly depend on θ, so nothing else fixes it;
* **smoothing** (only when needed): μ · v̇(t) / 1 m/s² and μ · θ̇(t) / 0.1 rad/s; the fit raises
  μ through :data:`SMOOTHING_STEPS` until the track is inside the plausibility limits.

The other rows are linear. After solving, the speed coefficients are clipped onto
[min_speed, max_speed] (the hinge leaves them at most millimetres per second outside), so that
v(t) ≥ 0 holds exactly at every time.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.interpolate import BSpline

from simcred.scenario.plausibility import PlausibilityLimits
from simcred.scenario.spline import DEGREE, spline_knots

STOP_SPEED = 0.5
"""Speed (m/s) at which the standstill weight s has fallen to one half."""
STOP_WEIGHT = 10.0
"""W of the standstill rows (per rad/s of yaw rate, against metres of position error)."""
FLOOR_WEIGHT = 100.0
"""Weight of the speed floor rows (per m/s of a speed coefficient below min_speed)."""
SMOOTHING_STEPS = (0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0)
"""μ tried in turn until the fitted track is inside the plausibility limits. As μ grows the track
tends to a straight line at constant speed, which is inside any limits that admit its speed."""
_ACCELERATION_SCALE = 1.0  # m/s²
_YAW_RATE_SCALE = 0.1  # rad/s


class FitConstraints:
    """Linear regularisation rows and their (constant) Jacobian on a check grid.

    Parameters
    ----------
    limits : PlausibilityLimits or None
        Speed limits for :meth:`clip_speed`; None: no standstill rows, no clipping.
    t0, t1 : float
        Span of the splines.
    sections : int
        Sections of the splines.
    grid : ndarray
        Check times in [t0, t1].
    measured_speed : ndarray
        Smoothed measured speed v̂ at ``grid`` (m/s), for the standstill weight.
    smoothing : float, default: 0.0
        μ.
    """

    def __init__(self, limits: PlausibilityLimits | None, t0: float, t1: float, sections: int,
                 grid: np.ndarray, measured_speed: np.ndarray, *, smoothing: float = 0.0) -> None:
        self.limits = limits
        n = sections + DEGREE
        b0, b1 = _bases(float(t0), float(t1), sections, grid)
        zeros = np.zeros_like(b0)
        stop = STOP_WEIGHT / (1.0 + (np.asarray(measured_speed) / STOP_SPEED) ** 4)
        stop_rows = stop > 1e-6 * STOP_WEIGHT if limits is not None else np.zeros(len(grid), bool)
        self._stop = (zeros[stop_rows], stop[stop_rows, None] * b1[stop_rows])
        self._smooth = (np.concatenate([b1 / _ACCELERATION_SCALE, zeros]),
                        np.concatenate([zeros, b1 / _YAW_RATE_SCALE]))
        self.smoothing = smoothing
        self._b0 = np.eye(n) if limits is not None else np.zeros((0, n))
        self._floor = 0.0 if limits is None else limits.min_speed

    def _linear(self) -> tuple[np.ndarray, np.ndarray]:
        mu = self.smoothing
        if not mu:
            return self._stop
        return (np.vstack([self._stop[0], mu * self._smooth[0]]),
                np.vstack([self._stop[1], mu * self._smooth[1]]))

    def jacobian(self, cv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂rows/∂c_v and ∂rows/∂c_θ: the speed floor's rows, then the linear rows."""
        d_cv, d_ch = self._linear()
        below = (self._b0 @ cv < self._floor)[:, None]
        floor = FLOOR_WEIGHT * below * self._b0
        return np.vstack([floor, d_cv]), np.vstack([np.zeros_like(floor), d_ch])

    def residuals(self, cv: np.ndarray, ch: np.ndarray) -> np.ndarray:
        """The rows: speed floor W_v · min(c_v − min_speed, 0), standstill, then (if μ > 0)
        smoothing."""
        d_cv, d_ch = self._linear()
        floor = FLOOR_WEIGHT * np.minimum(self._b0 @ cv - self._floor, 0.0)
        return np.concatenate([floor, d_cv @ cv + d_ch @ ch])

    def clip_speed(self, cv: np.ndarray) -> np.ndarray:
        """Speed coefficients clipped onto [min_speed, max_speed]: by the B-spline's convex hull
        property the speed then holds the bounds at every time, not only on the grid."""
        if self.limits is None:
            return cv
        return np.clip(cv, self.limits.min_speed, self.limits.max_speed)


def _bases(t0: float, t1: float, sections: int, grid: np.ndarray) -> tuple[np.ndarray, ...]:
    """The B-spline basis and its derivative at ``grid`` (read-only), cached for recent grids
    (the same computation): every refit of a variation campaign checks on the same grid."""
    grid = np.asarray(grid, dtype=np.float64)
    if grid.size > _CACHED_GRID:
        return _bases_of(t0, t1, sections, grid)
    return _bases_cached(t0, t1, sections, grid.tobytes())


_CACHED_GRID = 1 << 14


@lru_cache(maxsize=16)
def _bases_cached(t0: float, t1: float, sections: int, grid: bytes) -> tuple[np.ndarray, ...]:
    return _bases_of(t0, t1, sections, np.frombuffer(grid))


def _bases_of(t0: float, t1: float, sections: int, grid: np.ndarray) -> tuple[np.ndarray, ...]:
    basis = BSpline(spline_knots(t0, t1, sections), np.eye(sections + DEGREE), DEGREE,
                    extrapolate=False)
    out = (basis(grid), basis(grid, nu=1))
    for array in out:
        array.setflags(write=False)
    return out
