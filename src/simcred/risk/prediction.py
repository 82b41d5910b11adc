"""What each party may do, and where that takes it: the TOs' naturalistic predictions with priors,
the EGO's evasive maneuvers, the reaction-time law, and the predicted paths ([1] sec. III).

References
----------
[1] S. Wagner, K. Groh, T. Kuehbeck, M. Doerfel, A. Knoll, "Using Time-To-React Based on
    Naturalistic Traffic Object Behavior for Scenario-Based Risk Assessment of Automated Driving",
    IEEE Intelligent Vehicles Symposium (IV), 2018, pp. 1521-1528.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.polynomial.hermite_e import hermegauss
from numpy.typing import ArrayLike
from scipy.special import ndtr

from simcred.risk.scene import Lanes, require

_SMOOTHSTEP_PEAK_ACCEL = 10.0 / math.sqrt(3.0)
# work arrays of one chunk of scenes hold at most about this many samples

MANEUVERS = ("brake", "left", "right", "kickdown")


@dataclass(frozen=True, slots=True)
class Prediction:
    """One predicted behaviour of a TO: longitudinal acceleration plus a lateral target lane.

    Parameters
    ----------
    name : str
        Label, unique within a :class:`PredictionSet`.
    probability : float
        Prior probability of this behaviour, in [0, 1].
    acceleration : float or None, default: 0
        Constant longitudinal acceleration (m/s²) over the horizon; a braking vehicle stays at
        standstill once stopped. None: the TO's current acceleration (0 unless given).
    lane_change : {-1, 0, 1}, default: 0
        Target lane relative to the reference lane: +1 left, -1 right, 0 keep (left and
        right as seen by the TO: an oncoming TO's left is the EGO's right).
    acceleration_offset : float, default: 0
        Added to the TO's current acceleration where ``acceleration`` is None (one node of the
        plausibility-weighted set that :meth:`PredictionSet.expanded` makes of such a
        prediction).
    """

    name: str
    probability: float
    acceleration: float | None = 0.0
    lane_change: int = 0
    acceleration_offset: float = 0.0

    def __post_init__(self) -> None:
        require(0.0 <= self.probability <= 1.0,
                 f"prediction {self.name!r}: probability must lie in [0, 1], got "
                 f"{self.probability!r}")
        require(self.acceleration is None or math.isfinite(self.acceleration),
                 f"prediction {self.name!r}: acceleration must be finite or None")
        require(self.lane_change in (-1, 0, 1),
                 f"prediction {self.name!r}: lane_change must be -1, 0 or 1, got "
                 f"{self.lane_change!r}")
        require(math.isfinite(self.acceleration_offset),
                 f"prediction {self.name!r}: acceleration_offset must be finite")


DEFAULT_PREDICTIONS: tuple[Prediction, ...] = (
    Prediction("keep", 0.70, acceleration=None),
    Prediction("accelerate", 0.05, acceleration=1.0),
    Prediction("brake-2", 0.10, acceleration=-2.0),
    Prediction("brake-4", 0.04, acceleration=-4.0),
    Prediction("brake-6", 0.008, acceleration=-6.0),
    Prediction("brake-8", 0.002, acceleration=-8.0),
    Prediction("lane-change-left", 0.05, lane_change=1),
    Prediction("lane-change-right", 0.05, lane_change=-1),
)


@dataclass(frozen=True, slots=True)
class PredictionSet:
    """The TO predictions of a scene and the time grid they are sampled on.

    Parameters
    ----------
    predictions : tuple of Prediction, default: :data:`DEFAULT_PREDICTIONS`
        Priors must sum to 1 (within 1e-9).
    horizon : float, default: 5.0
        Prediction horizon (s); collisions later than this are not seen.
    dt : float, default: 0.1
        Sampling step (s) of trajectories and collision checks, and the grid step of TTR start
        times; ``horizon / dt`` must be an integer.
    lane_change_duration : float, default: 4.0
        Duration (s, at the current speed) of a lateral move by one lane width; shorter moves
        take proportionally less, but at least ``min_lateral_duration``.
    min_lateral_duration : float, default: 1.0
        Shortest lateral move (s).
    lane_anticipation : float, default: 1.0
        The reference lane of a vehicle is the lane containing ``y + v sin(heading) *
        lane_anticipation``: a TO already drifting across a lane marking keeps the lane it is
        heading into.
    path_speed_floor : float, default: 5.0
        Lateral paths are laid out in space with length ``duration * max(v cos(heading),
        path_speed_floor)``, so that slow or stopping vehicles do not move sideways on the spot.
    acceleration_sigma : float, default: 1.0
        Uncertainty (m/s², standard deviation) of a TO's acceleration over the horizon, around
        its current one: a prediction with ``acceleration=None`` ("keep") stands for a normal
        distribution N(a, sigma²) of accelerations, integrated by Gauss-Hermite quadrature
        (:meth:`expanded`). It covers the fit error of the measured acceleration (0.6 m/s²
        RMS on the A9 cut-in) and the driver's changes over the horizon. 0: the current
        acceleration alone.
    acceleration_nodes : int, default: 11
        Quadrature nodes per "keep" prediction (1 to 21).
    acceleration_bounds : (float, float), default: (-10.0, 6.0)
        The current acceleration is clipped to these bounds (m/s²) before use: a glitch of the
        fit (|a| of 100 m/s² and more) cannot send a prediction off the road.
    lane_heading_limit : float, default: π/4
        A vehicle whose heading lies within this angle (rad) of the road's direction (+x or -x)
        follows the lanes; otherwise (crossing, turning) it is predicted in its own frame
        (:func:`~simcred.risk.scene.road_frames`).
    max_lateral_acceleration : float, default: 8.0
        The initial curvature of a path, yaw_rate / v, is clipped to ±this / max(v,
        path_speed_floor)² (m/s², about the friction limit): a spurious yaw rate of the fit
        does not bend the path beyond what tyres allow.
    """

    predictions: tuple[Prediction, ...] = DEFAULT_PREDICTIONS
    horizon: float = 5.0
    dt: float = 0.1
    lane_change_duration: float = 4.0
    min_lateral_duration: float = 1.0
    lane_anticipation: float = 1.0
    path_speed_floor: float = 5.0
    acceleration_sigma: float = 1.0
    acceleration_nodes: int = 11
    acceleration_bounds: tuple[float, float] = (-10.0, 6.0)
    lane_heading_limit: float = math.pi / 4
    max_lateral_acceleration: float = 8.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "predictions", tuple(self.predictions))
        object.__setattr__(self, "acceleration_bounds", tuple(self.acceleration_bounds))
        require(len(self.predictions) > 0, "predictions must not be empty")
        for p in self.predictions:
            require(isinstance(p, Prediction), f"predictions must be Prediction, got {p!r}")
        require(len(set(self.names)) == len(self.names), "prediction names must be unique")
        total = math.fsum(self.probabilities)
        require(abs(total - 1.0) <= 1e-9, f"prediction probabilities must sum to 1, got {total!r}")
        for name in ("horizon", "dt", "lane_change_duration", "min_lateral_duration",
                     "path_speed_floor", "max_lateral_acceleration"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, f"{name} must be > 0, got {value!r}")
        require(math.isfinite(self.lane_anticipation) and self.lane_anticipation >= 0,
                 f"lane_anticipation must be >= 0, got {self.lane_anticipation!r}")
        steps = self.horizon / self.dt
        require(abs(steps - round(steps)) <= 1e-9 * max(1.0, steps),
                 f"horizon / dt must be an integer, got {self.horizon!r} / {self.dt!r}")
        require(1 <= round(steps) <= 100_000,
                 f"horizon / dt must lie in [1, 100000], got {round(steps)}")
        require(math.isfinite(self.acceleration_sigma) and self.acceleration_sigma >= 0,
                 f"acceleration_sigma must be >= 0, got {self.acceleration_sigma!r}")
        require(isinstance(self.acceleration_nodes, int) and 1 <= self.acceleration_nodes <= 21,
                 f"acceleration_nodes must be an integer in [1, 21], got "
                 f"{self.acceleration_nodes!r}")
        low_high = self.acceleration_bounds
        require(len(low_high) == 2 and all(math.isfinite(b) for b in low_high)
                 and low_high[0] <= 0 <= low_high[1],
                 f"acceleration_bounds must be (low <= 0, high >= 0), got {low_high!r}")
        require(0 < self.lane_heading_limit <= math.pi / 2,
                 f"lane_heading_limit must lie in (0, pi/2], got {self.lane_heading_limit!r}")

    @property
    def names(self) -> tuple[str, ...]:
        """Prediction names, in order."""
        return tuple(p.name for p in self.predictions)

    @property
    def probabilities(self) -> np.ndarray:
        """Prior probabilities, in order."""
        return np.array([p.probability for p in self.predictions])

    @property
    def times(self) -> np.ndarray:
        """Sample times 0, dt, ..., horizon (s)."""
        return np.arange(round(self.horizon / self.dt) + 1) * self.dt

    def expanded(self) -> PredictionSet:
        """The set with every "keep" prediction (``acceleration=None``) replaced by its
        quadrature nodes: accelerations a + sigma·z_k with probabilities p·w_k, where (z_k, w_k)
        are the probabilists' Gauss-Hermite nodes and weights of N(0, 1) (Σ w_k = 1); named
        ``"<name>[<offset m/s²>]"``. Returns the set itself when there is nothing to expand.

        Examples
        --------
        >>> PredictionSet(acceleration_nodes=3).expanded().names[:3]
        ('keep[-1.73]', 'keep[+0.00]', 'keep[+1.73]')
        """
        if self.acceleration_sigma == 0 or self.acceleration_nodes == 1:
            return self
        z, w = hermegauss(self.acceleration_nodes)
        w = w / w.sum()
        out: list[Prediction] = []
        for p in self.predictions:
            if p.acceleration is not None:
                out.append(p)
                continue
            offsets = p.acceleration_offset + self.acceleration_sigma * z
            out += [replace(p, name=f"{p.name}[{offset:+.2f}]", probability=p.probability * wk,
                            acceleration_offset=float(offset))
                    for offset, wk in zip(offsets, w, strict=True)]
        return replace(self, predictions=tuple(out), acceleration_sigma=0.0)


@dataclass(frozen=True, slots=True)
class EvasionSet:
    """The EGO's evasive maneuvers and the resolution of the TTR search.

    Parameters
    ----------
    maneuvers : tuple of str, default: ("brake", "left", "right", "kickdown")
        A non-empty subset of :data:`MANEUVERS`, in any order (result codes index this tuple):
        the evasive maneuvers of the TTR of [1] (after Hillenbrand et al.'s TTB, TTS, TTK).
    brake_acceleration : float, default: -8.0
        Full braking (m/s²), applied instantaneously (no jerk ramp), to standstill.
    kickdown_acceleration : float, default: 11.5
        Full acceleration (m/s²) below ``kickdown_switch_speed``; above it the engine's power
        limits it to ``kickdown_acceleration * kickdown_switch_speed / v`` (constant power).
        Defaults: the longitudinal limits of CommonRoad's vehicle model 2 (BMW 320i,
        commonroad-vehicle-models), as commonroad-crime's TTK uses them: 3.0 m/s² at 100 km/h.
    kickdown_switch_speed : float, default: 7.319
        Speed (m/s) above which the kickdown is power-limited.
    max_speed : float, default: 50.8
        The kickdown accelerates up to this speed (m/s) and then holds it.
    lateral_acceleration : float, default: 5.0
        Peak lateral acceleration (m/s²) of a steer by one lane width; fixes its duration
        ``sqrt(10/√3 * width / lateral_acceleration)`` (2.0 s for 3.5 m at 5 m/s²).
    min_steer_speed : float, default: 5.0
        Steering is available only if the EGO's planned speed stays >= this (m/s) from the start
        to the end of the steer.
    bisection_steps : int, default: 4
        Bisection steps refining the TTR below the grid step: resolution ``dt / 2**steps``.
    scan_step : int, default: 2
        Start times are scanned every ``scan_step`` samples before the bisection (which takes
        ``log2(scan_step)`` more steps, so the resolution stays ``dt / 2**bisection_steps``): a
        non-monotone gap shorter than ``scan_step * dt`` in the avoidable starts may go
        unseen. 1 scans every sample.
    """

    maneuvers: tuple[str, ...] = MANEUVERS
    brake_acceleration: float = -8.0
    kickdown_acceleration: float = 11.5
    kickdown_switch_speed: float = 7.319
    max_speed: float = 50.8
    lateral_acceleration: float = 5.0
    min_steer_speed: float = 5.0
    bisection_steps: int = 4
    scan_step: int = 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "maneuvers", tuple(self.maneuvers))
        require(len(self.maneuvers) > 0 and len(set(self.maneuvers)) == len(self.maneuvers)
                 and set(self.maneuvers) <= set(MANEUVERS),
                 f"maneuvers must be distinct names out of {', '.join(MANEUVERS)}, got "
                 f"{self.maneuvers!r}")
        require(math.isfinite(self.brake_acceleration) and self.brake_acceleration < 0,
                 f"brake_acceleration must be < 0, got {self.brake_acceleration!r}")
        for name in ("kickdown_acceleration", "kickdown_switch_speed", "max_speed"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0, f"{name} must be > 0, got {value!r}")
        require(math.isfinite(self.lateral_acceleration) and self.lateral_acceleration > 0,
                 f"lateral_acceleration must be > 0, got {self.lateral_acceleration!r}")
        require(math.isfinite(self.min_steer_speed) and self.min_steer_speed >= 0,
                 f"min_steer_speed must be >= 0, got {self.min_steer_speed!r}")
        require(isinstance(self.scan_step, int) and 1 <= self.scan_step <= 64,
                 f"scan_step must be an integer in [1, 64], got {self.scan_step!r}")
        require(isinstance(self.bisection_steps, int) and 0 <= self.bisection_steps <= 30,
                 f"bisection_steps must be an integer in [0, 30], got {self.bisection_steps!r}")

    def steer_duration(self, offset: float) -> float:
        """Duration (s) of a lateral move by ``offset`` at peak ``lateral_acceleration``."""
        return math.sqrt(_SMOOTHSTEP_PEAK_ACCEL * abs(offset) / self.lateral_acceleration)

    def kickdown_travel(self, v0: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance and speed after time ``t`` >= 0 of kickdown from speed ``v0`` >= 0.

        Three phases: constant acceleration a up to the switch speed v_s; constant power
        P = a·v_s up to ``max_speed``, where v(τ)² = u² + 2Pτ from speed u and the distance is
        (v(τ)³ - u³) / (3P); then constant speed. A vehicle already faster than ``max_speed``
        keeps its speed.

        Examples
        --------
        >>> d, v = EvasionSet().kickdown_travel(np.array([27.8]), np.array([1.0]))
        >>> d.round(2), v.round(2)
        (array([29.26]), array([30.68]))
        """
        a, v_s = self.kickdown_acceleration, self.kickdown_switch_speed
        power = a * v_s
        t1 = np.maximum((min(v_s, self.max_speed) - v0) / a, 0.0)
        tau1 = np.minimum(t, t1)
        x1, u1 = v0 * tau1 + 0.5 * a * tau1 * tau1, v0 + a * tau1
        u = np.maximum(v0, v_s)
        t2 = np.maximum((self.max_speed ** 2 - u * u) / (2.0 * power), 0.0)
        tau2 = np.clip(t - t1, 0.0, t2)
        w = np.sqrt(u * u + 2.0 * power * tau2)
        x2 = (w * w * w - u * u * u) / (3.0 * power)
        top = np.maximum(v0, self.max_speed)
        tau3 = np.maximum(t - t1 - t2, 0.0)
        speed = np.where(t <= t1, u1, np.where(tau3 > 0, top, w))
        return x1 + x2 + top * tau3, speed


