"""Calibrate a SUMO car-following model to recorded episodes: fit a few vType attributes.

The model is judged by replaying the episodes in SUMO (:func:`simcred.sim.sumo.replay`: the
recorded leader imposed, the follower starting from the recorded gap and speed) and comparing the
simulated follower with the recorded one, episode by episode.

Objective (:func:`objective`), dimensionless, smaller is better::

    J = mean over episodes e of ( NRMSE_e(gap) + NRMSE_e(v) ) / 2
    NRMSE_e(x) = sqrt(mean_k (x_sim[k] - x_rec[k])²) / sqrt(mean_k x_rec[k]²)

a normalised root-mean-square error of the bumper-to-bumper gap [m] and of the follower's speed
[m/s] over every time step of the episode (the "mixed" gap-and-speed measure of the car-following
calibration literature, e.g. Punzo, Montanino & Ciuffo 2021: gap alone leaves the speed free,
speed alone lets the gap drift). Each episode weighs the same whatever its length; the raw RMSEs
(m, m/s) are reported beside it (:func:`evaluate`).

Search (:func:`calibrate`): Nelder–Mead (``scipy.optimize.minimize``) in coordinates scaled to
[0, 1] per parameter between its bounds (so one simplex step means the same share of every range),
started from SUMO's passenger-car defaults, first simplex 10 % of each range, bounds enforced by
SciPy's clipping. Every evaluation is one seeded replay of all episodes; the result is rounded to
:data:`DIGITS` decimals (what a validation file or a command line can write literally) and the
objective is re-evaluated at the rounded values. Deterministic models (IDM ignores ``sigma``)
give the same result on every run.

:func:`halves` declares a split into a calibration and a held-out half by whole groups of
episodes (e.g. by recording file), so the held-out half shares no recording with the fit.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simcred.engine import engine
from simcred.errors import OptionError
from simcred.limits import check_count
from simcred.sim.sumo import SumoModel, parse_model, replay
from simcred.traces import RUN_INFO, TraceSet

#: vType attributes :func:`calibrate` may fit: (default bounds, SUMO's default, unit, meaning).
#: Bounds are physically sensible for a passenger car driven by a human: desired time headway
#: 0.5-3 s, comfortable acceleration 0.3-4 m/s², comfortable deceleration 0.5-6 m/s² (below
#: SUMO's emergencyDecel of 9 m/s²), standstill gap 0.5-6 m, IDM exponent 1-8, desired speed
#: 0.5-1.2 x the limit. Defaults: SUMO 1.28's passenger vType.
PARAMETERS: dict[str, tuple[tuple[float, float], float, str, str]] = {
    "tau": ((0.5, 3.0), 1.0, "s", "desired time headway"),
    "accel": ((0.3, 4.0), 2.6, "m/s²", "maximum (IDM: comfortable) acceleration"),
    "decel": ((0.5, 6.0), 4.5, "m/s²", "comfortable deceleration"),
    "minGap": ((0.5, 6.0), 2.5, "m", "standstill gap"),
    "delta": ((1.0, 8.0), 4.0, "", "IDM acceleration exponent"),
    "speedFactor": ((0.5, 1.2), 1.0, "", "desired speed / speed limit"),
}
#: The parameters fitted by default.
DEFAULT_PARAMETERS = ("tau", "accel", "decel", "minGap")
DIGITS = 3  # decimals of the fitted values
FIRST_STEP = 0.1  # first simplex: this share of each parameter's range


# -- objective ------------------------------------------------------------------------------------


def episode_errors(recorded: TraceSet, simulated: TraceSet) -> np.ndarray:
    """Per episode: RMSE of gap [m], RMSE of v [m/s], NRMSE of gap, NRMSE of v (``(n, 4)``).

    ``simulated`` must hold the same runs on the same time stamps as ``recorded`` (a replay of
    it); an episode whose recorded gap or speed is zero throughout has no NRMSE (one-line error).
    """
    if simulated.run_ids != recorded.run_ids:
        raise OptionError(f"{simulated.source}: the runs differ from those of {recorded.source} "
                          "(errors need the replay of the same episodes)")
    if simulated.time.shape != recorded.time.shape or not np.allclose(simulated.time,
                                                                      recorded.time):
        raise OptionError(f"{simulated.source}: time stamps differ from those of "
                          f"{recorded.source}")
    out = np.empty((recorded.n_runs, 4))
    for i in range(recorded.n_runs):
        rec, sim = recorded.run(i), simulated.run(i)
        for j, name in enumerate(("gap", "v")):
            scale = float(np.sqrt(np.mean(np.square(rec[name]))))
            if not scale > 0:
                raise OptionError(f"{recorded.source}: run '{recorded.run_ids[i]}': recorded "
                                  f"{name} is zero throughout (no relative error)")
            rmse = float(np.sqrt(np.mean(np.square(sim[name] - rec[name]))))
            out[i, j], out[i, 2 + j] = rmse, rmse / scale
    return out


def objective(recorded: TraceSet, simulated: TraceSet) -> float:
    """J = mean over episodes of (NRMSE(gap) + NRMSE(v)) / 2 (see the module doc)."""
    errors = episode_errors(recorded, simulated)
    return float(np.mean((errors[:, 2] + errors[:, 3]) / 2))


def evaluate(traces: TraceSet, model: SumoModel | str, *, seed: int = 0) -> dict[str, float]:
    """Replay ``traces`` with ``model``: the objective J, the mean per-episode RMSE of gap [m]
    and speed [m/s], and the number of episodes."""
    spec = model if isinstance(model, SumoModel) else parse_model(model)
    simulated = replay(traces, [spec], seed=seed)[spec.name]
    return _summary(episode_errors(traces, simulated))


def _summary(errors: np.ndarray) -> dict[str, float]:
    return {"objective": float(np.mean((errors[:, 2] + errors[:, 3]) / 2)),
            "rmse_gap_m": float(np.mean(errors[:, 0])),
            "rmse_v_mps": float(np.mean(errors[:, 1])), "episodes": int(len(errors))}


# -- the split ------------------------------------------------------------------------------------


def halves(traces: TraceSet, by: str = "file") -> tuple[list[str], list[str]]:
    """Two halves of the episodes by whole groups (``metadata["run_info"][run][by]``).

    Deterministic: groups sorted by size (largest first, ties by name), each put into the half
    with fewer episodes so far (the first half on a tie). Returns the run ids of the first half
    (for calibration) and of the second (held out), each in the set's order.
    """
    info = traces.metadata.get(RUN_INFO)
    if not isinstance(info, Mapping):
        raise OptionError(f"{traces.source}: no run_info metadata to split the episodes by {by!r}")
    groups: dict[str, list[str]] = {}
    for run in traces.run_ids:
        entry = info.get(run)
        if not isinstance(entry, Mapping) or by not in entry:
            raise OptionError(f"{traces.source}: run '{run}' has no {by!r} in its run_info")
        groups.setdefault(str(entry[by]), []).append(run)
    if len(groups) < 2:
        raise OptionError(f"{traces.source}: all episodes share one {by!r}; two halves by "
                          f"{by!r} need at least two groups")
    first: set[str] = set()
    second: set[str] = set()
    sizes = [0, 0]
    for name in sorted(groups, key=lambda g: (-len(groups[g]), g)):
        k = 0 if sizes[0] <= sizes[1] else 1
        (first, second)[k].update(groups[name])
        sizes[k] += len(groups[name])
    return ([r for r in traces.run_ids if r in first], [r for r in traces.run_ids if r in second])


# -- the fit --------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Calibration:
    """A fitted SUMO model: the start and fitted models, their objective and RMSEs on the
    calibration episodes, the search's facts."""

    model: SumoModel
    start: SumoModel
    bounds: Mapping[str, tuple[float, float]]
    before: Mapping[str, float]
    after: Mapping[str, float]
    evaluations: int
    converged: bool
    message: str
    seed: int
    runs: Sequence[str] = field(repr=False)

    @property
    def fitted(self) -> dict[str, float]:
        """The fitted values, by attribute name."""
        return {k: float(self.model.params[k]) for k in self.bounds}

    def model_text(self, separator: str = ",") -> str:
        """``IDM:tau=1.2,accel=0.8`` (:func:`~simcred.sim.sumo.parse_model`'s form; ``"+"`` for
        ``simcred simulate sumo-following --models``)."""
        return self.model.name.replace(",", separator)

    def to_dict(self) -> dict[str, Any]:
        return {"model": self.model.to_dict(), "start": self.start.to_dict(),
                "fitted": self.fitted, "bounds": {k: list(v) for k, v in self.bounds.items()},
                "objective": {"before": dict(self.before), "after": dict(self.after)},
                "search": {"method": "Nelder-Mead (scipy), scaled to [0, 1] per parameter",
                           "evaluations": self.evaluations, "converged": self.converged,
                           "message": self.message, "digits": DIGITS},
                "seed": self.seed, "episodes": len(self.runs)}


