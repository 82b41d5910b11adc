"""T-junction with a static occlusion: Neurohr et al. 2023 [1], sec. VI-B (Table 3), in 2-D.

The paper ran this scenario in CARLA; simcred regenerates it in its own plane (metres, seconds,
right-hand traffic). The main road runs along the x axis; the EGO's eastbound lane is
``y ∈ [-3.5, 0]``, the westbound lane ``y ∈ [0, 3.5]``. A side arm joins from the south around
``x = 0``. Three actors:

* **Cyclist** — follows a fixed path (:class:`CyclistPath`): north in the side arm along
  ``x = 2``, a left quarter circle of radius 6.5 m across the EGO's lane, then west in the
  westbound lane, i.e. into the arm the EGO came from. Speed ~ U(4, 6) m/s, start delay
  ~ U(0, 6) s, standing still before it.
* **Parked cars** — 1 to 3 boxes (4.2-4.9 m × 1.9 m, gaps 0.8-2.5 m) south of the EGO's lane, the
  easternmost ending at x ~ U(-9.5, -5.5): they can hide the side arm and the cyclist.
* **EGO** — :class:`~simcred.sim.vehicles.SimpleCar` integrated with RK4. Its AD function
  (:class:`Driver`) sets an acceleration, bounded to [-6, 2] m/s², that tracks a target speed:

  - cruise speed ~ U(11, 13) m/s per run, unless it must be able to stop before the conflict
    zone (where the cyclist's path crosses its lane); then the target is also at most
    ``sqrt(2 · 2.5 m/s² · distance to the stop position)``;
  - it must be able to stop (a) while a point of the cyclist's path in the side arm (checked
    every 2.5 m up to 30 m before the conflict zone) is hidden and a road user there, at 6 m/s,
    could reach the zone before the EGO has cleared it at its current speed (at least 1 m/s),
    or (b) while it sees the cyclist before or in the zone and the cyclist would arrive there
    less than 1.5 s after the EGO has cleared it;
  - on that profile it brakes exactly to the stop position, 1 m before the zone; once its front
    is in the zone it is committed and drives on.

  Steering follows a Stanley law towards the lane centre plus a seeded lane-keeping offset, an
  Ornstein-Uhlenbeck process in time (sd 0.15 m, 3 s), so ``ego.y`` is not constant; as in a
  real car, it only moves sideways while it rolls (ẏ = v sin ψ).

Perception is line of sight from the EGO's centre: a target is hidden iff the segment to it meets
a parked car (shapely, one prepared MultiPolygon per run); the sensor range is unlimited.

Categories ([1] η1, η2, η3): ``no-occlusion`` (never parked cars), ``occlusion`` (always),
``random`` (parked cars with probability 0.5 per run).

Randomness: run ``i`` draws, from :func:`~simcred.seeds.stream` ``(seed, i)`` only, first
:data:`N_UNIFORMS` uniforms (every per-run parameter, the same draws in every category), then the
lateral noise. So a run does not depend on the batch it is simulated in, and the same seed gives
the same EGO and cyclist in every category (common random numbers).

The runs are sampled every ``dt`` seconds; the AD function and the integrator run at
``dt / substeps`` with the fewest substeps that keep that step at most ``max_step`` (0.1 s).

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np
import shapely

from simcred.errors import OptionError
from simcred.kinematics import LANE_WIDTH
from simcred.seeds import stream
from simcred.sim.campaign import run_id
from simcred.sim.vehicles import SimpleCar, rk4_step
from simcred.traces import TraceSet, handed_over

CATEGORIES = ("no-occlusion", "occlusion", "random")
SIGNALS = ("ego.x", "ego.y", "ego.v", "ego.heading", "cyclist.x", "cyclist.y", "occluded",
           "parked")
MAX_CARS = 3

# Columns of the per-run uniform draws (in draw order).
COIN, COUNT, ROW_END, CYCLIST_SPEED, CYCLIST_DELAY, CRUISE, START = range(7)
LENGTHS = slice(7, 7 + MAX_CARS)
GAPS = slice(LENGTHS.stop, LENGTHS.stop + MAX_CARS - 1)
CURBS = slice(GAPS.stop, GAPS.stop + MAX_CARS)
N_UNIFORMS = CURBS.stop


@dataclass(frozen=True, slots=True)
class CyclistPath:
    """The cyclist's path by arc length ``s ≥ 0``: north along ``x = lane_x`` for ``approach`` m
    up to ``y = turn_y``, a left quarter circle of ``radius``, then west."""

    lane_x: float = 2.0
    turn_y: float = -4.0
    radius: float = 6.5
    approach: float = 40.0

    @property
    def arc(self) -> float:
        return self.radius * math.pi / 2

    def position(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position ``(x, y)`` at arc lengths ``s``."""
        angle = np.clip(s - self.approach, 0.0, self.arc) / self.radius
        north = np.minimum(s, self.approach) - self.approach
        west = np.maximum(s - self.approach - self.arc, 0.0)
        x = self.lane_x - self.radius + self.radius * np.cos(angle) - west
        return x, self.turn_y + north + self.radius * np.sin(angle)

    def arc_length_at(self, y: float) -> float:
        """Where the path first reaches height ``y`` (below ``turn_y + radius``)."""
        if y <= self.turn_y:
            return self.approach + y - self.turn_y
        return self.approach + self.radius * math.asin((y - self.turn_y) / self.radius)


