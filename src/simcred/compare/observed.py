"""Comparison with an *observed* side: reality seen through a sensor (issue 23, the observation-
model route).

Real recordings are a noisy, delayed, biased and gappy observation of the process a simulation
writes as ground truth (Neurohr et al. 2023 [1] sec. V-B, Fig. 2 path b). Comparing them directly
spends the test's power on the sensor. Here the simulation's ground truth is pushed through a
:class:`SensorModel` — per signal an offset, a delay of whole samples, white noise and dropouts
that hold the last value — and the comparison is made at the observation level, where both sides
have passed through the same sensor.

The sensor model is declared (a datasheet, a JSON file) or estimated by :func:`estimate_sensor`
from pairs of recordings of the same runs (ground truth and sensor data, as the scenario-based
sensor model of Wagner et al. 2019 [2] §IV is estimated). An estimated model carries bootstrap
draws of its parameters (runs resampled); :func:`observe` draws one parameter set per run from
them, so the simulated observations include the sensor model's estimation uncertainty.

Assumptions (docs/observed.md): the sensor acts on each signal alone, is time-invariant and the
same for every run; its noise is white; a dropout holds the last recorded value (so an exact
repeat in a recording is a dropout; signals that repeat exactly on their own cannot be
calibrated this way); the delay is whole samples. Runs lose their first ``max delay`` samples,
which an observation would need from before the run started; the recording is cropped alike.

References
----------
[1] Neurohr et al., Criticality Analysis / simulation credibility via Markov chains and MMD, 2023.
[2] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simcred._json import fields_dict
from simcred.compare.result import Comparison
from simcred.errors import OptionError
from simcred.seeds import resolve_seed, stream
from simcred.traces import TraceSet, handed_over, spans

OBSERVE_KEY, SENSOR_EFFECT_KEY = 2**42, 2**42 + 1
SIDES = ("a", "b")


@dataclass(frozen=True, slots=True)
class SignalSensor:
    """What the sensor does to one signal: ``y_t = x_{t - delay} + offset + noise_sd · e_t``,
    and with probability ``dropout`` a sample is lost and the last recorded value is held.

    Parameters
    ----------
    offset : float
        Bias (the signal's unit).
    delay : float
        Latency (s), applied in whole samples of the run's period.
    noise_sd : float
        Standard deviation of white noise, ≥ 0.
    dropout : float
        Probability that a sample is lost (held), in [0, 1).
    """

    offset: float = 0.0
    delay: float = 0.0
    noise_sd: float = 0.0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        for name in ("offset", "delay", "noise_sd", "dropout"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise OptionError(f"sensor {name} must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.delay < 0 or self.noise_sd < 0:
            raise OptionError(f"sensor delay and noise_sd must be ≥ 0, got {self.delay!r}, "
                              f"{self.noise_sd!r}")
        if not 0 <= self.dropout < 1:
            raise OptionError(f"sensor dropout must be in [0, 1), got {self.dropout!r}")

    def lag(self, dt: float) -> int:
        return int(round(self.delay / dt))

    def to_dict(self) -> dict[str, float]:
        return fields_dict(self)


def _signal_sensors(given: Mapping[str, Any], where: str) -> dict[str, SignalSensor]:
    if not isinstance(given, Mapping) or not given:
        raise OptionError(f"{where}: a sensor model maps signal names to "
                          "{offset, delay, noise_sd, dropout}")
    out = {}
    for name, spec in given.items():
        if isinstance(spec, SignalSensor):
            out[str(name)] = spec
            continue
        if not isinstance(spec, Mapping):
            raise OptionError(f"{where}: signal '{name}' must be a mapping, got {spec!r}")
        unknown = set(spec) - {"offset", "delay", "noise_sd", "dropout"}
        if unknown:
            raise OptionError(f"{where}: signal '{name}' has unknown sensor field(s) "
                              f"{sorted(unknown)}")
        out[str(name)] = SignalSensor(**spec)
    return out


@dataclass(frozen=True, slots=True)
class SensorModel:
    """A sensor per signal, plus optional parameter draws that carry its estimation uncertainty.

    ``signals``: the point model; ``draws``: bootstrap draws (each a full ``signals`` mapping),
    empty for a declared model; ``fit``: how it was estimated (informative only).
    """

    signals: Mapping[str, SignalSensor]
    draws: tuple[Mapping[str, SignalSensor], ...] = ()
    fit: Mapping[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "signals", _signal_sensors(self.signals, "sensor model"))
        draws = tuple(_signal_sensors(d, "sensor model draw") for d in self.draws)
        for d in draws:
            if set(d) != set(self.signals):
                raise OptionError("sensor model: every draw must name the same signals "
                                  f"as the model ({sorted(self.signals)})")
        object.__setattr__(self, "draws", draws)

    def max_lag(self, dt: float) -> int:
        return max(s.lag(dt) for d in (self.signals, *self.draws) for s in d.values())

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"signals": {k: s.to_dict() for k, s in self.signals.items()}}
        if self.draws:
            out["draws"] = [{k: s.to_dict() for k, s in d.items()} for d in self.draws]
        if self.fit:
            out["fit"] = dict(self.fit)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = "sensor model") -> SensorModel:
        """``{"signals": {name: {offset, delay, noise_sd, dropout}}, "draws": [...]}``, or the
        bare ``{name: {...}}`` mapping of a declared model."""
        if not isinstance(data, Mapping):
            raise OptionError(f"{where}: expected a JSON object")
        if "signals" not in data:
            return cls(_signal_sensors(data, where))
        draws = data.get("draws", [])
        if not isinstance(draws, list):
            raise OptionError(f"{where}: 'draws' must be a list")
        return cls(_signal_sensors(data["signals"], where),
                   tuple(_signal_sensors(d, f"{where} draw {i}") for i, d in enumerate(draws)),
                   dict(data.get("fit", {})))

    @classmethod
    def read(cls, path: str | Path) -> SensorModel:
        """Read a sensor model from a JSON file (see :meth:`from_dict`)."""
        try:
            data = json.loads(Path(path).read_text())
        except OSError as err:
            raise OptionError(f"{path}: cannot read the sensor model ({err.strerror})") from None
        except json.JSONDecodeError as err:
            raise OptionError(f"{path}: not JSON (line {err.lineno}: {err.msg})") from None
        return cls.from_dict(data, str(path))

    def write(self, path: str | Path) -> Path:
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return Path(path)


def _period(traces: TraceSet, i: int) -> float:
    t = traces.time[traces.offsets[i]:traces.offsets[i + 1]]
    steps = np.diff(t)
    dt = float(steps[0])
    if not np.allclose(steps, dt, rtol=1e-6, atol=1e-9):
        raise OptionError(f"{traces.source}: run '{traces.run_ids[i]}' is not equally spaced; "
                          "resample it before applying a sensor model")
    return dt


def _check_signals(traces: TraceSet, sensor: SensorModel) -> None:
    missing = [name for name in sensor.signals if name not in traces.signals]
    if missing:
        raise OptionError(f"{traces.source}: the sensor model names signal(s) {missing} that "
                          f"the set does not have ({list(traces.signals)})")


def _crop_lags(traces: TraceSet, sensor: SensorModel) -> int:
    lags = {sensor.max_lag(_period(traces, i)) for i in range(traces.n_runs)}
    crop = max(lags)
    short = np.flatnonzero(traces.lengths <= crop + 1)
    if short.size:
        raise OptionError(f"{traces.source}: run '{traces.run_ids[short[0]]}' has "
                          f"{traces.lengths[short[0]]} samples, too few for the sensor delay of "
                          f"{crop} samples")
    return crop


def delay_steps(sensor: SensorModel, *sets: TraceSet) -> int:
    """The samples every run of ``sets`` loses so that the sensor's largest delay looks back into
    the run (the sensor's signals checked on each set; one line for a run too short)."""
    for traces in sets:
        _check_signals(traces, sensor)
    return max(_crop_lags(traces, sensor) for traces in sets)


def crop(traces: TraceSet, steps: int) -> TraceSet:
    """Every run without its first ``steps`` samples."""
    if steps == 0:
        return traces
    keep, offsets = spans(traces.offsets[:-1] + steps, traces.offsets[1:])
    return TraceSet(traces.signals, handed_over(traces.time[keep]),
                    handed_over(traces.values[keep]), offsets, traces.run_ids,
                    dict(traces.metadata), traces.source, traces.run_sources)


def _hold(values: np.ndarray, dropped: np.ndarray) -> np.ndarray:
    """Forward-fill ``values`` over ``dropped`` samples (the first sample is never dropped)."""
    index = np.where(dropped, 0, np.arange(len(values)))
    np.maximum.accumulate(index, out=index)
    return values[index]


def observe(traces: TraceSet, sensor: SensorModel, *, seed: int | np.random.Generator | None = None,
            crop_to: int | None = None) -> TraceSet:
    """``traces`` (ground truth) as the sensor would record them.

    Each run is pushed through the point model, or, when the model has ``draws``, through one draw
    chosen at random per run. Signals the model does not name are kept as they are. Every run
    loses its first ``crop_to`` samples (default: the model's largest delay in samples), which
    the delayed observation would need from before the run started.

    >>> from simcred.traces import TraceSet
    >>> ts = TraceSet.from_runs([{"t": [0, 1, 2, 3], "x": [0.0, 1.0, 2.0, 3.0]}])
    >>> observe(ts, SensorModel({"x": SignalSensor(offset=10, delay=1)})).column("x").tolist()
    [10.0, 11.0, 12.0]
    """
    _check_signals(traces, sensor)
    lost = _crop_lags(traces, sensor)
    lost = lost if crop_to is None else crop_to
    rng = np.random.default_rng(seed) if not isinstance(seed, np.random.Generator) else seed
    columns = {name: traces.signals.index(name) for name in sensor.signals}
    runs_values = []
    for i in range(traces.n_runs):
        dt = _period(traces, i)
        model = sensor.signals if not sensor.draws \
            else sensor.draws[int(rng.integers(len(sensor.draws)))]
        x = traces.values[traces.offsets[i]:traces.offsets[i + 1]]
        y = x[lost:].copy()
        n = len(y)
        for name, j in columns.items():
            s = model[name]
            lag = s.lag(dt)
            if lag > lost:
                raise OptionError(f"crop_to={crop_to} is smaller than the sensor delay of "
                                  f"signal '{name}' ({lag} samples)")
            seen = x[lost - lag:lost - lag + n, j] + s.offset + s.noise_sd * rng.normal(size=n)
            dropped = rng.random(n) < s.dropout
            dropped[0] = False
            y[:, j] = _hold(seen, dropped)
        runs_values.append(y)
    keep, offsets = spans(traces.offsets[:-1] + lost, traces.offsets[1:])
    metadata = {**traces.metadata, "observed_through": sensor.to_dict()}
    return TraceSet(traces.signals, handed_over(traces.time[keep]),
                    handed_over(np.concatenate(runs_values)), offsets, traces.run_ids,
                    metadata, traces.source, traces.run_sources)


# -- estimation ----------------------------------------------------------------------------------

def _pairs(truth: TraceSet, recorded: TraceSet, names: Sequence[str]) -> list[tuple[int, int]]:
    if truth.n_runs < 2:
        raise OptionError(f"{truth.source}: estimating a sensor model needs at least 2 paired "
                          f"runs, got {truth.n_runs}")
    index = {rid: i for i, rid in enumerate(recorded.run_ids)}
    pairs = []
    for i, rid in enumerate(truth.run_ids):
        if rid not in index:
            raise OptionError(f"{recorded.source}: no recording of run '{rid}' (ground truth and "
                              "sensor data are paired by run id)")
        k = index[rid]
        t_truth = truth.time[truth.offsets[i]:truth.offsets[i + 1]]
        t_rec = recorded.time[recorded.offsets[k]:recorded.offsets[k + 1]]
        if len(t_truth) != len(t_rec) or not np.allclose(t_truth, t_rec):
            raise OptionError(f"{recorded.source}: run '{rid}' is not sampled at the ground "
                              "truth's times")
        pairs.append((i, k))
    for name in names:
        for ts in (truth, recorded):
            if name not in ts.signals:
                raise OptionError(f"{ts.source}: no signal '{name}' to estimate its sensor from")
    return pairs


def _fit_signal(name: str, x: list[np.ndarray], y: list[np.ndarray], dt: float, max_lag: int
                ) -> SignalSensor:
    """One signal's sensor from paired runs (lists of 1-D arrays)."""
    repeats = np.concatenate([r[1:] == r[:-1] for r in y])
    dropout = float(repeats.mean())
    if dropout >= 1.0:
        raise OptionError(f"signal '{name}': its recording never changes from one sample to the "
                          "next, so dropouts cannot be told from the signal (module docs); "
                          "leave it out (--features)")
    best = None
    for lag in range(max_lag + 1):
        parts = []
        for xr, yr in zip(x, y, strict=True):
            fresh = np.r_[True, yr[1:] != yr[:-1]][lag:]
            parts.append((yr[lag:] - xr[:len(xr) - lag])[fresh])
        residual = np.concatenate(parts)
        if residual.size < 3:
            break
        score = float(np.var(residual))
        if best is None or score < best[0] - 1e-12:
            best = (score, lag, float(np.mean(residual)), float(np.std(residual, ddof=1)))
    if best is None:
        raise OptionError("too few fresh (not dropped) samples to estimate the sensor")
    _, lag, offset, sd = best
    return SignalSensor(offset=offset, delay=lag * dt, noise_sd=sd, dropout=dropout)


def estimate_sensor(truth: TraceSet, recorded: TraceSet, *, signals: Sequence[str] | None = None,
                    max_delay: float = 2.0, bootstrap: int = 200,
                    seed: int | np.random.Generator | None = None) -> SensorModel:
    """Estimate a :class:`SensorModel` from ground truth and sensor data of the same runs.

    Per signal: dropouts are the exact repeats of the recording; the delay is the shift (whole
    samples, up to ``max_delay`` s) whose residuals ``y_t − x_{t−lag}`` over the fresh samples
    have the least variance; offset and noise are their mean and standard deviation.
    ``bootstrap`` resamples of the runs give the parameter draws that carry the estimation
    uncertainty into :func:`observe` (0: a point model only).

    Raises
    ------
    OptionError
        Fewer than 2 paired runs, a run without its recording or sampled at other times, a signal
        missing, unequal periods, or too few fresh samples.
    """
    names = list(truth.signals if signals is None else signals)
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, int) or bootstrap < 0:
        raise OptionError(f"bootstrap must be a non-negative integer, got {bootstrap!r}")
    if not (isinstance(max_delay, (int, float)) and math.isfinite(max_delay) and max_delay >= 0):
        raise OptionError(f"max_delay must be a finite number ≥ 0, got {max_delay!r}")
    pairs = _pairs(truth, recorded, names)
    periods = {round(_period(truth, i), 9) for i, _ in pairs}
    if len(periods) != 1:
        raise OptionError(f"{truth.source}: runs with different sample periods {sorted(periods)}")
    dt = periods.pop()
    max_lag = int(math.floor(max_delay / dt + 1e-9))

    def column(ts: TraceSet, i: int, name: str) -> np.ndarray:
        return ts.values[ts.offsets[i]:ts.offsets[i + 1], ts.signals.index(name)]

    def fit(chosen: np.ndarray) -> dict[str, SignalSensor]:
        return {name: _fit_signal(name, [column(truth, pairs[c][0], name) for c in chosen],
                                  [column(recorded, pairs[c][1], name) for c in chosen],
                                  dt, max_lag) for name in names}

    point = fit(np.arange(len(pairs)))
    rng = np.random.default_rng(resolve_seed(seed))
    draws = tuple(fit(rng.integers(len(pairs), size=len(pairs))) for _ in range(bootstrap))
    return SensorModel(point, draws, {"runs": len(pairs), "period": dt,
                                      "bootstrap": bootstrap})


# -- the comparison ------------------------------------------------------------------------------

@dataclass(frozen=True, slots=True)
class ObservedComparison:
    """Result of :func:`compare_observed`.

    ``comparison``: the comparison at the observation level (the unobserved side pushed through
    ``sensor``, both sides cropped by ``cropped`` samples). ``sensor_effect``: when asked for, the
    unobserved side's ground truth against its own observation — how different the sensor alone
    makes a set look, the direct comparison's bias.
    """

    comparison: Comparison
    observed: str
    sensor: SensorModel
    cropped: int
    sensor_effect: Comparison | None = None

    @property
    def rejected(self) -> bool:
        """The chain-level verdict (run-level test) or the distance being positive."""
        chain = self.comparison.chain
        if chain is not None:
            return bool(chain.rejected)
        return bool(self.comparison.distance)

    def to_dict(self) -> dict[str, Any]:
        return {"observed": self.observed, "sensor": self.sensor.to_dict(),
                "cropped": self.cropped, "comparison": self.comparison.to_dict(),
                "sensor_effect": None if self.sensor_effect is None
                else self.sensor_effect.to_dict()}


def compare_observed(a: TraceSet | str | Path, b: TraceSet | str | Path, *, observed: str,
                     sensor: SensorModel | str | Path, seed: int | np.random.Generator | None
                     = None, sensor_effect: bool = False, **options: Any) -> ObservedComparison:
    """Compare two sets of runs of which one (``observed``) is a sensor's recording.

    The other side's ground truth is pushed through ``sensor`` (:func:`observe`, own seed
    stream), both sides lose the first ``max delay`` samples of every run, and
    :func:`~simcred.compare.compare` runs on the result with ``options``.

    Parameters
    ----------
    observed : {"a", "b"}
        The side that is a recording.
    sensor : SensorModel or path to its JSON
        Declared or estimated (:func:`estimate_sensor`); with draws, the estimation uncertainty.
    sensor_effect : bool, default False
        Also compare the unobserved side with its own observation (what the sensor alone does).
    """
    from simcred.compare.process import compare, load

    if observed not in SIDES:
        raise OptionError(f"observed must be 'a' or 'b', got {observed!r}")
    model = sensor if isinstance(sensor, SensorModel) else SensorModel.read(sensor)
    a, b = load(a), load(b)
    root = resolve_seed(seed)
    truth, recording = (b, a) if observed == "a" else (a, b)
    lost = delay_steps(model, recording, truth)
    pushed = observe(truth, model, seed=stream(root, OBSERVE_KEY), crop_to=lost)
    cropped = crop(recording, lost)
    pair = (cropped, pushed) if observed == "a" else (pushed, cropped)
    result = compare(*pair, seed=root, **options)
    effect = None
    if sensor_effect:
        own = observe(truth, model, seed=stream(root, SENSOR_EFFECT_KEY), crop_to=lost)
        effect = compare(crop(truth, lost), own, seed=root, **options)
    return ObservedComparison(result, observed, model, lost, effect)
