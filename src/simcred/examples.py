"""Built-in, seeded example trace sets, so that the demo and the docs need no downloaded data."""

from __future__ import annotations

import numpy as np

from simcred.kinematics import LANE_WIDTH
from simcred.limits import check_count, check_finite
from simcred.traces import TraceSet, handed_over


def lane_change_runs(
    runs: int, steps: int, dt: float, duration_scale: float, rng: np.random.Generator,
    source: str,
) -> TraceSet:
    """Lane changes to the left on a straight road, one per run.

    Speed ~ N(20, 1) m/s, start x ~ N(0, 5) m, lane change starting at t ~ U(0.1, 0.4)·T_end with a
    duration ~ N(4, 0.3) s × ``duration_scale`` along a smoothstep, lateral noise N(0, 0.05) m.
    Signals: ``x``, ``y`` (m), ``v`` (m/s), ``heading`` (rad).
    """
    t = np.arange(steps) * dt
    speed = rng.normal(20.0, 1.0, size=(runs, 1))
    x = rng.normal(0.0, 5.0, size=(runs, 1)) + speed * t
    begin = rng.uniform(0.1, 0.4, size=(runs, 1)) * t[-1]
    duration = rng.normal(4.0, 0.3, size=(runs, 1)) * duration_scale
    u = np.clip((t - begin) / duration, 0.0, 1.0)
    y = LANE_WIDTH * u * u * (3 - 2 * u) + rng.normal(0.0, 0.05, size=(runs, steps))
    heading = np.arctan2(np.gradient(y, dt, axis=1), speed)
    return TraceSet(
        signals=("x", "y", "v", "heading"),
        time=handed_over(np.tile(t, runs)),
        values=handed_over(np.column_stack([x.ravel(), y.ravel(),
                                            np.repeat(speed.ravel(), steps), heading.ravel()])),
        offsets=np.arange(runs + 1) * steps,
        run_ids=tuple(f"run_{i:04d}" for i in range(runs)),
        metadata={"model": "example.lane_change", "duration_scale": duration_scale, "dt": dt},
        source=source,
    )


def lane_change_sets(
    runs: int = 300, steps: int = 100, dt: float = 0.1, seed: int = 0,
    duration_scale: float = 0.8,
) -> tuple[TraceSet, TraceSet]:
    """A baseline set and a variant whose lane changes take ``duration_scale`` times as long.

    ``duration_scale=1`` gives two independent samples of the same model (H0 holds).

    >>> a, b = lane_change_sets(runs=3, steps=5, seed=0)
    >>> a.n_runs, b.n_rows, a.signals
    (3, 15, ('x', 'y', 'v', 'heading'))
    """
    _lane_change_sets_iv(runs, steps, dt, duration_scale)
    ss_a, ss_b = np.random.SeedSequence(seed).spawn(2)
    a = lane_change_runs(runs, steps, dt, 1.0, np.random.default_rng(ss_a), "example:baseline")
    b = lane_change_runs(runs, steps, dt, duration_scale, np.random.default_rng(ss_b),
                         "example:variant")
    return a, b


def _lane_change_sets_iv(runs: int, steps: int, dt: float, duration_scale: float) -> None:
    check_count(runs, "runs", "runs")
    check_count(steps, "steps", "steps", minimum=2)
    check_count(runs * steps, "rows", "runs × steps")
    check_finite(dt, "dt", minimum=0, open_minimum=True)
    check_finite(duration_scale, "duration_scale", minimum=0, open_minimum=True)
