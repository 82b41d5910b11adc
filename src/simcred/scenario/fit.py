"""Fit the scenario description to measured positions, [1] sec. II-B.

"The description uses the curve representation in terms of velocity and heading but the data is
obtained by fitting the measured position data via equation (1)" [1]. :func:`fit_track` does this
for one object: nonlinear least squares of the positions integrated from v(t), θ(t) and (x0, y0)
against the measured ones, with an analytic Jacobian, adding spline sections until the position
error is small enough. :func:`fit_scenario` fits every object of a recording.

Modules: ``fit`` (this face: options, validation, whole recordings), ``fit_search`` (the
section search and its stop rules), ``fit_problem`` (one step's least squares and Jacobian),
``fit_result`` (:class:`TrackFit`, :class:`ScenarioFit`, :class:`StopReason`),
``fit_constraints`` (plausibility rows), ``fit_robust`` (noise, glitches, reversals).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B, eq. (1), Fig. 3; sec. III.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import OptionError, SimcredError
from simcred.kinematics import Track
from simcred.scenario.description import ScenarioDescription
from simcred.scenario.fit_problem import SHORT_SMOOTHING, SHORT_TRACK, measured_speed
from simcred.scenario.fit_result import ScenarioFit, StopReason, TrackFit
from simcred.scenario.fit_robust import position_noise, reversals
from simcred.scenario.fit_search import (
    NOISE_FACTOR,
    SearchSettings,
    search_result,
    search_sections,
)
from simcred.scenario.plausibility import VEHICLE_LIMITS, PlausibilityLimits
from simcred.traces import TIME, TraceSet

__all__ = [  # the fit's face; the result types and search constants are re-exported
    "GROWTH",
    "MIN_GAIN",
    "MIN_SAMPLES",
    "MIN_SECONDS_PER_SECTION",
    "NOISE_FACTOR",
    "PATIENCE",
    "SECONDS_PER_SECTION",
    "SHORT_SMOOTHING",
    "SHORT_TRACK",
    "THRESHOLD",
    "ScenarioFit",
    "StopReason",
    "TrackFit",
    "fit_scenario",
    "fit_track",
    "measured_speed",
]

THRESHOLD = 0.05
"""Default position RMSE (m) at which the section search stops."""
MIN_GAIN = 0.1
"""Default least relative RMSE reduction per step for which more sections are worth it."""
PATIENCE = 3
"""Default number of consecutive steps below ``min_gain`` after which the search gives up."""
GROWTH = 1.5
"""Default factor on the number of sections from one search step to the next."""
SECONDS_PER_SECTION = 4.0
"""The search starts with one section per this many seconds."""
MIN_SECONDS_PER_SECTION = 0.25
"""Default ``max_sections``: one section per this many seconds (and ≤ (samples − 4) / 2)."""
MIN_SAMPLES = 2


# -- one track ------------------------------------------------------------------------------------


def fit_track(
    t: ArrayLike, x: ArrayLike, y: ArrayLike, *, threshold: float = THRESHOLD,
    min_gain: float = MIN_GAIN, patience: int = PATIENCE, max_sections: int | None = None,
    initial_sections: int | None = None, growth: float = GROWTH,
    limits: PlausibilityLimits | None = VEHICLE_LIMITS, length: float = 4.5, width: float = 1.8,
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
    Nonlinear least squares of the positions integrated by eq. (1) from v(t), θ(t) and (x0, y0)
    against the measured ones, with an analytic Jacobian (:mod:`~simcred.scenario.fit_problem`),
    on more and more sections until a stop rule holds (:mod:`~simcred.scenario.fit_search`).

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
    settings = SearchSettings(float(threshold), float(min_gain),
                              min(2, patience) if turns else patience, limits,
                              position_noise(x, y))
    data = (t, x, y, measured_speed(t, x, y))
    steps, reason = search_sections(data, sections, limit, growth, settings)
    return search_result(data, steps, reason, settings, turns, length, width)


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
        Either ``{name: (t, x, y)}`` or ``{name: Track}``; or one run ``{"t": ...,
        "<name>.x": ..., "<name>.y": ...}`` (e.g. ``TraceSet.run(i)``); or a
        :class:`~simcred.traces.TraceSet`, of which run ``run`` is used.
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
        raise SimcredError("traces must be a non-empty mapping {name: Track or (t, x, y)} or a run "
                           "{'t': ..., '<name>.x': ..., '<name>.y': ...}")
    if TIME in traces:
        return _series_of_run(traces, objects, "run")
    names = list(traces) if objects is None else list(objects)
    out = {}
    for name in names:
        if name not in traces:
            raise SimcredError(f"object '{name}' is not in the traces (have: "
                               f"{', '.join(map(str, traces))})")
        value = traces[name]
        if isinstance(value, Track):
            out[name] = (value.t, value.x, value.y)
            continue
        try:
            t, x, y = value
        except (TypeError, ValueError):
            raise SimcredError(f"object '{name}': expected a Track or a (t, x, y) triple"
                               ) from None
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
