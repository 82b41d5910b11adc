"""Local variation of a traffic object's trajectory, Wagner, Groh et al. [1] sec. V.

The traffic object's (TO's) path is cut into equitemporal sections. Its fix points
P_0 … P_n at the section bounds τ_0 = t0 < … < τ_n = t1 carry a piecewise cubic Bézier curve
(:class:`BezierPath`) that is C² at every inner fix point. Its inner control points follow from
C¹ and C² continuity and four end conditions: the velocity vectors at τ_0 and τ_n ([1] sec. V).
Only the fix points around the TO's crossing of the EGO's lane boundary are displaced, by seeded
random road-frame offsets. The varied path is sampled at the description's times and refitted
with :func:`~simcred.scenario.fit.fit_track`, which restores smooth v(t) and θ(t) ([1] sec. V,
second paragraph). Variations that break :class:`PlausibilityLimits` are rejected and counted by
reason.

Variation ``i`` draws only from ``stream(seed, i)``. It is therefore the same whether it is made
alone (:func:`vary_one`), within any ``n`` (:func:`generate_variations`) or on any Dask worker.

Deviations from [1], which leaves these open:

* The samples are the description's positions plus the *change* of the Bézier path,
  B(P + D) − B(P), not B(P + D) itself (``keep_residual``; see :func:`vary_one`).
* The offsets (truncated normal, road frame), the window (2 fix points each side of the crossing)
  and the section length (1 s) are simcred's choices (:class:`VariationOptions`).
* Plausibility limits and rejection by reason are simcred's; [1] keeps every variation and notes
  "a few outliers".
* The refit starts its section search at the original track's sections (``warm_sections``).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. V; sec. II-B (the fit).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.special import ndtr, ndtri

from simcred.engine import Engine, Progress, shared
from simcred.errors import OptionError, SimcredError
from simcred.kinematics import LANE_WIDTH
from simcred.scenario.bezier import BezierPath, array_iv
from simcred.scenario.description import (
    ObjectTrack,
    ScenarioDescription,
    sample_times,
)
from simcred.scenario.fit import THRESHOLD, fit_track
from simcred.scenario.plausibility import (
    PLAUSIBILITY_DT,
    PlausibilityLimits,
    Reason,
    check_plausibility,
)
from simcred.scenario.variation_set import (
    Variation,
    VariationOptions,
    VariationRecord,
    VariationSet,
    VariationStatus,
    is_real,
    variation_provenance,
)
from simcred.seeds import stream

# -- variation ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class _Plan:
    """Everything about one description's variations that does not depend on the index."""

    description: ScenarioDescription
    to: str
    options: VariationOptions
    limits: PlausibilityLimits
    fix_times: np.ndarray
    fix_points: np.ndarray
    start_velocity: np.ndarray
    end_velocity: np.ndarray
    varied: tuple[int, ...]
    crossing_time: float
    boundary_y: float | None
    threshold: float
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray


def _plan(description: ScenarioDescription, to: str, ego: str, options: VariationOptions,
          limits: PlausibilityLimits) -> _Plan:
    _objects_iv(description, to, ego)
    if not isinstance(options, VariationOptions):
        raise OptionError(f"options must be VariationOptions, got {type(options).__name__}")
    if not isinstance(limits, PlausibilityLimits):
        raise OptionError(f"limits must be PlausibilityLimits, got {type(limits).__name__}")
    track = description.objects[to]
    n = max(1, round((track.t1 - track.t0) / options.section))
    tau = np.linspace(track.t0, track.t1, n + 1)
    tau[0], tau[-1] = track.t0, track.t1
    t = sample_times(track.t0, track.t1, options.sample_dt or description.dt)
    if len(t) < 8:
        raise OptionError(f"sample_dt gives {len(t)} samples over the TO's span, at least 8 are "
                          "needed for the refit")
    x, y = track.positions(t)
    ends = track.states(np.array([track.t0, track.t1]))
    velocity = np.column_stack([ends.v * np.cos(ends.heading), ends.v * np.sin(ends.heading)])
    crossing, boundary = _crossing(track, description, options, to, ego)
    return _Plan(description, to, options, limits, tau, np.column_stack(track.positions(tau)),
                 velocity[0], velocity[1], _varied(tau, crossing, options.window, to),
                 crossing, boundary, _threshold(description, options), t, x, y)