@dataclass(frozen=True, slots=True)
class Layout:
    """Road geometry. The EGO's lane is ``y ∈ [-lane_width, 0]``; the conflict zone is the part of
    its lane the cyclist (a disc of ``cyclist_radius``) sweeps."""

    lane_width: float = LANE_WIDTH
    cyclist: CyclistPath = field(default_factory=CyclistPath)
    cyclist_radius: float = 0.5
    ego_length: float = 4.5
    stop_gap: float = 1.0  # between the EGO's front and the conflict zone when it stops
    clear_gap: float = 0.5  # between the EGO's rear and the conflict zone when it has cleared it
    arm_spacing: float = 2.5  # side-arm points the EGO checks, every arm_spacing m ...
    arm_range: float = 30.0  # ... up to arm_range m before the conflict zone

    @property
    def lane_y(self) -> float:
        return -self.lane_width / 2

    @property
    def conflict_path(self) -> tuple[float, float]:
        """Arc lengths at which the cyclist enters and leaves the EGO's lane."""
        c, r = self.cyclist, self.cyclist_radius
        return c.arc_length_at(-self.lane_width - r), c.arc_length_at(r)

    @property
    def conflict_x(self) -> tuple[float, float]:
        """x range of the conflict zone."""
        x, _ = self.cyclist.position(np.array(self.conflict_path))
        return float(x.min()) - self.cyclist_radius, float(x.max()) + self.cyclist_radius

    @property
    def stop_x(self) -> float:
        """Centre of the EGO when it waits before the conflict zone."""
        return self.conflict_x[0] - self.stop_gap - self.ego_length / 2

    @property
    def commit_x(self) -> float:
        """Centre of the EGO when its front reaches the conflict zone."""
        return self.conflict_x[0] - self.ego_length / 2

    @property
    def clear_x(self) -> float:
        """Centre of the EGO once it has left the conflict zone."""
        return self.conflict_x[1] + self.clear_gap + self.ego_length / 2

    def arm_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Side-arm points ``(K, 2)`` on the cyclist's path and their path distances to the zone."""
        distance = np.arange(0.0, self.arm_range + 1e-9, self.arm_spacing)
        x, y = self.cyclist.position(self.conflict_path[0] - distance)
        return np.stack([x, y], axis=1), distance


