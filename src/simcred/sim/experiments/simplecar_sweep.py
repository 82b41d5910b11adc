"""The SimpleCar λ sweep of Neurohr et al. 2023 [1], sec. VI-A (Figs. 5-7), in simcred's simulator.

Every run follows the same path, traversed at its own pace: the input functions of the base time
s are time-scaled by τ (speed τ·v(τt), steering speed τ·w(τt)), so the path is the same up to the
start position (x0, y0) ~ N(0, 10²) m, ψ0 = φ0 = 0. For a logical scenario λ, τ ~ U[λ − 0.01, λ].
The runs are sampled every ``dt`` seconds for ``duration`` seconds; the integrator takes
``substeps`` RK4 steps per sample, with the inputs held over each substep.

Base input functions (our design; the paper shows its own only as a plot, Fig. 5):

* speed v(s) = 10 + 3 sin(2π s / 20) m/s;
* steering angle φ(s) = 0.15 sin(2π s / 10) rad, i.e. steering speed w(s) = φ'(s) =
  0.15 · 2π/10 · cos(2π s / 10) rad/s — a weaving path of about 200 m in 20 s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simcred.seeds import stream
from simcred.sim.campaign import run_id
from simcred.sim.vehicles import SimpleCar, rk4_step
from simcred.traces import TraceSet, handed_over

SPEED_MEAN, SPEED_AMPLITUDE, SPEED_PERIOD = 10.0, 3.0, 20.0  # m/s, m/s, s
STEERING_AMPLITUDE, STEERING_PERIOD = 0.15, 10.0  # rad, s
START_STD = 10.0  # m, x0 and y0 ~ N(0, START_STD²)
LAMBDAS = tuple(round(0.81 + 0.01 * k, 2) for k in range(40))  # 0.81 … 1.20


def base_inputs(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed v(s) (m/s) and steering speed w(s) (rad/s) at base time s (Fig. 5)."""
    speed = SPEED_MEAN + SPEED_AMPLITUDE * np.sin(2 * np.pi * s / SPEED_PERIOD)
    omega = 2 * np.pi / STEERING_PERIOD
    return speed, STEERING_AMPLITUDE * omega * np.cos(omega * s)


def draw_runs(indices: Sequence[int], seed: int, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Per run, from its own stream: τ ~ U[λ − 0.01, λ] and (x0, y0) ~ N(0, 10²)."""
    tau, start = np.empty(len(indices)), np.empty((len(indices), 2))
    for k, i in enumerate(indices):
        rng = stream(seed, i)
        tau[k] = rng.uniform(lam - 0.01, lam)
        start[k] = rng.normal(0.0, START_STD, size=2)
    return tau, start


def simulate(
    indices: Sequence[int],
    seed: int,
    *,
    lam: float,
    dt: float = 2.0,
    duration: float = 40.0,
    substeps: int = 10,
    wheelbase: float = 2.5,
) -> TraceSet:
    """Runs ``indices`` of the logical scenario λ = ``lam``: signals x, y (m), heading (rad), v."""
    car = SimpleCar(wheelbase)
    tau, start = draw_runs(indices, seed, lam)
    steps = int(round(duration / dt)) + 1
    h = dt / substeps
    state = np.zeros((len(indices), 4))
    state[:, :2] = start
    out = np.empty((steps, len(indices), 4))
    out[0] = state
    for k in range(1, steps):
        for j in range(substeps):
            t = (k - 1) * dt + j * h
            speed, steering_rate = base_inputs(tau * t)
            state = rk4_step(car, state, np.stack([tau * speed, tau * steering_rate], axis=1), h)
        out[k] = state
    sample_times = (np.arange(steps) * dt)[:, None]
    speed_at_samples = tau[None, :] * base_inputs(tau[None, :] * sample_times)[0]
    values = np.stack([out[..., 0], out[..., 1], out[..., 2], speed_at_samples], axis=2)
    runs = len(indices)
    return TraceSet(
        signals=("x", "y", "heading", "v"),
        time=handed_over(np.tile(np.arange(steps) * dt, runs)),
        values=handed_over(values.transpose(1, 0, 2).reshape(runs * steps, 4)),
        offsets=np.arange(runs + 1) * steps,
        run_ids=tuple(run_id(i) for i in indices),
        metadata={"model": "simplecar", "lambda": lam, "dt": dt, "duration": duration,
                  "substeps": substeps, "wheelbase": wheelbase},
        source=f"simplecar(lambda={lam})",
    )