def _crossing(track: ObjectTrack, description: ScenarioDescription, options: VariationOptions,
              to: str, ego: str) -> tuple[float, float | None]:
    """The first time the TO's y crosses a lane boundary (linear between samples 0.01 s apart):
    the given ``boundary_y``, the description's ``metadata["road"]["boundary_y"]``, or either
    boundary of the EGO's lane (:func:`_ego_lane_boundaries`), whichever is crossed first."""
    if options.crossing_time is not None:
        c = float(options.crossing_time)
        if not track.t0 <= c <= track.t1:
            raise OptionError(f"crossing_time {c!r} is outside the span of object '{to}' "
                              f"[{track.t0!r}, {track.t1!r}]")
        return c, None
    candidates = _boundaries(description, options, track.t0, ego)
    t = sample_times(track.t0, track.t1, PLAUSIBILITY_DT)
    y = track.positions(t)[1]
    found = [c for c in (_first_crossing(t, y, b) for b in candidates) if c is not None]
    if not found:
        where = " or ".join(f"y = {b!r} m" for b in candidates)
        raise SimcredError(f"object '{to}' never crosses the lane boundary {where} (y from "
                           f"{y.min():.3f} to {y.max():.3f} m); pass crossing_time, boundary_y "
                           "or crossing_side (--crossing-time, --boundary-y, --crossing-side)")
    return min(found)


def _boundaries(description: ScenarioDescription, options: VariationOptions, t0: float,
                ego: str) -> list[float]:
    """Lane boundaries to look for: the given one, the road's, else the EGO's lane's."""
    if options.boundary_y is not None:
        return [float(options.boundary_y)]
    road = description.metadata.get("road")
    given = road.get("boundary_y") if isinstance(road, Mapping) else None
    if options.crossing_side is None and is_real(given) and math.isfinite(given):
        return [float(given)]
    left, right = ego_lane_boundaries(description, ego, t0, options.lane_width)
    return {"left": [left], "right": [right]}.get(options.crossing_side, [left, right])


def ego_lane_boundaries(description: ScenarioDescription, ego: str, t: float,
                        lane_width: float = LANE_WIDTH) -> tuple[float, float]:
    """(left, right) boundary y (m) of the EGO's lane: the EGO's y at ``t`` (clipped to its
    span) ± ``lane_width`` / 2. The road runs along +x and the EGO is taken to be centred in
    its lane, as in simcred's scenarios and in recordings mapped onto the EGO's path."""
    track = description.objects[ego]
    centre = float(track.positions(np.array([min(max(t, track.t0), track.t1)]))[1][0])
    return centre + lane_width / 2, centre - lane_width / 2


def _first_crossing(t: np.ndarray, y: np.ndarray, boundary: float
                    ) -> tuple[float, float] | None:
    s = y - boundary
    change = np.flatnonzero((s[:-1] * s[1:] <= 0) & (s[:-1] != s[1:]))
    if change.size == 0:
        return None
    i = int(change[0])
    return float(t[i] + (t[i + 1] - t[i]) * s[i] / (s[i] - s[i + 1])), float(boundary)


def _varied(tau: np.ndarray, crossing: float, window: int, to: str) -> tuple[int, ...]:
    before = np.flatnonzero(tau <= crossing)[-window:]
    after = np.flatnonzero(tau > crossing)[:window]
    inner = [int(k) for k in np.concatenate([before, after]) if 0 < k < len(tau) - 1]
    if not inner:
        raise SimcredError(f"object '{to}': no inner fix point within {window} of the crossing "
                           f"at t = {crossing:.3f} s ({len(tau) - 1} sections): use a shorter "
                           "section")
    return tuple(inner)


def _threshold(description: ScenarioDescription, options: VariationOptions) -> float:
    if options.threshold is not None:
        return float(options.threshold)
    fit = description.metadata.get("fit")
    given = fit.get("threshold") if isinstance(fit, Mapping) else None
    if is_real(given) and math.isfinite(given) and given > 0:
        return float(given)
    return THRESHOLD


def draw_displacements(seed: int, index: int, count: int,
                       options: VariationOptions = VariationOptions()) -> np.ndarray:
    """The offsets of variation ``index``: shape (count, 2), columns longitudinal and lateral (m).

    Drawn from ``stream(seed, index)`` only: a uniform array U of shape (count, 2), mapped by the
    inverse normal CDF onto the normal law truncated at ± ``truncation`` σ
    (z = Φ⁻¹(Φ(−c) + (Φ(c) − Φ(−c)) U)), then scaled by (σ_lon, σ_lat); without truncation,
    ``standard_normal((count, 2))``. One draw per offset, no rejection loop.
    """
    _index_iv(index, seed)
    _count_iv(count, "count")
    rng = stream(seed, index)
    if options.truncation is None:
        z = rng.standard_normal((count, 2))
    else:
        low, high = ndtr(-options.truncation), ndtr(options.truncation)
        z = ndtri(low + (high - low) * rng.random((count, 2)))
    return z * np.array([options.sigma_lon, options.sigma_lat])