@dataclass(frozen=True, slots=True)
class Driver:
    """The EGO's AD function: speed choice under occlusion, yielding, lane keeping."""

    plan_decel: float = 2.5  # m/s², deceleration of the planned stop before the conflict zone
    max_decel: float = 6.0  # m/s²
    max_accel: float = 2.0  # m/s²
    speed_tau: float = 0.5  # s, time constant of speed tracking
    hidden_speed: float = 6.0  # m/s, assumed speed of an unseen road user in the side arm
    min_speed: float = 1.0  # m/s, floor of the speed used to predict when the EGO clears the zone
    time_buffer: float = 1.5  # s, cyclist arrival after the EGO has cleared that still yields
    stanley_gain: float = 1.0  # 1/s
    soft_speed: float = 1.0  # m/s, keeps the Stanley law finite at standstill
    steer_tau: float = 0.2  # s
    max_steer: float = 0.5  # rad
    max_steer_rate: float = 0.8  # rad/s
    wheelbase: float = 2.5  # m
    lateral_sd: float = 0.15  # m, lane-keeping offset (Ornstein-Uhlenbeck), stationary sd
    lateral_tau: float = 3.0  # s, its correlation time


@dataclass(frozen=True, slots=True)
class Distributions:
    """Per-run parameter ranges: ``(low, high)`` of uniform draws."""

    ego_start: tuple[float, float] = (-83.0, -77.0)
    cruise: tuple[float, float] = (11.0, 13.0)
    cyclist_speed: tuple[float, float] = (4.0, 6.0)
    cyclist_delay: tuple[float, float] = (0.0, 6.0)
    parked_cars: tuple[int, int] = (1, MAX_CARS)  # inclusive
    parked_end: tuple[float, float] = (-9.5, -5.5)  # east end of the easternmost parked car
    parked_length: tuple[float, float] = (4.2, 4.9)
    parked_gap: tuple[float, float] = (0.8, 2.5)
    parked_width: float = 1.9
    curb_gap: tuple[float, float] = (0.1, 0.4)  # between the EGO's lane edge and a parked car
    random_parked: float = 0.5  # probability of parked cars in the ``random`` category


@dataclass(frozen=True, slots=True)
class Scenario:
    """Everything that defines the experiment besides the category, seed and sampling."""

    layout: Layout = field(default_factory=Layout)
    driver: Driver = field(default_factory=Driver)
    draws: Distributions = field(default_factory=Distributions)
    max_step: float = 0.1  # s, longest step of the AD function and the integrator