def _bounds(params: Sequence[str], bounds: Mapping[str, Sequence[float]] | None
            ) -> dict[str, tuple[float, float]]:
    if isinstance(params, str) or not params:
        raise OptionError("give the vType attributes to fit as a non-empty list, e.g. "
                          "['tau', 'accel']")
    out = {}
    for name in params:
        if name not in PARAMETERS:
            raise OptionError(f"cannot fit vType attribute {name!r}: choose from "
                              f"{', '.join(PARAMETERS)}")
        if name in out:
            raise OptionError(f"vType attribute {name!r} is given twice")
        given = (bounds or {}).get(name, PARAMETERS[name][0])
        try:
            lo, hi = (float(b) for b in given)
        except (TypeError, ValueError):
            raise OptionError(f"bounds of {name} must be two numbers (low, high), got {given!r}"
                              ) from None
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise OptionError(f"bounds of {name} must be finite with 0 < low < high, got "
                              f"({lo:g}, {hi:g})")
        out[name] = (lo, hi)
    extra = set(bounds or {}) - set(out)
    if extra:
        raise OptionError(f"bounds given for attributes that are not fitted: {sorted(extra)}")
    return out


def calibrate(traces: TraceSet, model: SumoModel | str = "IDM",
              params: Sequence[str] = DEFAULT_PARAMETERS, *,
              bounds: Mapping[str, Sequence[float]] | None = None,
              start: Mapping[str, float] | None = None, seed: int = 0,
              max_evaluations: int = 200, tolerance: float = 1e-3,
              log: Callable[[int, Mapping[str, float], float], None] | None = None
              ) -> Calibration:
    """Fit the vType attributes ``params`` of a SUMO model to the episodes of ``traces``.

    Parameters
    ----------
    traces : TraceSet
        Car-following episodes (``gap``, ``v``, ``v_leader``; uniform step), all used for the fit
        (split them first, e.g. with :func:`halves`).
    model : SumoModel or str, default: "IDM"
        The SUMO model; attributes it sets that are not fitted stay as they are.
    params : sequence of str, default: tau, accel, decel, minGap
        Attributes to fit, from :data:`PARAMETERS`.
    bounds : mapping, optional
        ``{name: (low, high)}`` replacing the default bounds of :data:`PARAMETERS`.
    start : mapping, optional
        Start values (default: the model's own value, else SUMO's default); inside the bounds.
    seed : int, default: 0
        Replay seed (:func:`~simcred.sim.sumo.replay`).
    max_evaluations : int, default: 200
        Most replays of all episodes the search may run (each takes ~5 ms per 10 s episode).
    tolerance : float, default: 1e-3
        Nelder–Mead stops when the simplex spans less than this share of every range and the
        objective less than this.
    log : callable, optional
        Called after every evaluation with (count, values, objective).

    Returns
    -------
    Calibration
        The fitted model (values rounded to :data:`DIGITS` decimals) and the objective before
        (at the start) and after (at the rounded values).
    """
    from scipy.optimize import minimize

    spec = model if isinstance(model, SumoModel) else parse_model(model)
    box = _bounds(params, bounds)
    check_count(max_evaluations, "runs", "max_evaluations")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise OptionError(f"tolerance must be a positive number, got {tolerance!r}")
    unknown = set(start or {}) - set(box)
    if unknown:
        raise OptionError(f"start values given for attributes that are not fitted: "
                          f"{sorted(unknown)}")
    first = {}
    for name, (lo, hi) in box.items():
        value = (start or {}).get(name, spec.params.get(name, PARAMETERS[name][1]))
        if not (isinstance(value, int | float) and lo <= value <= hi):
            raise OptionError(f"start value of {name} must be in [{lo:g}, {hi:g}], got {value!r}")
        first[name] = float(value)
    names = list(box)
    low = np.array([box[n][0] for n in names])
    span = np.array([box[n][1] - box[n][0] for n in names])
    cache: dict[tuple[float, ...], np.ndarray] = {}

    def make(values: Mapping[str, float]) -> SumoModel:
        return SumoModel(spec.model, {**spec.params, **values}, spec.name)

    with engine() as runner:
        def errors(values: Mapping[str, float]) -> np.ndarray:
            key = tuple(round(values[n], 9) for n in names)
            if key not in cache:
                sim = replay(traces, [make(values)], seed=seed, runner=runner)[spec.name]
                cache[key] = episode_errors(traces, sim)
                if log is not None:
                    log(len(cache), dict(values), _summary(cache[key])["objective"])
            return cache[key]

        def f(x: np.ndarray) -> float:
            values = low + np.clip(x, 0.0, 1.0) * span
            return _summary(errors(dict(zip(names, map(float, values), strict=True))))["objective"]

        x0 = (np.array([first[n] for n in names]) - low) / span
        simplex = [x0]
        for j in range(len(names)):
            step = np.zeros(len(names))
            step[j] = FIRST_STEP if x0[j] + FIRST_STEP <= 1 else -FIRST_STEP
            simplex.append(x0 + step)
        result = minimize(f, x0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(names),
                          options={"maxfev": max_evaluations, "xatol": tolerance,
                                   "fatol": tolerance, "initial_simplex": np.array(simplex)})
        best = low + np.clip(result.x, 0.0, 1.0) * span
        fitted = {n: float(np.clip(round(float(v), DIGITS), *box[n]))
                  for n, v in zip(names, best, strict=True)}
        before, after = _summary(errors(first)), _summary(errors(fitted))
    final = make(fitted)
    text = final.model + ":" + ",".join(f"{k}={v!r}" for k, v in final.params.items())
    return Calibration(model=SumoModel(final.model, final.params, text), start=make(first),
                       bounds=box, before=before, after=after, evaluations=len(cache),
                       converged=bool(result.success), message=str(result.message), seed=seed,
                       runs=list(traces.run_ids))


__all__ = ["DEFAULT_PARAMETERS", "PARAMETERS", "Calibration", "calibrate", "episode_errors",
           "evaluate", "halves", "objective"]
