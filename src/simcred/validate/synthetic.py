"""A synthetic universe with a known validity domain, for tests, docs and examples.

Runs of a scalar process ``x`` (think: a follower's gap error) observed at an operating speed
``v``. Each run starts at a speed drawn uniformly from ``speeds`` and drifts slowly (a random walk
of ``drift`` m/s per √s), so some runs cross cells. The reference follows an AR(1) process
``x' = φ x + σ ε`` around a per-run offset (a driver's trait, so samples within a run are
dependent). The candidate is the same process where ``v < v_switch`` and uses ``φ + effect``
above: its true validity domain is ``v < v_switch``.

The response deviation of ``x`` (per second) grows about linearly with ``effect``: estimated on
1,500 runs × 150 samples per set (seed 0, the validation's five cells 5-10-...-30 m/s):
0.31-0.35 at 0.05, 0.50-0.53 at 0.075, 0.71-0.73 at 0.1, 1.18-1.21 at 0.15 (0-0.08 with no
effect; one-sided 95 % upper bounds 0.07-0.15). :data:`TOLERANCE` is 0.5: an AR-coefficient
error of about 0.075 is tolerated.
"""

from __future__ import annotations

import numpy as np

from simcred.traces import TraceSet

PHI = 0.8
SIGMA = 0.5
TRAIT = 0.3
DT = 0.1
TOLERANCE = 0.5  # tolerated response deviation of x [1/s] (module docs)


def universe(runs: int, steps: int, *, seed: int, effect: float = 0.0,
             v_switch: float = np.inf, speeds: tuple[float, float] = (5.0, 30.0),
             drift: float = 0.5, name: str = "reference") -> TraceSet:
    """``runs`` runs of ``steps`` samples (module docs); ``effect = 0`` gives the reference."""
    rng = np.random.default_rng(seed)
    v0 = rng.uniform(*speeds, size=runs)
    walk = np.cumsum(rng.normal(0.0, drift * np.sqrt(DT), size=(runs, steps)), axis=1)
    v = np.clip(v0[:, None] + walk - walk[:, :1], *speeds)
    trait = rng.normal(0.0, TRAIT, size=runs)
    noise = rng.normal(0.0, SIGMA, size=(runs, steps))
    x = np.empty((runs, steps))
    x[:, 0] = trait + noise[:, 0]
    for k in range(1, steps):
        phi = np.where(v[:, k - 1] < v_switch, PHI, PHI + effect)
        x[:, k] = trait + phi * (x[:, k - 1] - trait) + noise[:, k]
    t = np.arange(steps) * DT
    return TraceSet.from_runs([{"t": t, "v": v[i], "x": x[i]} for i in range(runs)],
                              run_ids=[f"{name}{i:04d}" for i in range(runs)],
                              metadata={"generator": "simcred.validate.synthetic", "seed": seed,
                                        "effect": effect, "v_switch": v_switch},
                              source=name)


def validation_spec(seed: int, *, permutations: int = 99, min_runs: int = 8,
                    tolerance: float = TOLERANCE, conditions: str = "5 <= v <= 30"):
    """The validation of the universe used in docs/validate.md: cells 5-10-...-30 m/s, feature
    ``x`` (4 bins) with the tolerance ``tolerance``, alpha = 0.05, at least ``min_runs`` runs and
    200 samples per side and cell. (Paths are placeholders: pass the sets with
    :class:`~simcred.validate.loop.Inputs`.)"""
    from simcred.validate.spec import parse_validation

    return parse_validation({
        "test_case": {"conditions": conditions, "tolerance": {"x": tolerance}},
        "reference": {"path": "-"}, "candidates": {"sim": {"runs": {"path": "-"}}},
        "features": ["x"], "conditions": {"v": {"unit": "m/s", "edges": [5, 10, 15, 20, 25, 30]}},
        "comparison": {"bins": 4, "permutations": permutations, "alpha": 0.05, "seed": seed},
        "min_data": {"runs": min_runs, "samples": 200}})