@dataclass(frozen=True, slots=True, eq=False)
class Occluders:
    """The parked cars of every run as one prepared MultiPolygon (None without cars)."""

    geoms: np.ndarray
    bounds: np.ndarray

    @classmethod
    def from_boxes(cls, boxes: np.ndarray) -> Occluders:
        """From ``(runs, cars, 4)`` boxes ``xmin, ymin, xmax, ymax``; NaN rows are no car."""
        runs, cars = np.nonzero(~np.isnan(boxes[..., 0]))
        geoms = np.full(len(boxes), None, dtype=object)
        if runs.size:
            shapely.multipolygons(shapely.box(*boxes[runs, cars].T), indices=runs, out=geoms)
            shapely.prepare(geoms)
        return cls(geoms, shapely.bounds(geoms))

    def blocked(self, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """``(runs, T)``: whether the sight line from ``origins`` (runs, 2) to ``targets``
        (runs, T, 2) meets a parked car of its run."""
        lo = np.minimum(origins[:, None, :], targets)
        hi = np.maximum(origins[:, None, :], targets)
        b = self.bounds[:, None, :]
        # Only sight lines whose bounding box meets the cars' go to shapely (NaN: no cars).
        near = ((lo[..., 0] <= b[..., 2]) & (hi[..., 0] >= b[..., 0])
                & (lo[..., 1] <= b[..., 3]) & (hi[..., 1] >= b[..., 1]))
        out = np.zeros(near.shape, dtype=bool)
        runs, k = np.nonzero(near)
        if runs.size:
            lines = shapely.linestrings(np.stack([origins[runs], targets[runs, k]], axis=1))
            out[runs, k] = shapely.intersects(self.geoms[runs], lines)
        return out


@dataclass(frozen=True, slots=True)
class Runs:
    """The random draws of a batch of runs, one row per run."""

    parked: np.ndarray
    boxes: np.ndarray
    cyclist_speed: np.ndarray
    cyclist_delay: np.ndarray
    cruise: np.ndarray
    start_x: np.ndarray
    noise: np.ndarray  # standard normals of the lane-keeping offset, one per AD step (+ start)

    @classmethod
    def draw(cls, indices: Sequence[int], seed: int, category: str, draws: Distributions,
             lane_width: float, n_noise: int) -> Runs:
        """Run ``i`` draws from ``stream(seed, i)``: :data:`N_UNIFORMS` uniforms, then
        ``n_noise`` standard normals."""
        u = np.empty((len(indices), N_UNIFORMS))
        noise = np.empty((len(indices), n_noise))
        for k, i in enumerate(indices):
            rng = stream(seed, i)
            u[k] = rng.random(N_UNIFORMS)
            noise[k] = rng.standard_normal(n_noise)
        chance = {"no-occlusion": 0.0, "occlusion": 1.0, "random": draws.random_parked}[category]
        parked = u[:, COIN] < chance
        return cls(parked, _parked_boxes(u, parked, draws, lane_width),
                   _uniform(u[:, CYCLIST_SPEED], draws.cyclist_speed),
                   _uniform(u[:, CYCLIST_DELAY], draws.cyclist_delay),
                   _uniform(u[:, CRUISE], draws.cruise), _uniform(u[:, START], draws.ego_start),
                   noise)


def _uniform(u: np.ndarray, bounds: tuple[float, float]) -> np.ndarray:
    """``u ~ U(0, 1)`` mapped to ``U(bounds)``."""
    return bounds[0] + (bounds[1] - bounds[0]) * u


def _parked_boxes(u: np.ndarray, parked: np.ndarray, draws: Distributions, lane_width: float
                  ) -> np.ndarray:
    """``(runs, MAX_CARS, 4)`` boxes of a row of cars westwards from the row's east end."""
    low, high = draws.parked_cars
    count = low + np.minimum((u[:, COUNT] * (high - low + 1)).astype(int), high - low)
    length = _uniform(u[:, LENGTHS], draws.parked_length)
    gap = _uniform(u[:, GAPS], draws.parked_gap)
    end = _uniform(u[:, [ROW_END]], draws.parked_end)
    east = end - np.concatenate([np.zeros((len(u), 1)), np.cumsum(length[:, :-1] + gap, axis=1)],
                                axis=1)
    north = -lane_width - _uniform(u[:, CURBS], draws.curb_gap)
    boxes = np.stack([east - length, north - draws.parked_width, east, north], axis=2)
    absent = ~parked[:, None] | (np.arange(MAX_CARS) >= count[:, None])
    boxes[absent] = np.nan
    return boxes


def _substeps(dt: float, max_step: float) -> int:
    return max(1, math.ceil(dt / max_step - 1e-9))


def _check(category: str, dt: float, duration: float) -> None:
    if category not in CATEGORIES:
        raise OptionError(f"unknown T-junction category {category!r} "
                          f"(choose one of: {', '.join(CATEGORIES)})")
    if not dt > 0 or not duration >= dt:
        raise OptionError(f"need dt > 0 and duration >= dt, got dt={dt}, duration={duration}")


def simulate(
    indices: Sequence[int],
    seed: int,
    *,
    category: str,
    dt: float = 0.1,
    duration: float = 20.0,
    scenario: Scenario | None = None,
) -> TraceSet:
    """Runs ``indices`` of the T-junction scenario of ``category`` (one of :data:`CATEGORIES`).

    Parameters
    ----------
    indices : sequence of int
        Run indices; run ``i`` is named ``run_id(i)`` and draws from ``stream(seed, i)`` only.
    seed : int
        Campaign seed.
    category : {"no-occlusion", "occlusion", "random"}
        Parked cars never, always, or with probability 0.5 per run ([1] η1, η2, η3).
    dt : float, default: 0.1
        Sampling step (s); the AD function runs at ``dt`` or, for ``dt > 0.1``, a fraction of it.
    duration : float, default: 20.0
        Length of a run (s); ``round(duration / dt) + 1`` samples from ``t = 0``.
    scenario : Scenario, optional
        Geometry, AD function and distributions; default ``Scenario()`` (the module's design).
        A non-default scenario is recorded in the metadata.

    Returns
    -------
    TraceSet
        Signals :data:`SIGNALS`: EGO pose and speed, cyclist position, ``occluded`` (1.0 when the
        EGO cannot see the cyclist) and ``parked`` (1.0 in runs with parked cars).

    Examples
    --------
    >>> ts = simulate(range(3), 7, category="occlusion", duration=2.0)
    >>> ts.n_runs, ts.lengths.tolist(), ts.run_ids[0]
    (3, [21, 21, 21], 'run_00000')
    """
    _check(category, dt, duration)
    chosen = Scenario() if scenario is None else scenario
    substeps = _substeps(dt, chosen.max_step)
    samples = int(round(duration / dt)) + 1
    runs = Runs.draw(indices, seed, category, chosen.draws, chosen.layout.lane_width,
                     (samples - 1) * substeps + 1)
    loop = _ClosedLoop(chosen, runs, dt / substeps, Occluders.from_boxes(runs.boxes))
    values = loop.sample(samples, substeps)
    metadata = {"model": "tjunction", "category": category, "dt": dt, "duration": duration}
    if scenario is not None and scenario != Scenario():
        metadata["scenario"] = asdict(scenario)
    n = len(runs.parked)
    return TraceSet(
        signals=SIGNALS,
        time=handed_over(np.tile(np.arange(samples) * dt, n)),
        values=handed_over(values.transpose(1, 0, 2).reshape(n * samples, len(SIGNALS))),
        offsets=np.arange(n + 1) * samples,
        run_ids=tuple(run_id(i) for i in indices),
        metadata=metadata,
        source=f"tjunction({category})",
    )


@dataclass(frozen=True, slots=True)
class _Cyclist:
    """Every run's cyclist at one instant: arc length, speed and position ``(runs, 2)``."""

    s: np.ndarray
    v: np.ndarray
    xy: np.ndarray


@dataclass(frozen=True, slots=True)
class _Sight:
    """What every EGO sees: whether the cyclist is hidden, and the path distance of the nearest
    hidden side-arm point to the conflict zone (inf when the checked arm is all visible)."""

    cyclist_hidden: np.ndarray
    nearest_hidden: np.ndarray


@dataclass(frozen=True, slots=True, eq=False)
class _ClosedLoop:
    """Perception, AD function and RK4 step of every run at once, with step ``step``."""

    scenario: Scenario
    runs: Runs
    step: float
    occluders: Occluders

    def sample(self, samples: int, substeps: int) -> np.ndarray:
        """``(samples, runs, signals)``: the signals every ``substeps`` steps from ``t = 0``."""
        offset = self.scenario.driver.lateral_sd * self.runs.noise[:, 0]
        state = np.zeros((len(offset), 4))
        state[:, 0], state[:, 1] = self.runs.start_x, self.scenario.layout.lane_y + offset
        speed = self.runs.cruise.copy()
        out = np.empty((samples, len(offset), len(SIGNALS)))
        last = (samples - 1) * substeps
        for j in range(last + 1):
            cyclist = self._cyclist(j * self.step)
            sight = self._perceive(state[:, :2], cyclist.xy)
            if j % substeps == 0:
                out[j // substeps] = np.column_stack([
                    state[:, 0], state[:, 1], speed, state[:, 2], cyclist.xy,
                    sight.cyclist_hidden, self.runs.parked])
            if j < last:
                accel = self._acceleration(state[:, 0], speed, cyclist, sight)
                steer = self._steering_rate(state, speed, self.scenario.layout.lane_y + offset)
                state = rk4_step(SimpleCar(self.scenario.driver.wheelbase), state,
                                 np.stack([speed + 0.5 * self.step * accel, steer], axis=1),
                                 self.step)
                speed = np.maximum(speed + self.step * accel, 0.0)
                offset = self._lateral_offset(offset, self.runs.noise[:, j + 1])
        return out

    def _cyclist(self, t: float) -> _Cyclist:
        delay, speed = self.runs.cyclist_delay, self.runs.cyclist_speed
        s = speed * np.maximum(t - delay, 0.0)
        x, y = self.scenario.layout.cyclist.position(s)
        return _Cyclist(s, np.where(t >= delay, speed, 0.0), np.stack([x, y], axis=1))

    def _perceive(self, ego: np.ndarray, cyclist: np.ndarray) -> _Sight:
        arm, distance = self.scenario.layout.arm_points()
        targets = np.concatenate([cyclist[:, None], np.broadcast_to(arm, (len(ego), *arm.shape))],
                                 axis=1)
        blocked = self.occluders.blocked(ego, targets)
        return _Sight(blocked[:, 0], np.where(blocked[:, 1:], distance, np.inf).min(axis=1))

    def _acceleration(self, x: np.ndarray, v: np.ndarray, cyclist: _Cyclist, sight: _Sight
                      ) -> np.ndarray:
        d, layout = self.scenario.driver, self.scenario.layout
        to_stop = layout.stop_x - x
        clears_in = (layout.clear_x - x) / np.maximum(v, d.min_speed)
        unseen_user = sight.nearest_hidden / d.hidden_speed < clears_in
        enter, leave = layout.conflict_path
        # A cyclist standing still never arrives: a huge arrival time, not inf/NaN.
        arrives_in = np.maximum(enter - cyclist.s, 0.0) / np.maximum(cyclist.v, 1e-9)
        yields = ~sight.cyclist_hidden & (cyclist.s < leave) & (
            arrives_in < clears_in + d.time_buffer)
        must_stop = (unseen_user | yields) & (x < layout.commit_x)
        stoppable = np.sqrt(2 * d.plan_decel * np.maximum(to_stop, 0.0))
        target = np.where(must_stop, np.minimum(self.runs.cruise, stoppable), self.runs.cruise)
        accel = (target - v) / d.speed_tau
        # On the stopping profile, brake exactly to the stop position: speed tracking alone lags.
        exact = must_stop & (v >= stoppable) & (to_stop > 0)
        braking = -v * v / (2 * np.maximum(to_stop, 1e-9))
        accel = np.where(exact, np.minimum(accel, braking), accel)
        return np.maximum(np.clip(accel, -d.max_decel, d.max_accel), -v / self.step)

    def _steering_rate(self, state: np.ndarray, v: np.ndarray, y_ref: np.ndarray) -> np.ndarray:
        """Stanley law towards ``y_ref`` on the eastbound lane, through a first-order steering."""
        d = self.scenario.driver
        wanted = -state[:, 2] + np.arctan2(d.stanley_gain * (y_ref - state[:, 1]),
                                           v + d.soft_speed)
        wanted = np.clip(wanted, -d.max_steer, d.max_steer)
        return np.clip((wanted - state[:, 3]) / d.steer_tau, -d.max_steer_rate, d.max_steer_rate)

    def _lateral_offset(self, offset: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """One exact step of the Ornstein-Uhlenbeck lane-keeping offset."""
        d = self.scenario.driver
        decay = math.exp(-self.step / d.lateral_tau)
        return decay * offset + d.lateral_sd * math.sqrt(1 - decay * decay) * noise
