"""The least-squares problem of one section-search step of the scenario fit, [1] sec. II-B, eq. (1).

For S sections, the parameters are p = (x0, y0, c_v, c_θ), 2S + 8 numbers, and the residuals are
the integrated positions minus the measured ones, (x̂(tᵢ) − xᵢ, ŷ(tᵢ) − yᵢ), plus the rows of
:class:`~simcred.scenario.fit_constraints.FitConstraints` (a hinge that keeps the speed
coefficients ≥ min_speed; θ̇ pulled to 0 where the vehicle stands; and, only for the returned fit
and only while it violates the limits, smoothing of v̇ and θ̇). Positions use the description's
own quadrature (:meth:`ObjectTrack.states`), so the Jacobian is exact for it: with Bₖ the B-spline
basis and I[f](t) that cumulative quadrature of f,
∂x̂/∂c_v,k = I[Bₖ cos θ],
∂ŷ/∂c_v,k = I[Bₖ sin θ], ∂x̂/∂c_θ,k = −I[v sin θ Bₖ], ∂ŷ/∂c_θ,k = I[v cos θ Bₖ],
∂x̂/∂x0 = ∂ŷ/∂y0 = 1. The solver is ``scipy.optimize.least_squares(method="lm",
x_scale="jac")``; the speed coefficients are finally clipped onto the speed limits, so that
v ≥ 0 holds exactly. Short tracks (n < 8) get a small extra pull (weight 0.01) towards
v̇ = θ̇ = 0, which makes the 10 parameters of one section well defined by fewer than 10 position
residuals.

Initial guess (first step): x(t), y(t) are smoothed by least-squares cubic splines with one
section per second; v = |(ẋ, ẏ)|, θ = unwrapped atan2(ẏ, ẋ) (interpolated where v < 0.2 m/s)
are projected onto the S-section basis (θ weighted by v²/(v² + 0.25)); x0, y0 = mean offset.
Later steps start from the previous solution projected onto the new basis.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B, eq. (1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from simcred.scenario.description import ObjectTrack
from simcred.scenario.fit_constraints import SMOOTHING_STEPS, FitConstraints
from simcred.scenario.plausibility import PlausibilityLimits, check_plausibility
from simcred.scenario.spline import Quadrature, Spline, _design

SHORT_TRACK = 8
"""Below this many samples the curves are also pulled towards constant v and θ (see fit_track)."""
SHORT_SMOOTHING = 0.01
"""Least smoothing μ on short tracks: a pull towards constant v and θ."""
_MOVING = 0.2  # m/s: below this the initial heading is interpolated, not measured


@dataclass(frozen=True, slots=True, eq=False)
class Solution:
    """The least-squares solution of one step: parameters, position errors, solver work."""

    t0: float
    t1: float
    sections: int
    params: np.ndarray
    rmse: float
    max_error: float
    iterations: int

    def track(self, length: float = 4.5, width: float = 1.8) -> ObjectTrack:
        return track_from_params(self.t0, self.t1, self.sections, self.params, length, width)


def track_from_params(t0: float, t1: float, sections: int, p: np.ndarray,
                      length: float = 4.5, width: float = 1.8) -> ObjectTrack:
    """The track of parameters ``p`` = (x0, y0, c_v, c_θ) on ``sections`` sections."""
    n = sections + 3
    return ObjectTrack(float(p[0]), float(p[1]), Spline(t0, t1, p[2:2 + n]),
                       Spline(t0, t1, p[2 + n:]), length=length, width=width)


def measured_speed(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> Spline:
    """|(ẋ, ẏ)| of positions smoothed by least-squares cubic splines, one section per second,
    itself as such a spline (the speed that decides where the vehicle stands)."""
    t0, t1 = float(t[0]), float(t[-1])
    sections = min(max(1, math.ceil(t1 - t0 - 1e-9)), max(1, (len(t) - 4) // 2))
    dx = Spline.least_squares(t, x, t0=t0, t1=t1, sections=sections).derivative(t)
    dy = Spline.least_squares(t, y, t0=t0, t1=t1, sections=sections).derivative(t)
    return Spline.least_squares(t, np.hypot(dx, dy), t0=t0, t1=t1, sections=sections)


class PositionProblem:
    """Residuals and analytic Jacobian of the position fit on one spline basis."""

    def __init__(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, sections: int, *,
                 span: tuple[float, float] | None = None,
                 limits: PlausibilityLimits | None = None) -> None:
        self.t, self.x, self.y = t, x, y
        self.t0, self.t1 = (float(t[0]), float(t[-1])) if span is None else span
        self.sections = sections
        self.n = sections + 3
        self.quad = Quadrature.build(self.t0, self.t1, sections, t)
        # Both cached (read-only): refits at the same times share them.
        self.basis_full = _design(self.t0, self.t1, sections, self.quad.full_nodes)
        self.basis_part = _design(self.t0, self.t1, sections, self.quad.part_nodes)
        self.limits = limits
        self.short = len(t) < SHORT_TRACK
        self.constraints: FitConstraints | None = None
        self._cached: tuple[bytes, tuple[np.ndarray, ...]] | None = None

    # -- model ----------------------------------------------------------------------------------

    def _nodes(self, p: np.ndarray) -> tuple[np.ndarray, ...]:
        """v, cos θ, sin θ at the full and partial nodes (cached for the last p)."""
        key = p.tobytes()
        if self._cached is None or self._cached[0] != key:
            cv, ch = p[2:2 + self.n], p[2 + self.n:]
            values = []
            for basis in (self.basis_full, self.basis_part):
                v, theta = basis @ cv, basis @ ch
                values += [v, np.cos(theta), np.sin(theta)]
            self._cached = (key, tuple(values))
        return self._cached[1]

    def positions(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        vf, cf, sf, vp, cp, sp = self._nodes(p)
        # [1] eq. (1): ẋ = v cos θ, ẏ = v sin θ
        return (p[0] + self.quad.integrate(vf * cf, vp * cp),
                p[1] + self.quad.integrate(vf * sf, vp * sp))

    def position_residuals(self, p: np.ndarray) -> np.ndarray:
        xh, yh = self.positions(p)
        return np.concatenate([xh - self.x, yh - self.y])

    def residuals(self, p: np.ndarray) -> np.ndarray:
        r = self.position_residuals(p)
        if self.constraints is None:
            return r
        return np.concatenate([r, self.constraints.residuals(p[2:2 + self.n], p[2 + self.n:])])

    def jacobian(self, p: np.ndarray) -> np.ndarray:
        jac = self.jacobian_positions(p)
        if self.constraints is None:
            return jac
        d_cv, d_ch = self.constraints.jacobian(p[2:2 + self.n])
        return np.vstack([jac, np.hstack([np.zeros((len(d_cv), 2)), d_cv, d_ch])])

    def jacobian_positions(self, p: np.ndarray) -> np.ndarray:
        vf, cf, sf, vp, cp, sp = self._nodes(p)
        q, n, rows = self.quad, self.n, len(self.t)
        # Integrands per basis function: B cos θ, B sin θ, −v sin θ B, v cos θ B.
        full = np.stack([cf, sf, -vf * sf, vf * cf]) * q.full_weights
        part = np.stack([cp, sp, -vp * sp, vp * cp]) * q.part_weights
        per_interval = np.einsum("akg,kgj->kaj", full, self.basis_full)
        cumulative = np.concatenate([np.zeros((1, 4, n)), np.cumsum(per_interval, axis=0)])
        d = cumulative[q.index] + np.einsum("akg,kgj->kaj", part, self.basis_part)
        jac = np.zeros((2 * rows, 2 + 2 * n))
        jac[:rows, 0] = 1.0
        jac[rows:, 1] = 1.0
        jac[:rows, 2:2 + n], jac[rows:, 2:2 + n] = d[:, 0], d[:, 1]
        jac[:rows, 2 + n:], jac[rows:, 2 + n:] = d[:, 2], d[:, 3]
        return jac

    # -- starts and solve ---------------------------------------------------------------------

    def initial_guess(self) -> np.ndarray:
        t, t0, t1 = self.t, self.t0, self.t1
        smooth = min(max(self.sections, math.ceil(t1 - t0 - 1e-9)), max(1, (len(t) - 4) // 2))
        sx = Spline.least_squares(t, self.x, t0=t0, t1=t1, sections=smooth)
        sy = Spline.least_squares(t, self.y, t0=t0, t1=t1, sections=smooth)
        dx, dy = sx.derivative(t), sy.derivative(t)
        speed = np.hypot(dx, dy)
        moving = speed > _MOVING
        if moving.sum() >= 2:
            heading = np.interp(t, t[moving], np.unwrap(np.arctan2(dy[moving], dx[moving])))
        elif moving.any():
            heading = np.full_like(t, np.arctan2(dy[moving], dx[moving])[0])
        else:
            heading = np.zeros_like(t)
        weights = speed**2 / (speed**2 + 0.25) + 1e-9
        return self._with_offsets(
            Spline.least_squares(t, speed, t0=t0, t1=t1, sections=self.sections).coefficients,
            Spline.least_squares(t, heading, t0=t0, t1=t1, sections=self.sections,
                                 weights=weights).coefficients)

    def warm_start(self, previous: Solution) -> np.ndarray:
        """The previous solution's v and θ, projected onto this basis at the quadrature nodes."""
        old = previous.track()
        nodes = self.quad.full_nodes.ravel()
        cv = Spline.least_squares(nodes, old.speed(nodes), t0=self.t0, t1=self.t1,
                                  sections=self.sections).coefficients
        ch = Spline.least_squares(nodes, old.heading(nodes), t0=self.t0, t1=self.t1,
                                  sections=self.sections).coefficients
        return self._with_offsets(cv, ch)

    def _with_offsets(self, cv: np.ndarray, ch: np.ndarray) -> np.ndarray:
        """(x0, y0, cv, ch) with x0, y0 the least-squares offsets for the given curves."""
        p = np.concatenate([[0.0, 0.0], cv, ch])
        xh, yh = self.positions(p)
        p[0], p[1] = np.mean(self.x - xh), np.mean(self.y - yh)
        return p

    def solve(self, start: np.ndarray, measured_speed: Spline, *,
              plausible: bool = False) -> Solution:
        """Least squares; with limits and ``plausible``, the smoothing grows until the track is
        inside them."""
        p, iterations = start, 0
        grid = self.quad.grid
        use = self.limits is not None or self.short
        # Called with ``plausible`` only for an implausible solution: μ = 0 is known to fail.
        steps = SMOOTHING_STEPS[1:] if self.limits is not None and plausible else (0.0,)
        if use:
            self.constraints = FitConstraints(self.limits, self.t0, self.t1, self.sections,
                                              grid, np.abs(measured_speed(grid)))
        for mu in steps if use else (None,):
            if mu is not None:
                self.constraints.smoothing = max(mu, SHORT_SMOOTHING if self.short else 0.0)
            p, used = self._least_squares(p)
            iterations += used
            if self.limits is None:
                break
            p = p.copy()
            p[2:2 + self.n] = self.constraints.clip_speed(p[2:2 + self.n])
            if not check_plausibility(track_from_params(self.t0, self.t1, self.sections, p),
                                      self.limits):
                break
        r = self.position_residuals(p)
        rows = len(self.t)
        squared = r[:rows] ** 2 + r[rows:] ** 2
        return Solution(self.t0, self.t1, self.sections, p,
                        rmse=float(np.sqrt(np.mean(squared))),
                        max_error=float(np.sqrt(squared.max())), iterations=iterations)


    def _least_squares(self, p: np.ndarray) -> tuple[np.ndarray, int]:
        result = least_squares(self.residuals, p, jac=self.jacobian, method="lm",
                               x_scale="jac", ftol=1e-10, xtol=1e-10, gtol=1e-10,
                               max_nfev=100 * len(p))
        return result.x, int(result.njev or 0)
