"""A manufactured universe for the observed comparison (issue 23): one hidden process, recorded
once as ground truth and once through a sensor.

The hidden process is car following at ``DT`` = 0.1 s: a leader's speed ``u`` (AR(1) around
20 m/s) and a follower's speed ``v`` that closes the speed difference it saw ``reaction`` steps
ago with ``gain`` per second, plus a small process noise. Both signals are recorded; the comparison
features are ``u`` and ``v``.

The sensor (:data:`SENSOR`) is what a real recording adds: a bias, a delay of whole samples,
white noise and 5 % dropouts during which the recording holds its last value. The recording of
run *i* sees the hidden process before the run started (a burn-in), as a real sensor does.
"""

from __future__ import annotations

import numpy as np

from simcred.compare.observed import SensorModel, SignalSensor
from simcred.traces import TraceSet

DT = 0.1
BURN = 50  # steps of hidden process before a run starts (the sensor's delay looks back into it)
SENSOR = SensorModel({
    "u": SignalSensor(offset=0.3, delay=0.3, noise_sd=0.25, dropout=0.05),
    "v": SignalSensor(offset=0.3, delay=0.3, noise_sd=0.25, dropout=0.05),
})


def hidden(rng: np.random.Generator, runs: int, steps: int, *, gain: float = 1.0,
           reaction: int = 5) -> np.ndarray:
    """Hidden states ``(runs, BURN + steps, 2)``: columns u, v."""
    n = BURN + steps
    u = np.empty((runs, n))
    v = np.empty((runs, n))
    u[:, 0] = 20 + rng.normal(0, 2, runs)
    v[:, 0] = u[:, 0] + rng.normal(0, 1, runs)
    for t in range(1, n):
        u[:, t] = 20 + 0.98 * (u[:, t - 1] - 20) + rng.normal(0, 0.4, runs)
        seen = u[:, max(t - 1 - reaction, 0)] - v[:, max(t - 1 - reaction, 0)]
        v[:, t] = v[:, t - 1] + DT * gain * seen + rng.normal(0, 0.05, runs)
    return np.stack([u, v], axis=2)


def traceset(states: np.ndarray) -> TraceSet:
    """``(runs, steps, 2)`` u, v → TraceSet."""
    runs, steps, _ = states.shape
    return TraceSet(("u", "v"), np.tile(np.arange(steps) * DT, runs), states.reshape(-1, 2),
                    np.arange(runs + 1) * steps, tuple(str(i) for i in range(runs)))


def record(rng: np.random.Generator, states: np.ndarray, sensor: SensorModel = SENSOR
           ) -> np.ndarray:
    """What the sensor records of hidden states ``(runs, BURN + steps, 2)``: ``(runs, steps, 2)``.

    Written independently of :func:`simcred.compare.observed.observe` (the oracle): the delayed
    value comes from the burn-in, not from a held first sample.
    """
    runs, n, _ = states.shape
    out = np.empty((runs, n - BURN, 2))
    for j, name in enumerate(("u", "v")):
        s = sensor.signals[name]
        lag = int(round(s.delay / DT))
        seen = states[:, BURN - lag:n - lag, j] + s.offset \
            + s.noise_sd * rng.normal(size=(runs, n - BURN))
        dropped = rng.random((runs, n - BURN)) < s.dropout
        dropped[:, 0] = False
        for t in range(1, n - BURN):
            seen[:, t] = np.where(dropped[:, t], seen[:, t - 1], seen[:, t])
        out[:, :, j] = seen
    return out


def truth(rng: np.random.Generator, runs: int, steps: int, **law: float) -> TraceSet:
    """Ground truth (a simulation's output) of ``runs`` runs."""
    return traceset(hidden(rng, runs, steps, **law)[:, BURN:])


def recording(rng: np.random.Generator, runs: int, steps: int, **law: float) -> TraceSet:
    """The sensor's recording of ``runs`` runs of the hidden process."""
    return traceset(record(rng, hidden(rng, runs, steps, **law)))


def calibration_pairs(rng: np.random.Generator, runs: int, steps: int
                      ) -> tuple[TraceSet, TraceSet]:
    """Paired GT/SD recordings of the same runs (a reference system next to the sensor)."""
    states = hidden(rng, runs, steps)
    return traceset(states[:, BURN:]), traceset(record(rng, states))


def validation(seed: int, *, sensor: SensorModel | None = None, tolerance: float = 0.25):
    """The validation of this universe used by tests/validate/test_observed.py and
    scripts/observed_validate.py: the follower's speed response (``v``, the leader's speed ``u``
    an input), tolerance ``tolerance`` m/s², cells of ``u`` 16-20-24 m/s (the test case), 3 bins,
    P = 99, α = 0.05; ``sensor``: the reference declared observed through it (inline). Paths are
    placeholders: pass the sets with :class:`~simcred.validate.loop.Inputs`."""
    from simcred.validate.spec import parse_validation

    reference: dict = {"path": "-"}
    if sensor is not None:
        reference["observed"] = {"sensor": {k: s.to_dict() for k, s in sensor.signals.items()}}
    return parse_validation({
        "test_case": {"conditions": "16 <= u <= 24", "tolerance": {"v": tolerance}},
        "reference": reference, "candidates": {"sim": {"runs": {"path": "-"}}},
        "features": ["u", "v"], "inputs": ["u"],
        "conditions": {"u": {"unit": "m/s", "edges": [16, 20, 24]}},
        "comparison": {"bins": 3, "permutations": 99, "alpha": 0.05, "seed": seed},
        "min_data": {"runs": 8, "samples": 200}})