@dataclass(frozen=True, slots=True)
class ReactionTime:
    """Log-normal reaction/response time T; a TTR of τ ends in an accident with P(T > τ).

    Parameters
    ----------
    median : float, default: 1.0
        Median response time (s).
    sigma : float, default: 0.5
        Standard deviation of ln T.
    """

    median: float = 1.0
    sigma: float = 0.5

    def __post_init__(self) -> None:
        require(math.isfinite(self.median) and self.median > 0,
                 f"reaction median must be > 0, got {self.median!r}")
        require(math.isfinite(self.sigma) and self.sigma > 0,
                 f"reaction sigma must be > 0, got {self.sigma!r}")

    def accident_probability(self, ttr: ArrayLike) -> np.ndarray:
        """g(τ) = P(T > τ) = Φ(-(ln τ - ln median) / sigma); g(0) = 1, g(inf) = 0.

        Examples
        --------
        >>> ReactionTime().accident_probability([0.0, 1.0, np.inf])
        array([1. , 0.5, 0. ])
        """
        with np.errstate(divide="ignore"):
            z = (np.log(np.asarray(ttr, dtype=float)) - math.log(self.median)) / self.sigma
        return ndtr(-z)


# -- trajectories ------------------------------------------------------------------------------


def travel_distance(v0: np.ndarray, a: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and speed after time ``t`` at constant acceleration ``a``, speed floored at 0."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t_stop = np.where(a < 0, v0 / -a, np.inf)
    te = np.minimum(t, t_stop)
    return v0 * te + 0.5 * a * te * te, np.maximum(v0 + a * te, 0.0)


@dataclass(frozen=True, slots=True)
class PredictedPath:
    """Lateral path y(ξ) over longitudinal travel ξ: a quintic from the current lateral state to
    a lane centre, reached with zero slope and curvature after length ``length``, then straight.
    Stored in the normalised variable u = ξ / length: y = y0 + Σ_k b_k u^k, k = 1..5."""

    y0: np.ndarray
    b: tuple[np.ndarray, ...]
    length: np.ndarray

    def at(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lateral position y and slope dy/dξ after travel ``xi``."""
        b1, b2, b3, b4, b5 = self.b
        u = np.minimum(xi / self.length, 1.0)
        y = self.y0 + u * (b1 + u * (b2 + u * (b3 + u * (b4 + u * b5))))
        dydu = b1 + u * (2.0 * b2 + u * (3.0 * b3 + u * (4.0 * b4 + u * (5.0 * b5))))
        return y, dydu / self.length


def predicted_path(y0: np.ndarray, heading: np.ndarray, curvature: np.ndarray, target: np.ndarray,
          length: np.ndarray) -> PredictedPath:
    """Quintic with y(0) = y0, y'(0) = tan(heading), y''(0) = curvature / cos³(heading) and
    y = target, y' = y'' = 0 at ξ = length (the standard quintic boundary-value solution)."""
    h = target - y0
    m = np.tan(heading) * length                  # b1 = y'(0) L
    k = curvature / np.cos(heading) ** 3 * length * length  # y''(0) L²
    b3 = (20.0 * h - 12.0 * m - 3.0 * k) / 2.0
    b4 = (-30.0 * h + 16.0 * m + 3.0 * k) / 2.0
    b5 = (12.0 * h - 6.0 * m - k) / 2.0
    return PredictedPath(y0, (m, k / 2.0, b3, b4, b5), length)


def lateral_plan(s: dict[str, np.ndarray], centre: np.ndarray, lane_change: np.ndarray,
                 cfg: PredictionSet, lanes: Lanes) -> PredictedPath:
    """Path of vehicles ``s`` (local states of their road frames, lane centres at ``centre +
    k·lanes.width``) to their reference lane shifted by ``lane_change`` lanes."""
    v_lon = s["v"] * np.cos(s["heading"])
    anticipated = s["y"] + s["v"] * np.sin(s["heading"]) * cfg.lane_anticipation
    target = centre + np.round((anticipated - centre) / lanes.width) * lanes.width
    target = target + lane_change * lanes.width
    duration = np.maximum(cfg.lane_change_duration * np.abs(target - s["y"]) / lanes.width,
                          cfg.min_lateral_duration)
    speed = np.maximum(s["v"], cfg.path_speed_floor)
    bound = cfg.max_lateral_acceleration / (speed * speed)
    curvature = np.clip(s["yaw_rate"] / speed, -bound, bound)
    length = duration * np.maximum(v_lon, cfg.path_speed_floor)
    return predicted_path(s["y"], s["heading"], curvature, target, length)


def heading_vector(slope: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of the heading of a path with slope dy/dx."""
    cos = 1.0 / np.sqrt(1.0 + slope * slope)
    return cos, slope * cos


def unit_vector(dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of the direction (dx, dy); (1, 0) for a zero vector."""
    norm = np.hypot(dx, dy)
    zero = norm == 0
    norm = np.where(zero, 1.0, norm)
    return np.where(zero, 1.0, dx / norm), dy / norm


def rectangles_overlap(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> np.ndarray:
    """Separating-axis test of oriented rectangles ``(x, y, cos, sin, half_length, half_width)``.

    True where the rectangles overlap or touch; arrays broadcast. Exact for rectangles: two
    convex polygons are disjoint iff their projections on one of the (here four) edge normals
    are disjoint.
    """
    ax, ay, _, _, al, aw = a
    bx, by, _, _, bl, bw = b
    dx, dy = bx - ax, by - ay
    # circumscribed circles first: most sample pairs are far apart, the exact test runs on the
    # rest only
    reach = np.hypot(al, aw) + np.hypot(bl, bw)
    near = dx * dx + dy * dy <= reach * reach
    overlap = np.zeros(near.shape, dtype=bool)
    if near.any():
        parts = np.broadcast_arrays(*a, *b)
        overlap[near] = _separating_axes(tuple(p[near] for p in parts[:6]),
                                         tuple(p[near] for p in parts[6:]))
    return overlap


def _separating_axes(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> np.ndarray:
    """The separating-axis test of :func:`rectangles_overlap` on equal-shaped arrays."""
    ax, ay, ac, as_, al, aw = a
    bx, by, bc, bs, bl, bw = b
    dx, dy = bx - ax, by - ay
    c = np.abs(ac * bc + as_ * bs)     # |cos(θb - θa)|
    s = np.abs(as_ * bc - ac * bs)     # |sin(θb - θa)|
    separated = np.abs(dx * ac + dy * as_) > al + bl * c + bw * s
    separated |= np.abs(dy * ac - dx * as_) > aw + bl * s + bw * c
    separated |= np.abs(dx * bc + dy * bs) > bl + al * c + aw * s
    separated |= np.abs(dy * bc - dx * bs) > bw + al * s + aw * c
    return ~separated


