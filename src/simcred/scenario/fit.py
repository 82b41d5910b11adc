"""Fit the scenario description to measured positions, [1] sec. II-B.

"The description uses the curve representation in terms of velocity and heading but the data is
obtained by fitting the measured position data via equation (1)" [1]. :func:`fit_track` does this
for one object: nonlinear least squares of the positions integrated from v(t), θ(t) and (x0, y0)
against the measured ones, with an analytic Jacobian, adding spline sections until the position
error is small enough. :func:`fit_scenario` fits every object of a recording.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (seed 002), sec. II-B, eq. (1), Fig. 3; sec. III.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from simcred._json import JsonResult
from simcred.errors import OptionError, SimcredError
from simcred.scenario.description import ObjectTrack, ScenarioDescription
from simcred.scenario.fit_constraints import SMOOTHING_STEPS, FitConstraints
from simcred.scenario.fit_robust import glitches, position_noise, reversals
from simcred.scenario.plausibility import (
    VEHICLE_LIMITS,
    PlausibilityLimits,
    Reason,
    check_plausibility,
)
from simcred.scenario.spline import Quadrature, Spline, design_matrix
from simcred.traces import TIME, TraceSet

THRESHOLD = 0.05
"""Default position RMSE (m) at which the section search stops."""
MIN_GAIN = 0.1
"""Default least relative RMSE reduction per step for which more sections are worth it."""
PATIENCE = 3
"""Default number of consecutive steps below ``min_gain`` after which the search gives up."""
NOISE_FACTOR = 1.2
"""The search stops at the noise floor: RMSE ≤ this factor × the estimated position noise."""
GROWTH = 1.5
"""Default factor on the number of sections from one search step to the next."""
SECONDS_PER_SECTION = 4.0
"""The search starts with one section per this many seconds."""
MIN_SECONDS_PER_SECTION = 0.25
"""Default ``max_sections``: one section per this many seconds (and ≤ (samples − 4) / 2)."""
MIN_SAMPLES = 2
SHORT_TRACK = 8
"""Below this many samples the curves are also pulled towards constant v and θ (see fit_track)."""
SHORT_SMOOTHING = 0.01
"""Least smoothing μ on short tracks: a pull towards constant v and θ."""
_MOVING = 0.2  # m/s: below this the initial heading is interpolated, not measured


class StopReason(StrEnum):
    """Why the section search stopped: the threshold was reached, or why not."""

    THRESHOLD = "threshold"
    """The position RMSE reached the threshold."""
    NOISE_FLOOR = "noise_floor"
    """The RMSE is within 1.2 × the estimated position noise: the threshold lies below the
    noise of the data, and more sections would only fit noise."""
    STALLED = "stalled"
    """``patience`` consecutive steps each reduced the RMSE by less than ``min_gain``."""
    MAX_SECTIONS = "max_sections"
    """``max_sections`` was reached without meeting the threshold."""
    REVERSING = "reversing"
    """Not reached, and the object reverses (see ``reversals``): the description drives forward
    (v ≥ 0) and cannot follow the reversed part."""


@dataclass(frozen=True, slots=True, eq=False)
class TrackFit(JsonResult):
    """The fit of one object.

    Attributes
    ----------
    track : ObjectTrack
        The fitted description of the object.
    rmse : float
        √(mean((x̂ − x)² + (ŷ − y)²)) over the samples that are not glitches (m).
    max_error : float
        Largest Euclidean position error over those samples (m).
    sections : int
        Sections of the returned track.
    history : tuple of (int, float)
        (sections, rmse) of every step of the section search, in order.
    iterations : int
        Jacobian evaluations (solver iterations) summed over the search.
    stop_reason : StopReason
        Why the search stopped; :attr:`reached` says whether the threshold was met.
    threshold, min_gain : float
        The settings used.
    noise : float
        Estimated RMS position noise of the data (m).
    glitches : tuple of int
        Indices of samples set aside as glitches (outliers); not in ``rmse``.
    reversals : tuple of float
        Times (s) where the object reverses its direction of travel at a stop.
    violations : tuple of Reason
        Plausibility limits the track violates (checked every 0.01 s); empty unless the fit ran
        without limits.
    """

    track: ObjectTrack
    rmse: float
    max_error: float
    sections: int
    history: tuple[tuple[int, float], ...]
    iterations: int
    stop_reason: StopReason
    threshold: float
    min_gain: float
    noise: float = 0.0
    glitches: tuple[int, ...] = ()
    reversals: tuple[float, ...] = ()
    violations: tuple[Reason, ...] = ()

    def __repr__(self) -> str:
        return (f"TrackFit({self.sections} sections, rmse {self.rmse:.4g} m, "
                f"{self.stop_reason})")

    @property
    def reached(self) -> bool:
        """Whether the position RMSE reached the threshold."""
        return self.stop_reason is StopReason.THRESHOLD

    def to_dict(self) -> dict[str, Any]:
        """The fit's numbers (the track itself: ``track``'s JSON in a description)."""
        return {"sections": self.sections, "rmse": self.rmse, "max_error": self.max_error,
                "reached": self.reached, "stop_reason": str(self.stop_reason),
                "iterations": self.iterations, "history": [list(step) for step in self.history],
                "threshold": self.threshold, "min_gain": self.min_gain, "noise": self.noise,
                "glitches": list(self.glitches), "reversals": list(self.reversals),
                "violations": [str(r) for r in self.violations]}


@dataclass(frozen=True, slots=True, eq=False)
class ScenarioFit(JsonResult):
    """The fitted description and the fit of every object."""

    description: ScenarioDescription
    fits: Mapping[str, TrackFit]

    def __repr__(self) -> str:
        return f"ScenarioFit({', '.join(f'{k}: {v!r}' for k, v in self.fits.items())})"

    def to_dict(self) -> dict[str, Any]:
        """Per object, :meth:`TrackFit.to_dict`."""
        return {name: fit.to_dict() for name, fit in self.fits.items()}

    @property
    def rmse(self) -> float:
        """The worst object's position RMSE (m)."""
        return max(fit.rmse for fit in self.fits.values())


