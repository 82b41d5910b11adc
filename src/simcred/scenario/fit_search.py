"""The section search of the scenario fit, [1] sec. II-B: more spline sections until the position
error is small enough, and the rules that stop it.

S grows until the RMSE reaches ``threshold`` (``threshold``), or reaches the noise floor,
1.2 × the estimated position noise (``noise_floor``), or makes no progress for ``patience``
steps (``stalled``), or hits ``max_sections``. For the last two the fewest sections within
(1 + min_gain) of the best RMSE are kept. Samples that lie far from where their neighbours put
them are set aside as glitches before the first step, from the data alone
(:func:`~simcred.scenario.fit_robust.glitches`), and every step is solved without them. With
plausibility limits, only the returned fit is smoothed until it holds them. Each step's least
squares: :mod:`simcred.scenario.fit_problem`.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simcred.scenario.fit_problem import PositionProblem, Solution
from simcred.scenario.fit_result import StopReason, TrackFit
from simcred.scenario.fit_robust import glitches
from simcred.scenario.fit_support import unsupported_acceleration
from simcred.scenario.plausibility import PlausibilityLimits, check_plausibility

NOISE_FACTOR = 1.2
"""The search stops at the noise floor: RMSE ≤ this factor × the estimated position noise."""


@dataclass(frozen=True, slots=True)
class SearchSettings:
    """The stop rules' settings and what they need of the data (its position noise)."""

    threshold: float
    min_gain: float
    patience: int
    limits: PlausibilityLimits | None
    noise: float


@dataclass(frozen=True, slots=True, eq=False)
class Step:
    """One search step: its solution, the samples set aside as glitches, the solver work."""

    solution: Solution
    glitches: np.ndarray
    iterations: int
    plausible: bool = False


def search_sections(data: tuple, sections: int, limit: int, growth: float,
                    settings: SearchSettings) -> tuple[list[Step], StopReason]:
    """Solve steps of ``sections``, growing by ``growth`` up to ``limit``, until a stop rule
    holds; ``data`` is (t, x, y, measured speed). The steps in order, and why the search stopped.
    """
    steps: list[Step] = []
    while True:
        steps.append(_solve_step(data, sections, settings, steps[-1] if steps else None))
        reason = _stop(steps, settings, sections >= limit)
        if reason is StopReason.THRESHOLD and settings.limits is not None:
            # Only the returned fit must be plausible: smooth it now; if that costs the
            # threshold, keep searching with more sections.
            steps[-1] = _plausible(data, steps[-1], settings)
            reason = _stop(steps, settings, sections >= limit)
        if reason is not None:
            return steps, reason
        sections = min(limit, max(sections + 1, math.ceil(growth * sections - 1e-9)))


def search_result(data: tuple, steps: list[Step], reason: StopReason, settings: SearchSettings,
                  turns: tuple[float, ...], length: float, width: float) -> TrackFit:
    """The :class:`TrackFit` of a finished search: the chosen step, made plausible."""
    chosen = _best(steps, reason, settings)
    best = chosen if settings.limits is None else _plausible(data, chosen, settings)
    extra = best.iterations - chosen.iterations
    return _result(data, steps, best, extra, reason, settings, turns, length, width)


def _plausible(data: tuple, step: Step, settings: SearchSettings) -> Step:
    """The step solved again, from its solution, with the smoothing raised until plausible."""
    if step.plausible:
        return step
    if not check_plausibility(step.solution.track(), settings.limits):
        return Step(step.solution, step.glitches, step.iterations, True)
    t, x, y, speed = data
    keep = ~step.glitches
    problem = PositionProblem(t[keep], x[keep], y[keep], step.solution.sections,
                              span=(float(t[0]), float(t[-1])), limits=settings.limits)
    solution = problem.solve(step.solution.params, speed, plausible=True)
    return Step(solution, step.glitches, step.iterations + solution.iterations, True)


def _solve_step(data: tuple, sections: int, settings: SearchSettings,
                previous: Step | None) -> Step:
    """One search step: the glitches (found once, from the data) set aside, solve."""
    t, x, y, speed = data
    glitch = glitches(t, x, y, settings.noise) if previous is None else previous.glitches
    keep = ~glitch
    problem = PositionProblem(t[keep], x[keep], y[keep], sections, span=(float(t[0]),
                                                                         float(t[-1])),
                              limits=settings.limits)
    start = problem.initial_guess() if previous is None \
        else problem.warm_start(previous.solution)
    solution = problem.solve(start, speed)
    return Step(solution, glitch, solution.iterations)


def _stop(steps: list[Step], settings: SearchSettings, at_limit: bool) -> StopReason | None:
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


def _best(steps: list[Step], reason: StopReason, settings: SearchSettings) -> Step:
    """The last step; after a failed search the fewest sections within (1 + min_gain) of the
    best RMSE."""
    if reason not in (StopReason.STALLED, StopReason.MAX_SECTIONS):
        return steps[-1]
    lowest = min(step.solution.rmse for step in steps)
    return next(step for step in steps if step.solution.rmse <= (1.0 + settings.min_gain) * lowest)


def _result(data: tuple, steps: list[Step], best: Step, extra: int, reason: StopReason,
            settings: SearchSettings, turns: tuple[float, ...], length: float, width: float
            ) -> TrackFit:
    if reason is StopReason.THRESHOLD and best.solution.rmse > settings.threshold:
        reason = StopReason.MAX_SECTIONS  # unreachable in practice: the search checks this
    if turns and reason is not StopReason.THRESHOLD:
        reason = StopReason.REVERSING
    track = best.solution.track(length, width)
    violations = () if settings.limits is None else tuple(
        check_plausibility(track, settings.limits))
    s = best.solution
    t, x, y, _ = data
    keep = ~best.glitches
    unsupported = unsupported_acceleration(track, t[keep], x[keep], y[keep],
                                           max(settings.noise, s.rmse))
    return TrackFit(track=track, rmse=s.rmse, max_error=s.max_error, sections=s.sections,
                    history=tuple((step.solution.sections, step.solution.rmse) for step in steps),
                    iterations=sum(step.iterations for step in steps) + extra,
                    stop_reason=reason,
                    threshold=settings.threshold, min_gain=settings.min_gain,
                    noise=settings.noise, glitches=tuple(int(i) for i in np.flatnonzero(
                        best.glitches)), reversals=turns, violations=violations,
                    unsupported_acceleration=unsupported)