def vary_one(
    description: ScenarioDescription,
    index: int,
    seed: int,
    *,
    to: str = "to",
    ego: str = "ego",
    options: VariationOptions = VariationOptions(),
    limits: PlausibilityLimits = PlausibilityLimits(),
    displacements: ArrayLike | None = None,
) -> Variation:
    """Variation ``index`` of the TO's trajectory, [1] sec. V.

    Parameters
    ----------
    description : ScenarioDescription
        The original scenario.
    index : int
        Variation index (≥ 0); its offsets come from ``stream(seed, index)`` only.
    seed : int
        Seed of the variation set (≥ 0).
    to, ego : str, default: "to", "ego"
        The varied object, and the EGO (kept unchanged; it must exist and differ from ``to``).
    options : VariationOptions, default: VariationOptions()
        Sections, window, offsets, sampling, refit.
    limits : PlausibilityLimits, default: PlausibilityLimits()
        Bounds for rejection.
    displacements : array_like, shape (k, 2), optional
        Explicit offsets (m) for the k varied fix points instead of random ones.

    Returns
    -------
    Variation
        ``kept`` if the refitted track meets every limit; else rejected, with its reasons.

    Notes
    -----
    1. Fix points P_k = TO position at τ_k (equitemporal, ``options.section``); end velocities
       v (cos θ, sin θ) at the TO's t0 and t1 ([1] sec. V: "fix the velocity and heading values
       at the start of the first and at the end of the last Bézier curve").
    2. The fix points near the crossing get offsets D_k (see :func:`draw_displacements`); the
       varied Bézier path is B(P + D) (:meth:`BezierPath.through`).
    3. The path is sampled at t0 + j · ``sample_dt`` and refitted with
       :func:`~simcred.scenario.fit.fit_track` at the description's threshold ([1] sec. V,
       "applying again the fitting algorithm"); the refit replaces the TO's track.
    4. :func:`check_plausibility` on the refit (every 0.01 s) decides kept or rejected.

    Deviation from [1]: by default (``keep_residual``) the samples are the description's own
    positions plus B(P + D) − B(P), which by linearity of :meth:`BezierPath.through` is the
    path through the offsets D with zero end velocities. [1] samples B(P + D) itself; its
    residual against the description (5 cm RMSE, 16 cm max for 1 s sections on the reference
    cut-in, which brakes abruptly) would enter every variation, even the unvaried one. With
    ``keep_residual=False`` that is what happens. The change has the same locality
    (:func:`influence`) in both.
    """
    _index_iv(index, seed)
    plan = _plan(description, to, ego, options, limits)
    return _vary(plan, int(index), int(seed), displacements)


def _vary(plan: _Plan, index: int, seed: int, displacements: ArrayLike | None) -> Variation:
    k = len(plan.varied)
    if displacements is None:
        offsets = draw_displacements(seed, index, k, plan.options)
    else:
        offsets = array_iv(displacements, (k, 2), "displacements")
    moved = np.zeros_like(plan.fix_points)
    moved[list(plan.varied)] = offsets
    path = BezierPath.through(plan.fix_times, plan.fix_points + moved, plan.start_velocity,
                              plan.end_velocity)
    if plan.options.keep_residual:
        # B(P + D) − B(P) = B(D) with zero end velocities (the system is linear in P, v0, v1).
        # Deviation from [1] sec. V, which samples B(P + D): see the Notes of vary_one.
        shift = BezierPath.through(plan.fix_times, moved, np.zeros(2), np.zeros(2))(plan.t)
        xy = np.column_stack([plan.x, plan.y]) + shift
    else:
        xy = path(plan.t)
    original = plan.description.objects[plan.to]
    try:  # [1] sec. V: "applying again the fitting algorithm explained in section II-B"
        fit = fit_track(plan.t, xy[:, 0], xy[:, 1], threshold=plan.threshold,
                        initial_sections=original.sections if plan.options.warm_sections
                        else None, length=original.length, width=original.width, name=plan.to)
    except SimcredError:
        record = VariationRecord(index, offsets, math.nan, 0, VariationStatus.REJECTED,
                                 (Reason.REFIT_FAILED,))
        return Variation(record, plan.description, path)
    reasons = tuple(check_plausibility(fit.track, plan.limits, rmse=fit.rmse))
    record = VariationRecord(index, offsets, fit.rmse, fit.sections,
                             VariationStatus.REJECTED if reasons else VariationStatus.KEPT, reasons)
    metadata = {**plan.description.metadata,
                "variation": variation_provenance(record, seed, plan.to)}
    varied = ScenarioDescription({**plan.description.objects, plan.to: fit.track},
                                 dt=plan.description.dt, metadata=metadata)
    return Variation(record, varied, path)