# -- one track ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Settings:
    threshold: float
    min_gain: float
    patience: int
    limits: PlausibilityLimits | None
    noise: float


# Long only by its numpydoc docstring; the code is short.
def fit_track(
    t: ArrayLike,
    x: ArrayLike,
    y: ArrayLike,
    *,
    threshold: float = THRESHOLD,
    min_gain: float = MIN_GAIN,
    patience: int = PATIENCE,
    max_sections: int | None = None,
    initial_sections: int | None = None,
    growth: float = GROWTH,
    limits: PlausibilityLimits | None = VEHICLE_LIMITS,
    length: float = 4.5,
    width: float = 1.8,
    name: str = "track",
) -> TrackFit:
    """Fit an :class:`ObjectTrack` to measured positions, [1] sec. II-B.

    Parameters
    ----------
    t, x, y : array_like, shape (n,)
        Sample times (s, strictly increasing) and positions (m); n ≥ 2. The track spans
        [t[0], t[-1]].
    threshold : float, default: 0.05
        Position RMSE (m) that ends the section search. 5 cm is negligible against the metre-scale
        inconsistencies of sensor data [1] sec. III, and above the 1 cm DGPS noise [1] sec. II-A,
        so that ground truth reaches it.
    min_gain : float, default: 0.1
        A step whose ``growth`` × more sections reduce the RMSE by less than this fraction makes
        no progress; ``patience`` such steps in a row end the search.
    patience : int, default: 3
        Steps without progress in a row after which the search gives up (``stalled``); ≤ 2 for an
        object that reverses (see ``reversals``), which the description cannot follow.
    max_sections : int, optional
        Upper bound on the sections; default one per 0.25 s, at most (n − 4) / 2 (at least 1).
    initial_sections : int, optional
        First step of the search; default one section per 4 s.
    growth : float, default: 1.5
        Sections of the next step: max(S + 1, ⌈growth · S⌉), capped at ``max_sections``.
    limits : PlausibilityLimits or None, default: VEHICLE_LIMITS
        Bounds on speed, acceleration and turning that the fitted curves hold
        (:mod:`~simcred.scenario.fit_constraints`); ``None`` fits positions alone, as [1] does.
    length, width : float, default: 4.5, 1.8
        Footprint stored in the track.
    name : str, default: "track"
        Names the object in error messages.

    Returns
    -------
    TrackFit
        With ``stop_reason`` saying whether the threshold was reached, or why not.

    Notes
    -----
    For S sections, the parameters are p = (x0, y0, c_v, c_θ), 2S + 8 numbers, and the residuals
    are the integrated positions minus the measured ones, (x̂(tᵢ) − xᵢ, ŷ(tᵢ) − yᵢ), plus the
    rows of :class:`~simcred.scenario.fit_constraints.FitConstraints` (a hinge that keeps the
    speed coefficients ≥ min_speed; θ̇ pulled to 0 where the vehicle stands; and, only for the
    returned fit and only while it violates ``limits``, smoothing of v̇ and θ̇). Positions use
    the description's own quadrature (:meth:`ObjectTrack.states`), so the Jacobian is exact for
    it: with Bₖ the B-spline basis and I[f](t) that cumulative quadrature of f,
    ∂x̂/∂c_v,k = I[Bₖ cos θ],
    ∂ŷ/∂c_v,k = I[Bₖ sin θ], ∂x̂/∂c_θ,k = −I[v sin θ Bₖ], ∂ŷ/∂c_θ,k = I[v cos θ Bₖ],
    ∂x̂/∂x0 = ∂ŷ/∂y0 = 1. The solver is ``scipy.optimize.least_squares(method="lm",
    x_scale="jac")``; the speed coefficients are finally clipped onto the speed limits, so that
    v ≥ 0 holds exactly.

    Section search: S grows until the RMSE reaches ``threshold`` (``threshold``), or reaches the
    noise floor, 1.2 × the estimated position noise (``noise_floor``), or makes no progress for
    ``patience`` steps (``stalled``), or hits ``max_sections``. For the last two the fewest
    sections within (1 + min_gain) of the best RMSE are kept. Within each step, samples whose
    residual jumps away from their neighbours' are set aside as glitches
    (:func:`~simcred.scenario.fit_robust.glitches`) and the step is solved again without them.
    Short tracks (n < 8) get a small extra pull (weight 0.01) towards v̇ = θ̇ = 0, which makes
    the 10 parameters of one section well defined by fewer than 10 position residuals.

    Initial guess (first step): x(t), y(t) are smoothed by least-squares cubic splines with one
    section per second; v = |(ẋ, ẏ)|, θ = unwrapped atan2(ẏ, ẋ) (interpolated where v < 0.2 m/s)
    are projected onto the S-section basis (θ weighted by v²/(v² + 0.25)); x0, y0 = mean offset.
    Later steps start from the previous solution projected onto the new basis.

    Deviation from [1]: the paper adds sections "until a threshold"; it does not say when to give
    up on data whose noise exceeds the threshold, nor bound the curves. The stop rules and
    ``limits`` are simcred's.

    Examples
    --------
    >>> t = np.linspace(0.0, 10.0, 501)
    >>> fit = fit_track(t, 20.0 * t, 0.5 * np.sin(0.3 * t))
    >>> fit.stop_reason.value, fit.rmse < 0.05, round(float(fit.track.speed(5.0)), 2)
    ('threshold', True, 20.0)
    """
    t, x, y = _fit_track_iv(t, x, y, name, threshold, min_gain, growth)
    patience = _positive_int(patience, "patience") or PATIENCE
    if limits is not None and not isinstance(limits, PlausibilityLimits):
        raise OptionError(f"limits must be PlausibilityLimits or None, got "
                          f"{type(limits).__name__}")
    duration = float(t[-1] - t[0])
    limit = _max_sections(max_sections, duration, len(t), name)
    sections = min(limit, _positive_int(initial_sections, "initial_sections")
                   or max(1, math.ceil(duration / SECONDS_PER_SECTION - 1e-9)))
    turns = reversals(t, x, y) if len(t) >= SHORT_TRACK else ()
    # A reversing object cannot be followed by a forward-driving description: give up early.
    settings = _Settings(float(threshold), float(min_gain),
                         min(2, patience) if turns else patience, limits, position_noise(x, y))
    data = (t, x, y, measured_speed(t, x, y))
    steps: list[_Step] = []
    while True:
        steps.append(_solve_step(data, sections, settings, steps[-1] if steps else None))
        reason = _stop(steps, settings, sections >= limit)
        if reason is StopReason.THRESHOLD and limits is not None:
            # Only the returned fit must be plausible: smooth it now; if that costs the
            # threshold, keep searching with more sections.
            steps[-1] = _plausible(data, steps[-1], settings)
            reason = _stop(steps, settings, sections >= limit)
        if reason is not None:
            break
        sections = min(limit, max(sections + 1, math.ceil(growth * sections - 1e-9)))
    chosen = _best(steps, reason, settings)
    best = chosen if limits is None else _plausible(data, chosen, settings)
    extra = best.iterations - chosen.iterations
    return _result(steps, best, extra, reason, settings, turns, length, width)


