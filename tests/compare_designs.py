"""Seeded designs for the comparison's calibration suites (tests/compare/): H0 and shifted.

Every generator returns one TraceSet of runs with signals x, y; two calls with one rng give two
independent sets of the same process. ``PAIRS`` are the H0 designs as functions rng → (A, B):
the same process in both sets, with the same run-length law except ``lengths`` and
``lengthsvar``, where only the run lengths differ.
"""

from __future__ import annotations

import numpy as np

from simcred.traces import TraceSet


def traceset(xy: np.ndarray, dt: float = 1.0) -> TraceSet:
    """(runs, steps, 2) array → TraceSet with signals x, y."""
    runs, steps, _ = xy.shape
    return TraceSet(("x", "y"), np.tile(np.arange(steps) * dt, runs), xy.reshape(-1, 2),
                    np.arange(runs + 1) * steps, tuple(str(i) for i in range(runs)))


def ragged(runs: list[np.ndarray], dt: float = 1.0) -> TraceSet:
    """Runs of unequal length, each a (steps, 2) array → TraceSet with signals x, y."""
    lengths = np.array([len(r) for r in runs])
    time = np.concatenate([np.arange(n) * dt for n in lengths])
    return TraceSet(("x", "y"), time, np.concatenate(runs), np.r_[0, np.cumsum(lengths)],
                    tuple(str(i) for i in range(len(runs))))


def ar1(rng, runs, steps, phi, level, noise):
    """x_t = level + phi (x_{t-1} - level) + noise·e_t, per run ``level`` and ``noise``."""
    x = np.empty((runs, steps))
    x[:, 0] = level + noise * rng.normal(size=runs) / np.sqrt(1 - phi * phi)
    for t in range(1, steps):
        x[:, t] = level + phi * (x[:, t - 1] - level) + noise * rng.normal(size=runs)
    return x


def traits(rng, runs=40, steps=40, shift=0.0):
    theta = rng.beta(2, 5, size=runs) + shift
    x = ar1(rng, runs, steps, 0.8, 3 * theta, 0.3 + theta)
    y = ar1(rng, runs, steps, 0.5, -2 * theta, 0.5)
    return traceset(np.stack([x, y], axis=2))


def selfloops(rng, runs=40, steps=100, dt=0.1, shift=0.0):
    acc = np.empty((runs, steps))
    acc[:, 0] = rng.normal(0, 0.5, size=runs)
    for t in range(1, steps):
        acc[:, t] = 0.97 * acc[:, t - 1] + rng.normal(0, 0.12 * (1 + shift), size=runs)
    speed = rng.normal(15, 2, size=runs)[:, None] + np.cumsum(acc, axis=1) * dt
    return traceset(np.stack([speed, acc], axis=2), dt)


def fewruns(rng, steps=40):
    runs = int(rng.integers(20, 51))
    theta = rng.beta(2, 2, size=runs)
    x = ar1(rng, runs, steps, 0.7, theta, 1.0)
    y = ar1(rng, runs, steps, 0.3, 0.0, 1.0)
    return traceset(np.stack([x, y], axis=2))


def secondorder(rng, runs=40, steps=40):
    def ar2(a1, a2):
        x = np.zeros((runs, steps + 20))
        for t in range(2, steps + 20):
            x[:, t] = a1 * x[:, t - 1] + a2 * x[:, t - 2] + rng.normal(size=runs)
        return x[:, 20:]
    return traceset(np.stack([ar2(1.5, -0.7), ar2(0.2, 0.6)], axis=2))


def timephase(rng, runs=40, steps=45, brake=1.0, noise=1.0):
    t = np.arange(steps)
    phase_acc = np.where(t < 15, 1.0, np.where(t < 30, 0.0, -1.2 * brake))
    acc = phase_acc[None, :] * rng.uniform(0.7, 1.3, size=(runs, 1)) \
        + rng.normal(0, 0.4 * noise, size=(runs, steps))
    speed = 10 + np.cumsum(acc, axis=1)
    return traceset(np.stack([speed, acc], axis=2))


#: First-order chain on four values of x (y: an independent fair coin), and a variant in which
#: only the successor law of x = 0 differs.
MARKOV = np.array([[.6, .3, .1, 0], [.2, .5, .2, .1], [.1, .2, .5, .2], [0, .1, .3, .6]])
MARKOV_ROW0 = np.array([.3, .4, .2, .1])


def markov(rng, lengths, row0=MARKOV[0]):
    """Runs of the MARKOV chain (x, coin y) of the given lengths, started uniformly."""
    cum = np.vstack([row0, MARKOV[1:]]).cumsum(axis=1)
    cum[:, -1] = 1.0  # no rounding below 1: u < 1 always finds a successor
    runs, steps = len(lengths), int(max(lengths))
    x = np.empty((runs, steps), dtype=int)
    x[:, 0] = rng.integers(0, 4, size=runs)
    u = rng.random((runs, steps))
    for t in range(1, steps):
        x[:, t] = (u[:, t, None] >= cum[x[:, t - 1]]).sum(axis=1)
    xy = np.stack([x, rng.integers(0, 2, size=(runs, steps))], axis=2).astype(float)
    return ragged([run[:n] for run, n in zip(xy, lengths, strict=True)])


def ar1_ragged(rng, lengths, phi=0.8):
    """Stationary AR(1) x (φ = phi) and y (φ = 0.5), one run per entry of ``lengths``."""
    steps = int(max(lengths))
    xy = np.stack([ar1(rng, len(lengths), steps, phi, 0.0, 1.0),
                   ar1(rng, len(lengths), steps, 0.5, 0.0, 1.0)], axis=2)
    return ragged([run[:n] for run, n in zip(xy, lengths, strict=True)])


def lengths(rng, runs=40):
    """Same Markov chain; A's runs have 10 steps, B's 100."""
    return markov(rng, [10] * runs), markov(rng, [100] * runs)


def lengthsvar(rng, runs=40):
    """Same AR(1) process; run lengths U{20..40} in A, U{30..50} in B."""
    return (ar1_ragged(rng, rng.integers(20, 41, size=runs)),
            ar1_ragged(rng, rng.integers(30, 51, size=runs)))


def onestate(rng, runs=40, steps=30):
    """Only the successor law of x = 0 differs (MARKOV_ROW0 in B): a partial null for all other
    states."""
    return markov(rng, [steps] * runs), markov(rng, [steps] * runs, MARKOV_ROW0)


GENERATORS = {"traits": traits, "selfloops": selfloops, "fewruns": fewruns,
              "secondorder": secondorder, "timephase": timephase}


def same(generator):
    """rng → two independent sets of ``generator``'s process."""
    return lambda rng: (generator(rng), generator(rng))


PAIRS = {**{name: same(g) for name, g in GENERATORS.items()},
         "lengths": lengths, "lengthsvar": lengthsvar}
