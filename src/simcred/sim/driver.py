"""The AD function of the cut-in experiments ([1] §III): ACC, emergency braking, evasion.

Batched over runs; it sees the EGO's own state (odometry) and its sensor's object list, never the
true object states. Road: straight along +x, lanes ``lane_centres`` (the EGO starts in the first,
the rightmost), width ``lane_width``. Every step it

1. **selects** the nearest *relevant* object ahead: one whose centre lies in the EGO's current
   lane, or (``cut_in=True``, the default) one that is **cutting in** — its perceived lateral
   velocity towards the EGO's lane is at least ``cut_in_lateral_speed`` and its time to lane
   crossing (the gap between its near side and the lane boundary over that velocity) is at most
   ``cut_in_tlc`` (see :meth:`ADFunction.cutting_in`). The cut-in trigger reads the perceived
   heading and speed, so a sensor that delays them delays the reaction;
2. estimates that object's acceleration from the perceived speed (first-order filter,
   ``accel_filter``) — with a delayed sensor the deceleration is seen late;
3. computes the **required deceleration** ``a_req``: the larger of the relative-motion value
   ``closing² / (2 (gap − min_gap))`` and, when the object brakes, the stop-behind-it value
   ``v² / (2 (gap − min_gap + v_obj² / (2 b)))`` (gap bumper to bumper, b its deceleration);
4. **decides** when ``a_req`` exceeds ``react_decel`` while cruising: evade to the left lane if
   ``a_req > evade_decel`` and the left lane is free, otherwise brake. The decision is kept:
   an evasion until the EGO is within ``arrived`` of the target lane's centre, braking until
   ``a_req`` falls below ``release_decel``; then it cruises (and may decide again);
5. **acts**: ACC (speed and gap control, comfort limits) while cruising; braking with
   ``brake_gain · a_req`` (at least ``react_decel``, at most ``max_decel``); or a lane change
   to the left with a light deceleration;
6. **steers** towards the target lane's centre: a PD law on the lateral error gives a lateral
   acceleration (bounded), converted to a steering angle through the single-track kinematics and
   reached with a steering rate clipped to the vehicle model's limits.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simcred.kinematics import LANE_WIDTH
from simcred.sim.sensors import HEADING, V, X, Y

CRUISE, BRAKE, EVADE = 0, 1, 2
MODES = ("cruise", "brake", "evade")


@dataclass(frozen=True, slots=True)
class DriverConfig:
    """Parameters of the AD function (SI units)."""

    set_speed: float = 100 / 3.6
    lane_centres: tuple[float, ...] = (0.0, LANE_WIDTH)
    lane_width: float = LANE_WIDTH
    vehicle_length: float = 4.5
    # relevance of an object: centre in the lane, or cutting in (perceived lateral motion)
    cut_in: bool = True  # False: only objects whose centre is in the lane (the old function)
    cut_in_lateral_speed: float = 0.3  # m/s towards the EGO's lane, at least
    cut_in_tlc: float = 1.0  # s, time to lane crossing of the object's near side, at most
    object_width: float = 1.8  # m, assumed width of an object (the object list has none)
    # ACC
    time_gap: float = 1.5  # s
    standstill_gap: float = 5.0  # m
    speed_gain: float = 0.4  # 1/s
    gap_gain: float = 0.05  # 1/s²
    max_accel: float = 1.5
    comfort_decel: float = 2.0
    # emergency
    accel_filter: float = 0.15  # s, time constant of the object-acceleration estimate
    min_gap: float = 2.0  # m kept at standstill behind the object
    react_decel: float = 3.0
    evade_decel: float = 4.0
    brake_gain: float = 1.2
    max_decel: float = 9.0
    release_decel: float = 1.0  # braking ends when a_req falls below this
    arrived: float = 0.2  # m, an evasion ends this close to the target lane's centre
    evade_brake: float = 1.0
    free_behind: float = 20.0  # m, left lane must be free this far behind ...
    free_ahead: float = 60.0  # m, ... and this far ahead
    # lateral control
    lateral_gain: float = 3.0  # 1/s², lateral acceleration per metre of error
    lateral_damping: float = 3.5  # 1/s, per m/s of lateral speed
    max_lateral_accel: float = 4.0
    steer_tau: float = 0.1  # s
    wheelbase: float = 2.58  # m (CommonRoad vehicle 2)
    max_steer_rate: float = 0.4  # rad/s (CommonRoad vehicle 2)


@dataclass(slots=True)
class DriverMemory:
    """What the AD function keeps between steps, per run."""

    mode: np.ndarray
    target_lane: np.ndarray
    object_speed: np.ndarray  # previous perceived speed of every object (runs, objects)
    object_accel: np.ndarray  # filtered acceleration estimate (runs, objects)
    required: np.ndarray = field(default_factory=lambda: np.zeros(0))  # last a_req (runs,)


@dataclass(frozen=True, slots=True)
class ADFunction:
    """The AD function; ``start`` once, then ``act`` every step (see the module docstring)."""

    config: DriverConfig = field(default_factory=DriverConfig)

    def start(self, runs: int, objects: np.ndarray) -> DriverMemory:
        """Memory before the first step; ``objects`` is the first object list (runs, n, 4)."""
        return DriverMemory(np.full(runs, CRUISE), np.zeros(runs, dtype=int),
                            objects[:, :, V].copy(), np.zeros(objects.shape[:2]),
                            np.zeros(runs))

    def act(self, memory: DriverMemory, ego: np.ndarray, steering: np.ndarray,
            objects: np.ndarray, dt: float) -> np.ndarray:
        """Inputs ``(runs, 2)``: steering rate and acceleration.

        ``ego`` (runs, 4) is x, y, v, heading of the EGO's centre; ``steering`` its steering
        angle; ``objects`` (runs, n, 4) the object list. Updates ``memory`` in place.
        """
        c = self.config
        self._estimate(memory, objects, dt)
        lead, gap = self._lead(memory, ego, objects)
        required = self._required(ego, objects, memory.object_accel, lead, gap)
        self._decide(memory, ego, objects, required)
        memory.required = required
        accel = self._longitudinal(memory, ego, objects, lead, gap, required)
        lane_y = np.asarray(c.lane_centres)[memory.target_lane]
        return np.column_stack([self._steering_rate(ego, steering, lane_y), accel])

    def _estimate(self, memory: DriverMemory, objects: np.ndarray, dt: float) -> None:
        raw = (objects[:, :, V] - memory.object_speed) / dt
        memory.object_accel += (raw - memory.object_accel) * (dt / max(self.config.accel_filter,
                                                                       dt))
        memory.object_speed = objects[:, :, V].copy()

    def cutting_in(self, objects: np.ndarray, lane_y: np.ndarray) -> np.ndarray:
        """``(runs, n)``: which objects cut into the lane centred at ``lane_y`` (runs,).

        An object in a neighbouring lane (centre within 1.5 lane widths of ``lane_y``) cuts in
        when its perceived lateral velocity towards the lane, ``v sin θ`` signed towards it, is
        at least ``cut_in_lateral_speed`` and its time to lane crossing — the lateral gap between
        its near side (``object_width / 2`` from its centre) and the lane boundary, divided by
        that velocity; 0 once its side is over the boundary — is at most ``cut_in_tlc``.
        """
        c = self.config
        offset = objects[:, :, Y] - lane_y[:, None]
        towards = -np.sign(offset) * objects[:, :, V] * np.sin(objects[:, :, HEADING])
        gap = np.maximum(np.abs(offset) - (c.object_width + c.lane_width) / 2, 0.0)
        moving = towards >= c.cut_in_lateral_speed
        tlc = np.divide(gap, towards, out=np.full_like(gap, np.inf), where=moving)
        return (np.abs(offset) < 1.5 * c.lane_width) & moving & (tlc <= c.cut_in_tlc)

    def _lead(self, memory: DriverMemory, ego: np.ndarray, objects: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        """Index of the nearest relevant object ahead (-1: none) and its bumper gap (inf)."""
        c = self.config
        lane_y = np.asarray(c.lane_centres)[memory.target_lane]
        ahead = objects[:, :, X] - ego[:, None, X]
        relevant = np.abs(objects[:, :, Y] - lane_y[:, None]) < c.lane_width / 2
        if c.cut_in:
            relevant = relevant | self.cutting_in(objects, lane_y)
        distance = np.where(relevant & (ahead > 0), ahead, np.inf)
        lead = np.argmin(distance, axis=1)
        gap = distance[np.arange(len(lead)), lead] - c.vehicle_length
        return np.where(np.isfinite(gap), lead, -1), gap

    def _required(self, ego: np.ndarray, objects: np.ndarray, object_accel: np.ndarray,
                  lead: np.ndarray, gap: np.ndarray) -> np.ndarray:
        c = self.config
        rows = np.arange(len(lead))
        pick = np.maximum(lead, 0)
        v_obj = objects[rows, pick, V] * np.cos(objects[rows, pick, HEADING])
        decel = np.maximum(-object_accel[rows, pick], 0.0)
        room = np.maximum(gap - c.min_gap, 0.1)
        closing = np.maximum(ego[:, V] - v_obj, 0.0)
        relative = closing ** 2 / (2 * room)
        braking = decel > 0.5
        stop_room = room + v_obj ** 2 / (2 * np.where(braking, decel, 1.0))
        behind = np.where(braking, ego[:, V] ** 2 / (2 * stop_room), 0.0)
        return np.where(lead >= 0, np.maximum(relative, behind), 0.0)

    def _decide(self, memory: DriverMemory, ego: np.ndarray, objects: np.ndarray,
                required: np.ndarray) -> None:
        c = self.config
        released = (memory.mode == BRAKE) & (required < c.release_decel)
        arrived = (memory.mode == EVADE) & (np.abs(ego[:, Y] - np.asarray(c.lane_centres)[
            memory.target_lane]) < c.arrived)
        memory.mode = np.where(released | arrived, CRUISE, memory.mode)
        fresh = (memory.mode == CRUISE) & (required > c.react_decel)
        can_evade = memory.target_lane + 1 < len(c.lane_centres)
        left = np.minimum(memory.target_lane + 1, len(c.lane_centres) - 1)
        left_y = np.asarray(c.lane_centres)[left]
        ahead = objects[:, :, X] - ego[:, None, X]
        occupied = ((np.abs(objects[:, :, Y] - left_y[:, None]) < c.lane_width / 2)
                    & (ahead > -c.free_behind) & (ahead < c.free_ahead)).any(axis=1)
        evade = fresh & (required > c.evade_decel) & can_evade & ~occupied
        memory.mode = np.where(evade, EVADE, np.where(fresh, BRAKE, memory.mode))
        memory.target_lane = np.where(evade, left, memory.target_lane)

    def _longitudinal(self, memory: DriverMemory, ego: np.ndarray, objects: np.ndarray,
                      lead: np.ndarray, gap: np.ndarray, required: np.ndarray) -> np.ndarray:
        c = self.config
        v = ego[:, V]
        rows = np.arange(len(lead))
        v_obj = objects[rows, np.maximum(lead, 0), V]
        cruise = c.speed_gain * (c.set_speed - v)
        follow = (c.speed_gain * (v_obj - v)
                  + c.gap_gain * (gap - c.standstill_gap - c.time_gap * v))
        acc = np.clip(np.where(lead >= 0, np.minimum(cruise, follow), cruise),
                      -c.comfort_decel, c.max_accel)
        brake = -np.clip(c.brake_gain * required, c.react_decel, c.max_decel)
        accel = np.where(memory.mode == BRAKE, np.minimum(acc, brake), acc)
        evading = (memory.mode == EVADE) & (np.abs(ego[:, Y] - np.asarray(c.lane_centres)[
            memory.target_lane]) > 0.5)
        accel = np.where(evading, np.minimum(acc, -c.evade_brake), accel)
        return np.where(v > 0, accel, np.maximum(accel, 0.0))

    def _steering_rate(self, ego: np.ndarray, steering: np.ndarray, lane_y: np.ndarray
                       ) -> np.ndarray:
        c = self.config
        v = np.maximum(ego[:, V], 1.0)
        lateral_speed = ego[:, V] * np.sin(ego[:, HEADING])
        lateral = np.clip(c.lateral_gain * (lane_y - ego[:, Y])
                          - c.lateral_damping * lateral_speed,
                          -c.max_lateral_accel, c.max_lateral_accel)
        wanted = np.arctan(c.wheelbase * lateral / (v * v))
        return np.clip((wanted - steering) / c.steer_tau, -c.max_steer_rate, c.max_steer_rate)
