"""The comparison process of Neurohr et al. 2023 [1], sec. V-A (Fig. 2, path a).

Select features → equal-frequency binning on the pooled values → Markov-chain counts → MMD test
of the start distributions (R1; stop if rejected, unless told to continue) → MMD test of the
successor distribution of every start state seen in both sets (R2) → distance = fraction of
rejected states over the whole state space ([1] eq. (6)).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TypeVar

import numpy as np

from simcred.compare.chains import ChainCounts, aligned, successor_counts
from simcred.compare.discretize import StateSpace
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestSpec, Test, mmd_test
from simcred.compare.result import (
    Comparison,
    ComparisonOptions,
    InputInfo,
    StateTest,
    UntestableState,
)
from simcred.errors import OptionError
from simcred.traces import TraceSet

T = TypeVar("T")
Progress = Callable[[Sequence[T]], Iterable[T]]
START_KEY = 0  # seed stream of the start test; state s uses 1 + s


def compare(
    a: TraceSet | str | Path,
    b: TraceSet | str | Path,
    *,
    features: Sequence[str] | str | None = None,
    bins: int | Sequence[int] = 10,
    kernel: str = "gaussian",
    estimator: str = "biased",
    test: str = "bound",
    alpha: float = 0.01,
    permutations: int = 999,
    seed: int | np.random.Generator | None = None,
    continue_on_start_difference: bool = False,
    progress: Progress | None = None,
) -> Comparison:
    """Compare two trace sets as Markov chains with MMD tests ([1] sec. V-A).

    Parameters
    ----------
    a, b : TraceSet or path
        The two sets of runs (a path is read with :meth:`TraceSet.read`).
    features : sequence of str or comma-separated str, default: all signals
        The signals that span the state space. Default: every signal, which requires both sets to
        have the same signal names.
    bins : int or sequence of int, default: 10
        Equal-frequency bins per feature (before duplicate edges are removed), at least 2.
    kernel : {"gaussian", "laplace", "linear"}, default: "gaussian"
        [1] eqs. (3)-(5); Gaussian and Laplace use the median heuristic for σ.
    estimator : {"biased", "unbiased"}, default: "biased"
        MMD_b (the paper's, reported not squared) or MMD²_u.
    test : {"bound", "permutation"}, default: "bound"
        The paper's Gretton-type bound or a permutation test with ``permutations`` resamples.
    alpha : float, default: 0.01
        Level of every single test, in (0, 1).
    permutations : int, default: 999
        Resamples of the permutation test.
    seed : int, Generator or None
        Seed of the permutation test. None draws fresh entropy, which is stored in the result.
    continue_on_start_difference : bool, default: False
        Test the transitions even when the start distributions differ.
    progress : callable, optional
        Wraps the sequence of start states (e.g. a progress bar).

    Returns
    -------
    Comparison

    Notes
    -----
    Each start state's permutation test draws from its own stream
    ``SeedSequence(seed, spawn_key=(1 + state,))``, so results do not depend on the order or the
    worker in which states are tested.

    Examples
    --------
    >>> from simcred.examples import lane_change_sets
    >>> a, b = lane_change_sets(runs=60, steps=40, seed=1)
    >>> result = compare(a, b, features=["x", "y"], bins=5)
    >>> result.n_states, result.stopped
    (25, False)
    """
    a, b = (x if isinstance(x, TraceSet) else TraceSet.read(x) for x in (a, b))
    options, spec = _compare_iv(a, b, features, bins, kernel, estimator, test, alpha,
                                permutations, seed, continue_on_start_difference)
    values_a, values_b = a.features(options.features), b.features(options.features)
    space = StateSpace.equal_frequency(np.vstack([values_a, values_b]), options.bins,
                                       options.features)
    counts_a = ChainCounts.from_codes(space.encode(values_a), a.offsets, space.n_states)
    counts_b = ChainCounts.from_codes(space.encode(values_b), b.offsets, space.n_states)

    states, x, y = aligned(counts_a.start_states, counts_a.start_counts,
                           counts_b.start_states, counts_b.start_counts)
    start = mmd_test(space.vectors(states), x, y, spec, space.shape,
                     _stream(options.seed, START_KEY))
    stopped = start.rejected and not continue_on_start_difference
    tested: list[StateTest] = []
    untestable: list[UntestableState] = []
    if not stopped:
        groups = list(successor_counts(counts_a, counts_b))
        for g in progress(groups) if progress else groups:
            state = tuple(int(i) for i in space.decode([g.state])[0])
            if min(g.m, g.n) < spec.estimator.min_samples:
                untestable.append(UntestableState(state, g.m, g.n))
                continue
            result = mmd_test(space.vectors(g.successors), g.counts_a, g.counts_b, spec,
                              space.shape, _stream(options.seed, 1 + g.state))
            tested.append(StateTest(state, result))
    inputs = tuple(InputInfo(t.source, t.digest(), t.n_runs, t.n_rows) for t in (a, b))
    return Comparison(options, inputs, space, start, stopped, tuple(tested), tuple(untestable))


def _stream(entropy: int, key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(entropy, spawn_key=(key,)))


def resolve_seed(seed: int | np.random.Generator | None) -> int:
    """The integer entropy behind ``seed``: fresh if None, one draw from a Generator."""
    if seed is None:
        return int(np.random.SeedSequence().entropy)
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(2**63))
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise OptionError(f"seed must be a non-negative integer or a numpy Generator, got {seed!r}")
    return int(seed)


def resolve_features(a: TraceSet, b: TraceSet, features: Sequence[str] | str | None
                     ) -> tuple[str, ...]:
    """Explicit features (each must exist in both sets), or all signals when both sets agree."""
    if features is None:
        if set(a.signals) != set(b.signals):
            raise OptionError(
                f"trace sets have different signal names ({a.source}: {sorted(a.signals)}; "
                f"{b.source}: {sorted(b.signals)}); choose the features to compare"
            )
        return a.signals
    names = tuple(f.strip() for f in features.split(",")) if isinstance(features, str) \
        else tuple(features)
    if not names or any(not n for n in names):
        raise OptionError(f"features must be non-empty signal names, got {features!r}")
    if len(set(names)) != len(names):
        raise OptionError(f"features repeat a name: {list(names)}")
    for traces in (a, b):
        traces.features(names)  # raises, naming the set and the unknown signal
    return names


def resolve_bins(bins: int | Sequence[int], n_features: int) -> tuple[int, ...]:
    per_feature = [bins] * n_features if isinstance(bins, numbers.Integral) else list(bins)
    if len(per_feature) != n_features:
        raise OptionError(f"bins gives {len(per_feature)} values for {n_features} features")
    for value in per_feature:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 2:
            raise OptionError(f"bins must be integers >= 2, got {value!r}")
    return tuple(int(v) for v in per_feature)


def _choice(enum: type, value: str, name: str):
    try:
        return enum(value)
    except ValueError:
        choices = ", ".join(e.value for e in enum)
        raise OptionError(f"{name} must be one of {choices}; got {value!r}") from None


def _compare_iv(a, b, features, bins, kernel, estimator, test, alpha, permutations, seed,
                continue_on_start_difference) -> tuple[ComparisonOptions, MMDTestSpec]:
    names = resolve_features(a, b, features)
    spec = MMDTestSpec(
        kernel=_choice(Kernel, kernel, "kernel"),
        estimator=_choice(Estimator, estimator, "estimator"),
        test=_choice(Test, test, "test"),
        alpha=_check_alpha(alpha),
        permutations=_check_permutations(permutations),
    )
    if spec.estimator is Estimator.UNBIASED and min(a.n_runs, b.n_runs) < 2:
        raise OptionError("the unbiased estimator needs at least 2 runs in each trace set "
                          f"({a.source}: {a.n_runs}, {b.source}: {b.n_runs})")
    options = ComparisonOptions(
        features=names,
        bins=resolve_bins(bins, len(names)),
        kernel=spec.kernel.value,
        estimator=spec.estimator.value,
        test=spec.test.value,
        alpha=spec.alpha,
        permutations=spec.permutations if spec.test is Test.PERMUTATION else None,
        seed=resolve_seed(seed),
        continue_on_start_difference=bool(continue_on_start_difference),
    )
    return options, spec


def _check_alpha(alpha: float) -> float:
    if isinstance(alpha, bool) or not isinstance(alpha, numbers.Real) \
            or not math.isfinite(alpha) or not 0 < alpha < 1:
        raise OptionError(f"alpha must be a number in (0, 1), got {alpha!r}")
    return float(alpha)


def _check_permutations(permutations: int) -> int:
    if isinstance(permutations, bool) or not isinstance(permutations, numbers.Integral) \
            or permutations < 1:
        raise OptionError(f"permutations must be a positive integer, got {permutations!r}")
    return int(permutations)