def generate_variations(
    description: ScenarioDescription,
    n: int,
    seed: int | None,
    *,
    to: str = "to",
    ego: str = "ego",
    options: VariationOptions = VariationOptions(),
    limits: PlausibilityLimits = PlausibilityLimits(),
    runner: Engine | None = None,
    chunk_size: int = 50,
    progress: Progress | None = None,
) -> VariationSet:
    """Variations 0 … n − 1 of the TO's trajectory, [1] sec. V; see :func:`vary_one`.

    Parameters
    ----------
    description : ScenarioDescription
        The original scenario.
    n : int
        Variations to generate (≥ 1); kept and rejected ones are both counted.
    seed : int or None
        Seed (≥ 0). None draws fresh entropy, stored in the result so that it replays.
    to, ego, options, limits
        As in :func:`vary_one`.
    runner : Engine, optional
        Where chunks of indices run (e.g. a :class:`~simcred.engine.DaskEngine`); default
        in-process. The result does not depend on it.
    chunk_size : int, default: 50
        Indices per task.
    progress : callable, optional
        Wraps the chunks, e.g. in a progress bar.

    Returns
    -------
    VariationSet

    Examples
    --------
    >>> from simcred.scenario.fit import fit_track
    >>> t = np.linspace(0.0, 8.0, 81)
    >>> lane = 3.5 - 3.5 * np.clip((t - 2.0) / 4.0, 0.0, 1.0) ** 2 * (
    ...     3.0 - 2.0 * np.clip((t - 2.0) / 4.0, 0.0, 1.0))
    >>> to = fit_track(t, 30.0 + 25.0 * t, lane).track
    >>> ego = fit_track(t, 27.0 * t, 0.0 * t).track
    >>> base = ScenarioDescription({"ego": ego, "to": to}, dt=0.1)
    >>> result = generate_variations(base, 4, seed=1)
    >>> result.generated, round(result.crossing_time, 2), result.varied
    (4, 4.0, (3, 4, 5, 6))
    >>> result.kept + result.rejected == 4, result.records[2].displacements.shape
    (True, (4, 2))
    """
    plan = _plan(description, to, ego, options, limits)
    n = _count_iv(n, "n")
    chunk_size = _count_iv(chunk_size, "chunk_size")
    seed = int(np.random.SeedSequence().entropy) if seed is None else seed
    _index_iv(0, seed)
    chunks = [range(lo, min(lo + chunk_size, n)) for lo in range(0, n, chunk_size)]
    parts = (runner or Engine()).map(_vary_chunk, chunks,
                                     shared_values={"variation_plan": plan, "variation_seed": seed},
                                     progress=progress)
    done = [variation for part in parts for variation in part]
    original = plan.description.objects[to]
    return VariationSet(
        variations=tuple(v for v in done if v.kept),
        records=tuple(v.record for v in done), seed=int(seed), to=to, ego=ego,
        fix_times=plan.fix_times, varied=plan.varied, crossing_time=plan.crossing_time,
        boundary_y=plan.boundary_y, threshold=plan.threshold,
        original_reasons=tuple(check_plausibility(original, limits)),
        options=options, limits=limits, base=description)


def _vary_chunk(indices: range) -> list[Variation]:
    plan, seed = shared("variation_plan"), shared("variation_seed")
    return [_vary(plan, i, seed, None) for i in indices]


# -- validation -----------------------------------------------------------------------------------


def _count_iv(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise OptionError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _index_iv(index: Any, seed: Any) -> None:
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or index < 0:
        raise OptionError(f"index must be an integer >= 0, got {index!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise OptionError(f"seed must be an integer >= 0 (per-variation streams need an integer "
                          f"seed), got {seed!r}")


def _objects_iv(description: ScenarioDescription, to: str, ego: str) -> None:
    if not isinstance(description, ScenarioDescription):
        raise SimcredError(f"description must be a ScenarioDescription, got "
                           f"{type(description).__name__}")
    names = ", ".join(description.objects)
    for role, name in (("to", to), ("ego", ego)):
        if name not in description.objects:
            raise SimcredError(f"{role} object '{name}' is not in the description (have: {names})")
    if to == ego:
        raise OptionError(f"to and ego must be different objects, both are '{to}'")
