"""The closed loop of the cut-in experiments: sensor → AD function → vehicle model, batched.

Traffic objects move on given trajectories (scripted in the manufactured universe, from their
scenario descriptions in a resimulation); the EGO is driven by the :class:`~simcred.sim.driver.
ADFunction` through a vehicle model integrated with RK4. Everything is recorded at every step.

Positions are those of the vehicle's centre (CommonRoad ST: its centre of gravity; KS, whose
state is the rear axle: the point ``b`` ahead of it, the rear-axle-to-centre-of-gravity distance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcred.kinematics import TrackBatch
from simcred.sim.driver import ADFunction, DriverMemory
from simcred.sim.sensors import Sensor
from simcred.sim.vehicles import VehicleModel, initial_state, rk4_step

EGO_SIGNALS = ("x", "y", "v", "heading", "acceleration", "steering")


def centre_offset(model: VehicleModel) -> float:
    """Distance (m) from the model's reference point forward to the vehicle's centre."""
    return float(model.params.b) if model.name == "ks" else 0.0


def start_state(model: VehicleModel, ego: np.ndarray) -> np.ndarray:
    """Model state ``(runs, states)`` for EGO centres ``ego`` (runs, 4): x, y, v, heading."""
    back = centre_offset(model)
    heading = ego[:, 3]
    return initial_state(model, x=ego[:, 0] - back * np.cos(heading),
                         y=ego[:, 1] - back * np.sin(heading), speed=ego[:, 2], heading=heading)


def centre_pose(model: VehicleModel, state: np.ndarray) -> np.ndarray:
    """``(runs, 4)``: x, y, v, heading of the vehicle centre."""
    x, y, heading = model.pose(state)
    ahead = centre_offset(model)
    speed = state[:, model.state_names.index("speed")]
    return np.column_stack([x + ahead * np.cos(heading), y + ahead * np.sin(heading), speed,
                            heading])


@dataclass(frozen=True, slots=True)
class LoopRecord:
    """Everything a closed-loop run produced, sampled at every step ``t``.

    ``ego`` the EGO's centre, shape (runs, steps), with its acceleration; ``objects`` and
    ``perceived`` the true and the perceived traffic objects, shape (runs, steps, n) (batched
    tracks, :class:`~simcred.kinematics.TrackBatch`); ``steering`` (runs, steps) the EGO's
    steering angle (rad); ``mode`` (runs, steps) the AD function's mode.
    """

    t: np.ndarray
    ego: TrackBatch
    steering: np.ndarray
    objects: TrackBatch
    perceived: TrackBatch
    mode: np.ndarray

    def __repr__(self) -> str:
        runs, steps = self.mode.shape
        return f"LoopRecord({runs} runs, {steps} steps, {self.objects.shape[2]} objects)"


def run_closed_loop(model: VehicleModel, ego_start: np.ndarray, objects: np.ndarray,
                    sensor: Sensor, driver: ADFunction, dt: float, noise: np.ndarray
                    ) -> LoopRecord:
    """Run the loop.

    Parameters
    ----------
    model : VehicleModel
        The EGO's vehicle model (KS or ST: inputs steering rate and acceleration).
    ego_start : (runs, 4) array
        EGO centre x, y, speed, heading at ``t = 0``.
    objects : (runs, steps, n, 4) array
        True object states at every step.
    sensor : Sensor
        Turns true object states into the object list.
    driver : ADFunction
        The AD function.
    dt : float
        Step (s).
    noise : (runs, steps, n, 2) array
        Standard normal draws for the sensor.
    """
    runs, steps, n, _ = objects.shape
    state = start_state(model, ego_start)
    steering_index = model.state_names.index("steering")
    memories = [sensor.start(runs, dt) for _ in range(n)]
    ego = np.empty((runs, steps, len(EGO_SIGNALS)))
    perceived = np.empty_like(objects)
    mode = np.empty((runs, steps), dtype=np.int8)
    memory: DriverMemory | None = None
    for k in range(steps):
        pose = centre_pose(model, state)
        seen = np.stack([sensor.perceive(memories[j], pose[:, :2], objects[:, k, j],
                                         noise[:, k, j]) for j in range(n)], axis=1)
        if memory is None:
            memory = driver.start(runs, seen)
        inputs = driver.act(memory, pose, state[:, steering_index], seen, dt)
        ego[:, k, :4], ego[:, k, 4], ego[:, k, 5] = pose, inputs[:, 1], state[:, steering_index]
        perceived[:, k], mode[:, k] = seen, memory.mode
        state = rk4_step(model, state, inputs, dt)
    return LoopRecord(np.arange(steps) * dt, TrackBatch(*np.moveaxis(ego[..., :5], -1, 0)),
                      ego[..., 5], TrackBatch.from_states(objects),
                      TrackBatch.from_states(perceived), mode)