@dataclass(frozen=True, slots=True, eq=False)
class _Solution:
    t0: float
    t1: float
    sections: int
    params: np.ndarray
    rmse: float
    max_error: float
    iterations: int

    def track(self, length: float = 4.5, width: float = 1.8) -> ObjectTrack:
        return _track(self.t0, self.t1, self.sections, self.params, length, width)


def _track(t0: float, t1: float, sections: int, p: np.ndarray, length: float = 4.5,
           width: float = 1.8) -> ObjectTrack:
    n = sections + 3
    return ObjectTrack(float(p[0]), float(p[1]), Spline(t0, t1, p[2:2 + n]),
                       Spline(t0, t1, p[2 + n:]), length=length, width=width)


@dataclass(frozen=True, slots=True, eq=False)
class _Step:
    solution: _Solution
    glitches: np.ndarray
    iterations: int
    plausible: bool = False


def measured_speed(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> Spline:
    """|(ẋ, ẏ)| of positions smoothed by least-squares cubic splines, one section per second,
    itself as such a spline (the speed that decides where the vehicle stands)."""
    t0, t1 = float(t[0]), float(t[-1])
    sections = min(max(1, math.ceil(t1 - t0 - 1e-9)), max(1, (len(t) - 4) // 2))
    dx = Spline.least_squares(t, x, t0=t0, t1=t1, sections=sections).derivative(t)
    dy = Spline.least_squares(t, y, t0=t0, t1=t1, sections=sections).derivative(t)
    return Spline.least_squares(t, np.hypot(dx, dy), t0=t0, t1=t1, sections=sections)


def _plausible(data: tuple, step: _Step, settings: _Settings) -> _Step:
    """The step solved again, from its solution, with the smoothing raised until plausible."""
    if step.plausible:
        return step
    if not check_plausibility(step.solution.track(), settings.limits):
        return _Step(step.solution, step.glitches, step.iterations, True)
    t, x, y, speed = data
    keep = ~step.glitches
    problem = _Problem(t[keep], x[keep], y[keep], step.solution.sections,
                       span=(float(t[0]), float(t[-1])), limits=settings.limits)
    solution = problem.solve(step.solution.params, speed, plausible=True)
    return _Step(solution, step.glitches, step.iterations + solution.iterations, True)


def _solve_step(data: tuple, sections: int, settings: _Settings,
                previous: _Step | None) -> _Step:
    """One search step: solve, set glitches aside, solve again until the glitches settle."""
    t, x, y, speed = data
    glitch = np.zeros(len(t), dtype=bool) if previous is None else previous.glitches
    start_from = None if previous is None else previous.solution
    iterations = 0
    span = (float(t[0]), float(t[-1]))
    for _ in range(_GLITCH_PASSES):
        keep = ~glitch
        problem = _Problem(t[keep], x[keep], y[keep], sections, span=span,
                           limits=settings.limits)
        start = problem.initial_guess() if start_from is None \
            else problem.warm_start(start_from)
        solution = problem.solve(start, speed)
        iterations += solution.iterations
        if len(t) < SHORT_TRACK:
            break
        xh, yh = solution.track().positions(t)
        found = glitches(np.column_stack([xh - x, yh - y]), settings.noise)
        if np.array_equal(found, glitch):
            break
        glitch, start_from = found, solution
    return _Step(solution, glitch, iterations)


_GLITCH_PASSES = 3


def _stop(steps: list[_Step], settings: _Settings, at_limit: bool) -> StopReason | None:
    rmse = [step.solution.rmse for step in steps]
    if rmse[-1] <= settings.threshold:
        return StopReason.THRESHOLD
    if rmse[-1] <= NOISE_FACTOR * settings.noise:
        return StopReason.NOISE_FLOOR
    recent = rmse[-settings.patience - 1:]
    if len(recent) > settings.patience and all(
            before - after < settings.min_gain * before
            for before, after in zip(recent, recent[1:], strict=False)):
        return StopReason.STALLED
    return StopReason.MAX_SECTIONS if at_limit else None


def _best(steps: list[_Step], reason: StopReason, settings: _Settings) -> _Step:
    """The last step; after a failed search the fewest sections within (1 + min_gain) of the
    best RMSE."""
    if reason not in (StopReason.STALLED, StopReason.MAX_SECTIONS):
        return steps[-1]
    lowest = min(step.solution.rmse for step in steps)
    return next(step for step in steps if step.solution.rmse <= (1.0 + settings.min_gain) * lowest)


def _result(steps: list[_Step], best: _Step, extra: int, reason: StopReason,
            settings: _Settings, turns: tuple[float, ...], length: float, width: float
            ) -> TrackFit:
    if reason is StopReason.THRESHOLD and best.solution.rmse > settings.threshold:
        reason = StopReason.MAX_SECTIONS  # unreachable in practice: the search checks this
    if turns and reason is not StopReason.THRESHOLD:
        reason = StopReason.REVERSING
    track = best.solution.track(length, width)
    violations = () if settings.limits is None else tuple(
        check_plausibility(track, settings.limits))
    s = best.solution
    return TrackFit(track=track, rmse=s.rmse, max_error=s.max_error, sections=s.sections,
                    history=tuple((step.solution.sections, step.solution.rmse) for step in steps),
                    iterations=sum(step.iterations for step in steps) + extra,
                    stop_reason=reason,
                    threshold=settings.threshold, min_gain=settings.min_gain,
                    noise=settings.noise, glitches=tuple(int(i) for i in np.flatnonzero(
                        best.glitches)), reversals=turns, violations=violations)


class _Problem:
    """Residuals and analytic Jacobian of the position fit on one spline basis."""

    def __init__(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, sections: int, *,
                 span: tuple[float, float] | None = None,
                 limits: PlausibilityLimits | None = None) -> None:
        self.t, self.x, self.y = t, x, y
        self.t0, self.t1 = (float(t[0]), float(t[-1])) if span is None else span
        self.sections = sections
        self.n = sections + 3
        self.quad = Quadrature.build(self.t0, self.t1, sections, t)
        self.basis_full = design_matrix(self.t0, self.t1, sections, self.quad.full_nodes)
        self.basis_part = design_matrix(self.t0, self.t1, sections, self.quad.part_nodes)
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

    def warm_start(self, previous: _Solution) -> np.ndarray:
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
              plausible: bool = False) -> _Solution:
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
            if not check_plausibility(_track(self.t0, self.t1, self.sections, p),
                                      self.limits):
                break
        r = self.position_residuals(p)
        rows = len(self.t)
        squared = r[:rows] ** 2 + r[rows:] ** 2
        return _Solution(self.t0, self.t1, self.sections, p,
                         rmse=float(np.sqrt(np.mean(squared))),
                         max_error=float(np.sqrt(squared.max())), iterations=iterations)


    def _least_squares(self, p: np.ndarray) -> tuple[np.ndarray, int]:
        result = least_squares(self.residuals, p, jac=self.jacobian, method="lm",
                               x_scale="jac", ftol=1e-10, xtol=1e-10, gtol=1e-10,
                               max_nfev=100 * len(p))
        return result.x, int(result.njev or 0)


# -- validation -----------------------------------------------------------------------------------


def _fit_track_iv(t: ArrayLike, x: ArrayLike, y: ArrayLike, name: str, threshold: float,
                  min_gain: float, growth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    _options_iv(threshold, min_gain, growth)
    arrays = []
    for label, values in (("t", t), ("x", x), ("y", y)):
        try:
            a = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise SimcredError(f"object '{name}': column '{label}' is not numeric") from None
        if a.ndim != 1:
            raise SimcredError(f"object '{name}': column '{label}' must be 1-D, got shape "
                               f"{a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise SimcredError(f"object '{name}': column '{label}', sample {bad[0] + 1}: value "
                               f"is {a[bad[0]]} (values must be finite)")
        arrays.append(a)
    t, x, y = arrays
    if not len(t) == len(x) == len(y):
        raise SimcredError(f"object '{name}': columns t, x, y have different lengths "
                           f"({len(t)}, {len(x)}, {len(y)})")
    if len(t) < MIN_SAMPLES:
        raise SimcredError(f"object '{name}': {len(t)} samples, at least {MIN_SAMPLES} are "
                           "needed for a fit")
    step_ok = t[1:] > t[:-1]
    if not step_ok.all():
        i = int(np.flatnonzero(~step_ok)[0]) + 1
        raise SimcredError(f"object '{name}': time is not strictly increasing at sample {i + 1} "
                           f"(t={t[i]!r} after {t[i - 1]!r})")
    return t, x, y


def _positive_int(value: Any, label: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise OptionError(f"{label} must be an integer >= 1, got {value!r}")
    return int(value)


def _max_sections(value: int | None, duration: float, samples: int, name: str) -> int:
    identifiable = max(1, (samples - 4) // 2)
    given = _positive_int(value, "max_sections")
    if given is None:
        return min(identifiable, max(1, math.ceil(duration / MIN_SECONDS_PER_SECTION - 1e-9)))
    if given > identifiable:
        raise OptionError(f"object '{name}': max_sections={given} is more than the {samples} "
                          f"samples can identify (at most {identifiable})")
    return given


def _options_iv(threshold: float, min_gain: float, growth: float) -> None:
    if not (math.isfinite(threshold) and threshold > 0):
        raise OptionError(f"threshold must be a finite number > 0, got {threshold!r}")
    if not (math.isfinite(min_gain) and 0 <= min_gain < 1):
        raise OptionError(f"min_gain must be in [0, 1), got {min_gain!r}")
    if not (math.isfinite(growth) and growth > 1):
        raise OptionError(f"growth must be a finite number > 1, got {growth!r}")


# -- a whole scenario -----------------------------------------------------------------------------


def fit_scenario(
    traces: Mapping[str, Any] | TraceSet,
    *,
    objects: Sequence[str] | None = None,
    run: int = 0,
    dimensions: Mapping[str, tuple[float, float]] | None = None,
    dt: float | None = None,
    metadata: Mapping[str, Any] | None = None,
    threshold: float = THRESHOLD,
    min_gain: float = MIN_GAIN,
    max_sections: int | None = None,
    growth: float = GROWTH,
    limits: PlausibilityLimits | None = VEHICLE_LIMITS,
) -> ScenarioFit:
    """Fit every object of a recording, [1] sec. II-B.

    Parameters
    ----------
    traces : mapping or TraceSet
        Either ``{name: (t, x, y)}``; or one run ``{"t": ..., "<name>.x": ..., "<name>.y": ...}``
        (e.g. ``TraceSet.run(i)``); or a :class:`~simcred.traces.TraceSet`, of which run ``run``
        is used.
    objects : sequence of str, optional
        Objects to fit; default all (for a run: every ``<name>`` with both ``.x`` and ``.y``).
    run : int, default: 0
        Run of a TraceSet.
    dimensions : mapping of str to (length, width), optional
        Footprints; default 4.5 m × 1.8 m.
    dt : float, optional
        Sampling hint of the description; default the median sample step of the first object.
    metadata : mapping, optional
        Stored in the description, with a ``"fit"`` entry per object (sections, rmse, reason).
    threshold, min_gain, max_sections, growth, limits
        As in :func:`fit_track`, for every object.

    Returns
    -------
    ScenarioFit
    """
    series = _series(traces, objects, run)
    dims = dict(dimensions or {})
    fits = {}
    for name, (t, x, y) in series.items():
        length, width = dims.get(name, (4.5, 1.8))
        fits[name] = fit_track(t, x, y, threshold=threshold, min_gain=min_gain,
                               max_sections=max_sections, growth=growth, limits=limits,
                               length=length, width=width, name=name)
    if dt is None:
        first = np.asarray(next(iter(series.values()))[0], dtype=np.float64)
        dt = float(np.median(np.diff(first)))
    info = {name: {"sections": f.sections, "rmse": f.rmse, "reached": f.reached,
                   "stop_reason": f.stop_reason.value} for name, f in fits.items()}
    meta = {**dict(metadata or {}), "fit": {"threshold": threshold, "min_gain": min_gain,
                                            "objects": info}}
    description = ScenarioDescription({n: f.track for n, f in fits.items()}, dt=dt,
                                      metadata=meta)
    return ScenarioFit(description, fits)


def _series(traces: Mapping[str, Any] | TraceSet, objects: Sequence[str] | None, run: int
            ) -> dict[str, tuple[Any, Any, Any]]:
    if isinstance(traces, TraceSet):
        if not 0 <= run < traces.n_runs:
            raise OptionError(f"{traces.source}: run {run} does not exist "
                              f"({traces.n_runs} runs)")
        return _series_of_run(traces.run(run), objects, f"{traces.source}: run "
                                                          f"'{traces.run_ids[run]}'")
    if not isinstance(traces, Mapping) or not traces:
        raise SimcredError("traces must be a non-empty mapping {name: (t, x, y)} or a run "
                           "{'t': ..., '<name>.x': ..., '<name>.y': ...}")
    if TIME in traces:
        return _series_of_run(traces, objects, "run")
    names = list(traces) if objects is None else list(objects)
    out = {}
    for name in names:
        if name not in traces:
            raise SimcredError(f"object '{name}' is not in the traces (have: "
                               f"{', '.join(map(str, traces))})")
        try:
            t, x, y = traces[name]
        except (TypeError, ValueError):
            raise SimcredError(f"object '{name}': expected a (t, x, y) triple") from None
        out[name] = (t, x, y)
    return out


def _series_of_run(columns: Mapping[str, Any], objects: Sequence[str] | None, where: str
                   ) -> dict[str, tuple[Any, Any, Any]]:
    if objects is None:
        objects = [c[:-2] for c in columns if c.endswith(".x") and f"{c[:-2]}.y" in columns]
        if not objects:
            raise SimcredError(f"{where}: no '<name>.x' / '<name>.y' column pairs")
    out = {}
    for name in objects:
        for axis in ("x", "y"):
            if f"{name}.{axis}" not in columns:
                raise SimcredError(f"{where}: no column '{name}.{axis}' for object '{name}'")
        out[name] = (columns[TIME], columns[f"{name}.x"], columns[f"{name}.y"])
    return out
