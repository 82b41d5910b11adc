"""Batched vehicle models: many runs stepped at once, state arrays of shape (runs, states).

Every model is a :class:`VehicleModel`: named states and inputs, a batched right-hand side
``derivatives(state, inputs)`` and a pose ``(x, y, heading)``. :func:`rk4_step` integrates any of
them with a fixed step; :func:`initial_state` builds start states by state name.

Models: :class:`SimpleCar` ([1] eq. (8)); :class:`KinematicSingleTrack` (KS) and
:class:`SingleTrack` (ST) of CommonRoad [2], vectorised from the reference code [3] with the same
arithmetic, so that they agree with it to rounding; :class:`CommonRoadLoop` runs the reference code
itself, one state at a time (slow, the oracle). Parameters are CommonRoad's own parameter sets,
by default vehicle 2 (BMW 320i).

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of
    ADSs, IEEE Access, 2023.
[2] Althoff & Würsching, CommonRoad: Vehicle Models (version 2020a), TU Munich, 2020.
[3] commonroad-vehicle-models 3.0.2 (Python package ``vehiclemodels``): ``vehicle_dynamics_ks``,
    ``vehicle_dynamics_st``, ``utils/vehicle_dynamics_ks_cog``, ``utils/steering_constraints``,
    ``utils/acceleration_constraints``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Protocol

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import OptionError

if TYPE_CHECKING:
    from vehiclemodels.vehicle_parameters import VehicleParameters


class VehicleModel(Protocol):
    """What the simulator needs of a vehicle model."""

    name: str
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]

    def derivatives(self, state: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Time derivative of ``state`` (runs, states) under ``inputs`` (runs, inputs)."""
        ...

    def pose(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position x, y (m) and heading (rad) of every run."""
        ...


def rk4_step(model: VehicleModel, state: np.ndarray, inputs: np.ndarray, dt: float
             ) -> np.ndarray:
    """One classical Runge-Kutta step of length ``dt``, inputs held constant over the step."""
    k1 = model.derivatives(state, inputs)
    k2 = model.derivatives(state + 0.5 * dt * k1, inputs)
    k3 = model.derivatives(state + 0.5 * dt * k2, inputs)
    k4 = model.derivatives(state + dt * k3, inputs)
    return state + (dt / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


@dataclass(frozen=True, slots=True)
class SimpleCar:
    """SimpleCar of Neurohr et al. 2023 [1], eq. (8).

    States (x, y, ψ, φ): position, heading, steering angle. Inputs (u_v, u_φ̇): speed and
    steering speed. ẋ = u_v cos ψ, ẏ = u_v sin ψ, ψ̇ = u_v/L · tan φ, φ̇ = u_φ̇.
    """

    wheelbase: float = 2.5
    name: str = "simplecar"
    state_names: tuple[str, ...] = ("x", "y", "heading", "steering")
    input_names: tuple[str, ...] = ("speed", "steering_rate")

    def derivatives(self, state: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        heading, steering = state[:, 2], state[:, 3]
        speed, steering_rate = inputs[:, 0], inputs[:, 1]
        return np.stack([
            speed * np.cos(heading),                       # [1] eq. (8)
            speed * np.sin(heading),
            speed / self.wheelbase * np.tan(steering),
            steering_rate,
        ], axis=1)

    def pose(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return state[:, 0], state[:, 1], state[:, 2]


def initial_state(model: VehicleModel, **values: ArrayLike) -> np.ndarray:
    """Start states of ``model``, one row per run, from values given by state name.

    The batched counterpart of CommonRoad's ``init_ks`` / ``init_st`` [3], which take the states
    as given. Values broadcast against each other; states not named start at 0 (for ST: yaw rate
    and slip angle, as when driving straight).

    Parameters
    ----------
    model : VehicleModel
        The model whose ``state_names`` name the columns.
    **values : array_like
        Scalars or 1-D arrays, e.g. ``x=0, y=0, heading=0.1, speed=10``.

    Returns
    -------
    numpy.ndarray
        Shape (runs, len(model.state_names)), float64.

    Examples
    --------
    >>> initial_state(SimpleCar(), x=[0.0, 5.0], y=1.0, heading=0.5)
    array([[0. , 1. , 0.5, 0. ],
           [5. , 1. , 0.5, 0. ]])
    """
    for name, value in values.items():
        if name not in model.state_names:
            raise ValueError(f"model {model.name!r} has no state {name!r}; its states are "
                             f"{', '.join(model.state_names)}")
        if np.ndim(value) > 1:
            raise ValueError(f"initial {name!r} must be a scalar or 1-D, one value per run")
        if not np.all(np.isfinite(value)):
            raise ValueError(f"initial {name!r} must be finite")
    columns = np.broadcast_arrays(*(np.asarray(values.get(name, 0.0), dtype=float)
                                    for name in model.state_names))
    return np.stack(columns, axis=-1).reshape(-1, len(model.state_names))


def _bmw_320i() -> VehicleParameters:
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2

    return parameters_vehicle2()


# Hard-coded in vehicle_dynamics_st [3], not part of the parameter sets.
_GRAVITY = 9.81
_CRAWL_SPEED = 0.1  # below this |speed| ST switches to the kinematic model


def _constrained_inputs(steering: np.ndarray, speed: np.ndarray, inputs: np.ndarray,
                        p: VehicleParameters) -> tuple[np.ndarray, np.ndarray]:
    """Steering rate and acceleration after CommonRoad's input constraints, [3] utils.

    ``steering_constraints``: no steering further into a steering-angle limit, otherwise the rate
    is clipped to [v_min, v_max]. ``acceleration_constraints``: no acceleration beyond the speed
    limits, otherwise clipped to [-a_max, a_max · min(1, v_switch / speed)] (engine power limit).
    """
    s, lon = p.steering, p.longitudinal
    steering_rate, acceleration = inputs[:, 0], inputs[:, 1]
    stop_steering = (((steering <= s.min) & (steering_rate <= 0))
                     | ((steering >= s.max) & (steering_rate >= 0)))
    steering_rate = np.where(stop_steering, 0.0, np.clip(steering_rate, s.v_min, s.v_max))
    # np.maximum keeps the unused branch free of division by zero
    power_limit = np.where(speed > lon.v_switch,
                           lon.a_max * lon.v_switch / np.maximum(speed, lon.v_switch), lon.a_max)
    stop_speed = (((speed <= lon.v_min) & (acceleration <= 0))
                  | ((speed >= lon.v_max) & (acceleration >= 0)))
    acceleration = np.where(stop_speed, 0.0, np.clip(acceleration, -lon.a_max, power_limit))
    return steering_rate, acceleration


@dataclass(frozen=True, slots=True)
class CommonRoadLoop:
    """A per-state model function of commonroad-vehicle-models [3], looped over the runs.

    The reference the batched models are checked and timed against: each row goes through the
    library's own function as Python floats. Obtain one with ``model.reference()``.

    Parameters
    ----------
    dynamics : callable
        ``f(x, u, p) -> list``, e.g. ``vehiclemodels.vehicle_dynamics_ks.vehicle_dynamics_ks``.
    params : VehicleParameters
        CommonRoad parameter set passed as ``p``.
    name, state_names, input_names : str, tuple of str
        As for the batched model it stands in for.
    """

    dynamics: Callable[[list, list, VehicleParameters], list]
    params: VehicleParameters = field(hash=False)  # a mutable dataclass
    name: str
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]

    def derivatives(self, state: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        rows = [self.dynamics(x, u, self.params)
                for x, u in zip(state.tolist(), inputs.tolist(), strict=True)]
        return np.array(rows, dtype=float).reshape(state.shape)

    def pose(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return state[:, 0], state[:, 1], state[:, self.state_names.index("heading")]


class _CommonRoadModel:
    """What KS and ST share: CommonRoad's state order (x, y, steering, speed, heading, …)."""

    __slots__ = ()
    _reference_module: ClassVar[str]  # vehiclemodels.<module> holding the function of that name

    def pose(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return state[:, 0], state[:, 1], state[:, 4]

    def reference(self) -> CommonRoadLoop:
        """The same model run through commonroad-vehicle-models' own per-state function [3]."""
        module = importlib.import_module(f"vehiclemodels.{self._reference_module}")
        return CommonRoadLoop(getattr(module, self._reference_module), self.params,
                              f"{self.name}-commonroad", self.state_names, self.input_names)


@dataclass(frozen=True, slots=True)
class KinematicSingleTrack(_CommonRoadModel):
    """Kinematic single-track model (KS) of CommonRoad [2], batched; reference point: rear axle.

    States (x, y, δ, v, ψ): rear-axle position, steering angle, speed, heading. Inputs
    (v_δ, a_long): steering angle velocity and longitudinal acceleration, first passed through
    CommonRoad's steering and acceleration constraints. With l = a + b ([3]
    ``vehicle_dynamics_ks``)

    .. math::
        \\dot x = v \\cos ψ, \\quad \\dot y = v \\sin ψ, \\quad \\dot δ = v_δ, \\quad
        \\dot v = a_{long}, \\quad \\dot ψ = \\frac{v}{l} \\tan δ.

    Parameters
    ----------
    params : VehicleParameters, default: CommonRoad vehicle 2 (BMW 320i)
        A CommonRoad parameter set, e.g. ``parameters_vehicle1()`` from
        ``vehiclemodels.parameters_vehicle1`` (Ford Escort).

    Notes
    -----
    Same arithmetic as [3], in the same order, so derivatives agree with ``reference()`` to
    rounding of the elementary functions. SimpleCar ([1] eq. (8)) is this model with the speed as
    an input instead of a state and no input constraints.
    """

    params: VehicleParameters = field(default_factory=_bmw_320i, hash=False)
    name: str = "ks"
    state_names: tuple[str, ...] = ("x", "y", "steering", "speed", "heading")
    input_names: tuple[str, ...] = ("steering_rate", "acceleration")
    _reference_module: ClassVar[str] = "vehicle_dynamics_ks"

    def derivatives(self, state: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        p = self.params
        steering, speed, heading = state[:, 2], state[:, 3], state[:, 4]
        steering_rate, acceleration = _constrained_inputs(steering, speed, inputs, p)
        return np.stack([
            speed * np.cos(heading),
            speed * np.sin(heading),
            steering_rate,
            acceleration,
            speed / (p.a + p.b) * np.tan(steering),
        ], axis=1)


@dataclass(frozen=True, slots=True)
class SingleTrack(_CommonRoadModel):
    """Single-track model (ST) of CommonRoad [2], batched; reference point: centre of gravity.

    States (x, y, δ, v, ψ, ψ̇, β): position of the centre of gravity, steering angle, speed,
    heading, yaw rate, slip angle. Inputs and constraints as :class:`KinematicSingleTrack`.
    Linear tyres with cornering stiffness C_S = -p_ky1 / p_dy1 and friction μ = p_dy1, load
    transfer through the sprung-mass height h_s. For |v| ≥ 0.1 m/s ([3] ``vehicle_dynamics_st``)

    .. math::
        \\dot x = v \\cos(ψ + β), \\quad \\dot y = v \\sin(ψ + β), \\quad \\dot ψ = ψ̇,

    and ψ̈, β̇ from the tyre forces. Below 0.1 m/s, where those divide by v, it uses the kinematic
    model about the centre of gravity (``vehicle_dynamics_ks_cog``: β_ks = atan(tan δ · b / l),
    position along ψ + β_ks, ψ̇ = v cos β_ks tan δ / l) and the time derivatives of its yaw rate and
    slip angle as ψ̈, β̇.

    Parameters
    ----------
    params : VehicleParameters, default: CommonRoad vehicle 2 (BMW 320i)
        A CommonRoad parameter set.

    Notes
    -----
    Reproduces [3], including what differs from [2] and from a derivation:

    * In the low-speed branch [3] computes β̇ = b v_δ / (l cos²δ (1 + (tan²δ · b / l)²)); the
      derivative of atan(tan δ · b / l) has (tan δ · b / l)² there. Kept as in [3]; with
      vehicle 2 its β̇ is 0.3 % too large at δ = 0.1 rad, 2.6 % at 0.3 rad and half the
      derivative's at the steering limit (1.066 rad).
    * In that branch ψ̈ uses the slip angle state β where the kinematic model it differentiates
      uses β_ks, and the heading follows the kinematic yaw rate, not the state ψ̇.
    * The speed v is the speed at the centre of gravity; in KS it is the rear axle's.
    """

    params: VehicleParameters = field(default_factory=_bmw_320i, hash=False)
    name: str = "st"
    state_names: tuple[str, ...] = (
        "x", "y", "steering", "speed", "heading", "yaw_rate", "slip_angle")
    input_names: tuple[str, ...] = ("steering_rate", "acceleration")
    _reference_module: ClassVar[str] = "vehicle_dynamics_st"

    def derivatives(self, state: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        p = self.params
        g = _GRAVITY
        mu = p.tire.p_dy1
        c_sf = c_sr = -p.tire.p_ky1 / p.tire.p_dy1
        lf, lr, h, m, inertia = p.a, p.b, p.h_s, p.m, p.I_z
        lwb = p.a + p.b
        steering, speed, heading, yaw_rate, slip = (state[:, i] for i in range(2, 7))
        steering_rate, acceleration = _constrained_inputs(steering, speed, inputs, p)
        crawl = np.abs(speed) < _CRAWL_SPEED

        # Kinematic branch ([3] vehicle_dynamics_ks_cog and the lines after it).
        tan_steering = np.tan(steering)
        slip_ks = np.arctan(tan_steering * p.b / lwb)
        yaw_rate_ks = speed * np.cos(slip_ks) * tan_steering / lwb
        slip_rate_ks = (p.b * steering_rate) / (
            lwb * np.cos(steering) ** 2 * (1 + (tan_steering ** 2 * p.b / lwb) ** 2))
        yaw_acc_ks = 1 / lwb * (acceleration * np.cos(slip) * tan_steering
                                - speed * np.sin(slip) * slip_rate_ks * tan_steering
                                + speed * np.cos(slip) * steering_rate / np.cos(steering) ** 2)

        # Dynamic branch; v is replaced in the crawling runs only, whose result is not used.
        v = np.where(crawl, 1.0, speed)
        front = g * lr - acceleration * h  # normal load per unit mass, front and rear axle
        rear = g * lf + acceleration * h
        yaw_acc = (-mu * m / (v * inertia * (lr + lf))
                   * (lf ** 2 * c_sf * front + lr ** 2 * c_sr * rear) * yaw_rate
                   + mu * m / (inertia * (lr + lf))
                   * (lr * c_sr * rear - lf * c_sf * front) * slip
                   + mu * m / (inertia * (lr + lf)) * lf * c_sf * front * steering)
        slip_rate = ((mu / (v ** 2 * (lr + lf)) * (c_sr * rear * lr - c_sf * front * lf) - 1)
                     * yaw_rate
                     - mu / (v * (lr + lf)) * (c_sr * rear + c_sf * front) * slip
                     + mu / (v * (lr + lf)) * (c_sf * front) * steering)

        course = heading + np.where(crawl, slip_ks, slip)
        return np.stack([
            speed * np.cos(course),
            speed * np.sin(course),
            steering_rate,
            acceleration,
            np.where(crawl, yaw_rate_ks, yaw_rate),
            np.where(crawl, yaw_acc_ks, yaw_acc),
            np.where(crawl, slip_rate_ks, slip_rate),
        ], axis=1)


#: The vehicle models an EGO can be simulated with, by their CLI names.
VEHICLE_MODELS: dict[str, Callable[[], VehicleModel]] = {"ks": KinematicSingleTrack,
                                                         "st": SingleTrack}


def vehicle_model(name: str) -> VehicleModel:
    """The EGO vehicle model called ``name`` ("ks" or "st")."""
    try:
        return VEHICLE_MODELS[name]()
    except KeyError:
        raise OptionError(f"unknown vehicle model {name!r} "
                          f"(choose one of: {', '.join(VEHICLE_MODELS)})") from None
