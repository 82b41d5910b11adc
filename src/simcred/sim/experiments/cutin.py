"""Cut-in and brake on a two-lane highway: the manufactured universe of paper 002 ([1] §III).

"Reality" is the higher-fidelity vehicle model (CommonRoad ST) for the EGO, the real sensor
(:class:`~simcred.sim.sensors.TrackerSensor`: 1.4 m offset along the line of sight, velocity and
heading from a 1 s regression of noisy positions) and the AD function
(:class:`~simcred.sim.driver.ADFunction`). The EGO drives 100 km/h in the right lane (y = 0);
the traffic object (TO) starts ahead in the left lane (y = 3.5 m) a little slower, changes to the
right lane (quintic lateral profile) and brakes hard just before its centre crosses the lane
boundary.

The measurement holds two recordings of the same drive, both at the simulation step (100 Hz):

* **GT** — true centre states of EGO and TO plus DGPS-level white noise (1 cm position per
  axis, 0.05 km/h speed, 0.1° heading; [1] §II-A);
* **SD** — what the AD function used: its odometry (the EGO's true state with the same
  DGPS-level noise: [1] finds negligible self-measurement errors) and the object list; plus the
  AD function's mode (``ad.mode``: 0 cruise, 1 brake, 2 evade) as its own log.

Every parameter is in :class:`CutInConfig`; ``simcred simulate cutin`` writes the measurement.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from simcred._json import plain
from simcred.errors import OptionError
from simcred.io.measurement import Measurement
from simcred.kinematics import LANE_WIDTH, Track
from simcred.seeds import stream
from simcred.sim.closed_loop import LoopRecord, run_closed_loop
from simcred.sim.driver import ADFunction, DriverConfig
from simcred.sim.sensors import TrackerSensor
from simcred.sim.vehicles import VEHICLE_MODELS, vehicle_model
from simcred.traces import TraceSet


@dataclass(frozen=True, slots=True)
class CutInScript:
    """The TO's scripted manoeuvre (s, m, m/s, m/s²)."""

    start_distance: float = 30.0  # centre ahead of the EGO's centre at t = 0
    start_lane: float = LANE_WIDTH
    end_lane: float = 0.0
    speed: float = 25.0
    lane_change_start: float = 2.0
    lane_change_duration: float = 3.0
    brake_start: float = 3.2  # the centre crosses the lane boundary at 3.5 s
    brake_decel: float = 6.0
    brake_to: float = 10.0  # speed held after braking


#: A second drive of the same universe ([1] §IV: a sensor model comes from "a set of drives"):
#: the TO starts farther and slower, changes lanes faster (2.5 s) and brakes earlier and more
#: gently (5 m/s² from 3.0 s down to 12 m/s; its centre crosses the boundary at 3.25 s).
HELD_OUT_SCRIPT = CutInScript(start_distance=35.0, speed=24.0, lane_change_start=2.0,
                              lane_change_duration=2.5, brake_start=3.0, brake_decel=5.0,
                              brake_to=12.0)


@dataclass(frozen=True, slots=True)
class DGPSNoise:
    """Standard deviations of the reference measurement ([1] §II-A)."""

    position: float = 0.01  # m, per axis
    speed: float = 0.05 / 3.6  # m/s
    heading: float = float(np.deg2rad(0.1))  # rad


@dataclass(frozen=True, slots=True)
class CutInConfig:
    """Everything that defines the manufactured universe."""

    duration: float = 12.0
    dt: float = 0.01
    ego_speed: float = 100 / 3.6
    ego_model: str = "st"
    script: CutInScript = field(default_factory=CutInScript)
    sensor: TrackerSensor = field(default_factory=TrackerSensor)
    driver: DriverConfig = field(default_factory=DriverConfig)
    dgps: DGPSNoise = field(default_factory=DGPSNoise)

    def __post_init__(self) -> None:
        if self.ego_model not in VEHICLE_MODELS:
            raise OptionError(f"unknown EGO model {self.ego_model!r} "
                              f"(choose one of: {', '.join(VEHICLE_MODELS)})")
        if not (self.dt > 0 and self.duration > 10 * self.dt):
            raise OptionError(f"need dt > 0 and duration > 10 dt, got dt={self.dt}, "
                              f"duration={self.duration}")

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt)) + 1


def scripted_object(script: CutInScript, t: np.ndarray) -> np.ndarray:
    """The TO's true state ``(len(t), 4)``: x, y, v, heading (EGO starts at the origin)."""
    braking = np.clip(t - script.brake_start, 0.0,
                      (script.speed - script.brake_to) / script.brake_decel)
    longitudinal = script.speed - script.brake_decel * braking
    braked_distance = 0.5 * braking ** 2 + braking * (t - script.brake_start - braking)
    x = script.start_distance + script.speed * t - script.brake_decel * braked_distance
    u = np.clip((t - script.lane_change_start) / script.lane_change_duration, 0.0, 1.0)
    shape = u ** 3 * (10 - 15 * u + 6 * u * u)
    slope = 30 * u * u * (1 - u) ** 2 / script.lane_change_duration
    lateral = script.end_lane - script.start_lane
    y = script.start_lane + lateral * shape
    vy = lateral * slope
    return np.column_stack([x, y, np.hypot(longitudinal, vy), np.arctan2(vy, longitudinal)])


def drive(config: CutInConfig, seed: int) -> LoopRecord:
    """Run the manufactured universe once."""
    t = np.arange(config.steps) * config.dt
    truth = scripted_object(config.script, t)[None, :, None, :]
    noise = stream(seed, 0).standard_normal((1, config.steps, 1, 2))
    ego_start = np.array([[0.0, 0.0, config.ego_speed, 0.0]])
    return run_closed_loop(vehicle_model(config.ego_model), ego_start, truth, config.sensor,
                           ADFunction(config.driver), config.dt, noise)


def simulate(seed: int = 0, config: CutInConfig | None = None) -> Measurement:
    """The measurement (GT and SD) of one drive of the manufactured universe.

    Examples
    --------
    >>> m = simulate(1, CutInConfig(duration=1.0))
    >>> m.gt.signals[:4], m.sd.n_rows
    (('ego.x', 'ego.y', 'ego.v', 'ego.heading'), 101)
    """
    chosen = CutInConfig() if config is None else config
    record = drive(chosen, seed)
    rng = stream(seed, 1)
    t, ego, to = record.t, record.ego.states()[0], record.objects.states()[0, :, 0]
    gt = {"t": t, **Track.from_states(t, _dgps(ego, chosen.dgps, rng)).to_columns("ego"),
          **Track.from_states(t, _dgps(to, chosen.dgps, rng)).to_columns("to")}
    sd = {"t": t, **Track.from_states(t, _dgps(ego, chosen.dgps, rng)).to_columns("ego"),
          **record.perceived.track(t, (0, slice(None), 0)).to_columns("to"),
          "ad.mode": record.mode[0].astype(float)}
    metadata = {"experiment": "cutin", "seed": seed, "config": plain(asdict(chosen))}
    return Measurement(
        gt=TraceSet.from_runs([gt], run_ids=["gt"], metadata={**metadata, "kind": "GT"},
                              source="cutin:GT"),
        sd=TraceSet.from_runs([sd], run_ids=["sd"], metadata={**metadata, "kind": "SD"},
                              source="cutin:SD"),
        metadata=metadata)


def _dgps(states: np.ndarray, noise: DGPSNoise, rng: np.random.Generator) -> np.ndarray:
    scale = np.array([noise.position, noise.position, noise.speed, noise.heading])
    return states + scale * rng.standard_normal(states.shape)


