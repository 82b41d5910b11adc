"""Resimulation of scenario descriptions ([1] §II-C), many at once.

Traffic objects follow their descriptions exactly (sampled at every step: a perfect trajectory
follower); the EGO starts from its described state at ``t0`` and is driven by the AD function
through a vehicle model (KS by default) and a sensor model (ideal or scenario-based). All
descriptions of one call share the time grid ``t0 + k dt`` of the first one and are simulated
as one batch; run ``i`` draws its sensor noise from ``stream(seed, i)`` only.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simcred.errors import SimcredError
from simcred.kinematics import MOTION_SIGNALS, TIME_TOLERANCE
from simcred.limits import check_count
from simcred.scenario.description import ScenarioDescription
from simcred.seeds import stream
from simcred.sim.campaign import run_id
from simcred.sim.closed_loop import LoopRecord, run_closed_loop
from simcred.sim.driver import ADFunction, DriverConfig
from simcred.sim.sensors import IdealSensor, Sensor
from simcred.sim.vehicles import vehicle_model
from simcred.traces import TIME, TraceSet

MODE_SIGNAL = "ad.mode"


def time_grid(description: ScenarioDescription, dt: float) -> np.ndarray:
    """``t0 + k dt`` for every k that stays inside the description's span (at most the
    ``steps`` limit of :mod:`simcred.limits`: a one-line error before any work)."""
    steps = int(np.floor((description.t1 - description.t0) / dt + TIME_TOLERANCE)) + 1
    check_count(steps, "steps", f"a resimulation of {description.t1 - description.t0:g} s at "
                f"dt {dt:g} s: steps")
    return description.t0 + np.arange(steps) * dt


def resimulate(descriptions: ScenarioDescription | Sequence[ScenarioDescription], *,
               sensor: Sensor | None = None, vehicle: str = "ks",
               driver: DriverConfig | None = None, dt: float = 0.01, seed: int = 0,
               ego: str = "ego", indices: Sequence[int] | None = None) -> TraceSet:
    """Resimulate every description; one run each, named ``run_id(index)``.

    Returns a :class:`~simcred.traces.TraceSet` with ``ego.x, .y, .v, .heading``, the same for
    every other object (as followed), and ``ad.mode`` (0 cruise, 1 brake, 2 evade).
    """
    batch = [descriptions] if isinstance(descriptions, ScenarioDescription) else list(descriptions)
    if not batch:
        raise SimcredError("nothing to resimulate: no scenario descriptions")
    names = _object_names(batch, ego)
    t = time_grid(batch[0], dt)
    indices = list(range(len(batch))) if indices is None else list(indices)
    record = simulate_batch(batch, names, t, sensor=sensor, vehicle=vehicle, driver=driver,
                            seed=seed, ego=ego, indices=indices)
    return _traceset(record, t, names, ego, [run_id(i) for i in indices])


def simulate_batch(batch: Sequence[ScenarioDescription], names: Sequence[str], t: np.ndarray,
                   *, sensor: Sensor | None, vehicle: str, driver: DriverConfig | None,
                   seed: int, ego: str, indices: Sequence[int]) -> LoopRecord:
    """The closed loop over ``batch`` on times ``t`` (see :func:`resimulate`)."""
    dt = float(t[1] - t[0])
    objects = np.stack([_object_states(d, names, t) for d in batch])
    start = np.array([_ego_start(d, ego) for d in batch])
    noise = np.stack([stream(seed, i).standard_normal((len(t), len(names), 2))
                      for i in indices])
    return run_closed_loop(vehicle_model(vehicle), start, objects,
                           IdealSensor() if sensor is None else sensor,
                           ADFunction(DriverConfig() if driver is None else driver), dt, noise)


def _object_names(batch: Sequence[ScenarioDescription], ego: str) -> list[str]:
    names = [n for n in batch[0].objects if n != ego]
    for k, description in enumerate(batch):
        if ego not in description.objects:
            raise SimcredError(f"description {k} has no EGO object '{ego}'")
        if [n for n in description.objects if n != ego] != names:
            raise SimcredError(f"description {k} has objects "
                               f"{sorted(description.objects)}, description 0 "
                               f"{sorted(batch[0].objects)}")
    if not names:
        raise SimcredError("a resimulation needs at least one traffic object besides the EGO")
    return names


def _object_states(description: ScenarioDescription, names: Sequence[str], t: np.ndarray
                   ) -> np.ndarray:
    """``(steps, objects, 4)``: x, y, v, heading of every traffic object on ``t``."""
    if t[-1] > description.t1 + TIME_TOLERANCE or t[0] < description.t0 - TIME_TOLERANCE:
        raise SimcredError(f"description spans [{description.t0}, {description.t1}] s, the "
                           f"batch needs [{t[0]}, {t[-1]}] s")
    sampled = description.sample(t)
    return np.stack([np.column_stack([sampled[f"{n}.{s}"] for s in MOTION_SIGNALS])
                     for n in names], axis=1)


def _ego_start(description: ScenarioDescription, ego: str) -> np.ndarray:
    return description.objects[ego].states(np.array([description.t0])).states()[0]


def _traceset(record: LoopRecord, t: np.ndarray, names: Sequence[str], ego: str,
              run_ids: Sequence[str]) -> TraceSet:
    runs = []
    for r in range(record.ego.shape[0]):
        run = {TIME: t, **record.ego.track(t, r).to_columns(ego)}
        for k, name in enumerate(names):
            run.update(record.objects.track(t, (r, slice(None), k)).to_columns(name))
        run[MODE_SIGNAL] = record.mode[r].astype(float)
        runs.append(run)
    return TraceSet.from_runs(runs, run_ids=run_ids, source="resimulation")
