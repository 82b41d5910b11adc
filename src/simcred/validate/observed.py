"""An observed reference in ``validate`` (issue 23, the observation-model route; docs/observed.md).

When the validation file declares ``reference: {observed: {sensor: ...}}``, the reference is a
sensor's recording of the process the candidates write as ground truth. Every candidate is then
pushed through the sensor model (:func:`simcred.compare.observed.observe`: offset, delay in whole
samples, white noise, held dropouts; one parameter draw per run when the model was estimated,
so its estimation uncertainty is carried into every cell), every run on both sides loses the
first *max delay* samples, and the per-cell engine compares the sets as it would compare direct
ones: cells are assigned, and responses compared, at the observation level on both sides.

The sensor alone is measured, not guessed: per candidate and test-case cell, the candidate's
ground truth against its own observation (a second, independent pass through the sensor),
paired run by run, by the same response comparison. Its deviation, in the tolerance's unit,
says how large a difference the sensor by itself makes — the bias a direct comparison would
carry.

Path b (the HMM, :mod:`simcred.compare.hidden`) is not a route here: the engine decides each
cell on a response deviation in the feature's unit per second with bootstrap bounds against the
tolerance; path b gives a distance between hidden transition rows and a p-value, with no
deviation in that unit, and it needs calibration runs that cover every hidden state in every
cell.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simcred.compare.observed import SensorModel, crop, delay_steps, observe
from simcred.errors import OptionError
from simcred.regions import engine
from simcred.regions.cells import Grid, segments
from simcred.regions.engine import CellResult
from simcred.seeds import named_stream
from simcred.traces import TraceSet
from simcred.validate.domain import cell_settings
from simcred.validate.spec import ValidationFileError, ValidationSpec

KEY = "reference.observed.sensor"
ROUTE = "observation model"
#: Seed streams of a candidate: its observation compared with the reference, and the second,
#: independent observation that measures the sensor alone.
OBSERVE_STREAM, EFFECT_STREAM = 0, 1
EFFECT_SUFFIX = "/sensor alone"  # the effect's cells are seeded apart from the domain's


def read_sensor(spec: ValidationSpec, base: Path) -> SensorModel | None:
    """The declared sensor model (None when the reference is compared as it is); one line
    naming :data:`KEY` for a file that cannot be read or is not a sensor model."""
    observed = spec.reference.observed
    if observed is None:
        return None
    try:
        if isinstance(observed.sensor, dict):
            return SensorModel.from_dict(observed.sensor, "declared sensor")
        path = Path(observed.sensor)
        return SensorModel.read(path if path.is_absolute() else base / path)
    except OptionError as exc:
        raise ValidationFileError(f"{KEY}: {exc}") from None


def sensor_source(spec: ValidationSpec) -> str:
    sensor = spec.reference.observed.sensor
    return "declared in the validation file" if isinstance(sensor, dict) else str(sensor)


@dataclass(frozen=True, slots=True, eq=False)
class Observation:
    """The observation level of one validation: the reference cropped, each candidate pushed
    through the sensor, the candidates' ground truth as read (``truths``), and (once measured)
    per candidate the sensor-alone cells."""

    sensor: SensorModel
    source: str
    cropped: int
    reference: TraceSet
    candidates: dict[str, TraceSet]
    truths: dict[str, TraceSet]
    effects: dict[str, tuple[CellResult, ...]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"reference": "observed", "route": ROUTE,
                "compared": "the reference's recording against each candidate pushed through "
                            "the sensor model; every run on both sides without its first "
                            f"{self.cropped} samples (the sensor's largest delay)",
                "sensor": sensor_summary(self.sensor, self.source),
                "cropped_samples": self.cropped,
                "sensor_alone": {n: [c.to_dict() for c in cells]
                                 for n, cells in self.effects.items()}}


def sensor_summary(sensor: SensorModel, source: str) -> dict[str, Any]:
    """Per signal the model's values; for an estimated model (draws) each value's 95 % interval
    over the draws (the estimation uncertainty the comparison carries)."""
    signals = {}
    for name, point in sensor.signals.items():
        row: dict[str, Any] = dict(point.to_dict())
        if sensor.draws:
            values = {k: np.array([d[name].to_dict()[k] for d in sensor.draws]) for k in row}
            row["interval_95"] = {k: [float(np.quantile(v, 0.025)), float(np.quantile(v, 0.975))]
                                  for k, v in values.items()}
        signals[name] = row
    kind = "estimated" if sensor.draws else "declared"
    return {"source": source, "kind": kind, "draws": len(sensor.draws),
            "fit": dict(sensor.fit), "signals": signals}


def observation_level(spec: ValidationSpec, sensor: SensorModel, reference: TraceSet,
                      candidates: dict[str, TraceSet]) -> Observation:
    """The reference cropped by the sensor's largest delay, each candidate's ground truth pushed
    through the sensor (its own seed stream: independent of the order of candidates)."""
    seed = spec.comparison.seed
    try:
        lost = delay_steps(sensor, reference, *candidates.values())
        seen = {n: observe(t, sensor, seed=named_stream(seed, n, OBSERVE_STREAM), crop_to=lost)
                for n, t in candidates.items()}
    except OptionError as exc:
        raise ValidationFileError(f"{KEY}: {exc}") from None
    return Observation(sensor, sensor_source(spec), lost, crop(reference, lost), seen,
                       dict(candidates))


def with_sensor_alone(observation: Observation, spec: ValidationSpec, grid: Grid,
                      relevant: tuple[int, ...]) -> Observation:
    """``observation`` with, per candidate and test-case cell, its ground truth compared with
    its own (independent) observation, paired run by run (module docs)."""
    settings = cell_settings(spec)
    rule = engine.cell_rule(spec.comparison.alpha, len(relevant), replay=True)
    effects = {}
    for name, truth in observation.truths.items():
        own = observe(truth, observation.sensor, crop_to=observation.cropped,
                      seed=named_stream(spec.comparison.seed, name, EFFECT_STREAM))
        truth = crop(truth, observation.cropped)
        truth_cells = segments(truth, grid, settings.min_length).by_cell
        own_cells = segments(own, grid, settings.min_length).by_cell
        effects[name] = tuple(
            engine.compare_cell(settings, grid, cell, name + EFFECT_SUFFIX, rule,
                                truth_cells.get(cell), own_cells.get(cell))
            for cell in relevant)
    return replace(observation, effects=effects)
