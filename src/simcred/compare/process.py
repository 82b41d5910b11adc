"""The comparison process of Neurohr et al. 2023 [1], sec. V-A (Fig. 2, path a).

Select features → equal-frequency binning on the pooled values → Markov-chain counts → MMD test
of the start distributions (R1; stop if rejected, unless told to continue) → MMD test of the
successor distribution of every start state seen in both sets (R2) → distance = fraction of
rejected states over the whole state space ([1] eq. (6)).
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simcred.compare.chains import ChainCounts, aligned, successor_counts
from simcred.compare.design import Design, build_design, runs_design
from simcred.compare.discretize import StateSpace
from simcred.compare.effect import check_margins
from simcred.compare.encoding import EncodedRuns, encode, state_space
from simcred.compare.facts import SetFacts
from simcred.compare.method import Method, feature_names
from simcred.compare.mmd import Test, mmd_test
from simcred.compare.resample import check_periods
from simcred.compare.resample import resample as resample_runs
from simcred.compare.result import (
    Comparison,
    ComparisonOptions,
    InputInfo,
    StateTest,
    UntestableState,
)
from simcred.compare.streamed import TimelessSet, read_timeless
from simcred.compare.transitions import response_features
from simcred.engine import Progress
from simcred.errors import OptionError
from simcred.limits import check_count
from simcred.seeds import resolve_seed, stream
from simcred.traces import TraceSet

START_KEY = 0  # seed stream of the start test; state s uses 1 + s
DEFAULT_REPLICATES = 500  # response test: cluster-bootstrap replicates of the effect intervals


def compare(
    a: TraceSet | str | Path,
    b: TraceSet | str | Path,
    method: Method | None = None,
    *,
    progress: Progress | None = None,
    **options: Any,
) -> Comparison:
    """Compare two trace sets as Markov chains with MMD tests ([1] sec. V-A).

    Parameters
    ----------
    a, b : TraceSet or path
        The two sets of runs (a path is read with :meth:`TraceSet.read`; a Parquet data set is
        read out of core, :func:`~simcred.compare.outofcore.compare_datasets`).
    method : Method, optional
        How to compare (:class:`~simcred.compare.method.Method`: features, bins, kernel,
        estimator, test, alpha, permutations, seed, multiplicity, chain, one_sided, history,
        time_bins, resample, baseline, bootstrap, relevance, inputs, pair_by, group_by, margin,
        continue_on_start_difference, stop_early; each documented there). Default:
        ``Method()``.
    progress : callable, optional
        Wraps the sequence of start states (e.g. a progress bar).
    **options
        Fields of :class:`Method` as keywords: they build the method, or replace fields of
        ``method`` (``compare(a, b, test="bound", bins=5)``).

    Returns
    -------
    Comparison

    Notes
    -----
    Each start state's permutation test draws from its own stream
    ``SeedSequence(seed, spawn_key=(1 + state,))``, so results do not depend on the order or the
    worker in which states are tested. The run-level test draws all its permutations from
    ``SeedSequence(seed, spawn_key=(RUNS_KEY,))``; see docs/comparison.md.

    Examples
    --------
    >>> from simcred.examples import lane_change_sets
    >>> a, b = lane_change_sets(runs=60, steps=40, seed=1)
    >>> result = compare(a, b, features=["x", "y"], bins=5, test="bound")
    >>> result.n_states, result.stopped
    (25, False)
    >>> a, b = lane_change_sets(runs=150, steps=40, seed=1)
    >>> result = compare(a, b, Method(features=["y"], bins=5, permutations=199, seed=3))
    >>> result.chain.pvalue <= 0.01, result.distance > 0
    (True, True)
    """
    from simcred.io.dataset import is_dataset

    method = Method.of(method, **options)
    if is_dataset(a) or is_dataset(b):  # Parquet data sets: read out of core
        from simcred.compare.outofcore import compare_datasets

        return compare_datasets(a, b, method, progress=progress)
    a, b = load_for(a, method), load_for(b, method)
    settings = comparison_options([s.facts() if isinstance(s, TimelessSet) else s
                                   for s in (a, b)], method)
    prepared = [Prepared.for_options(traces, settings) for traces in (a, b)]
    design = build_design(a, b, pair_by=settings.pair_by, group_by=settings.group_by) \
        if Test(settings.test) is Test.RESPONSE else None
    named = feature_units(a, b, settings.features)
    units = dict(zip(settings.features, named, strict=True))
    a = b = None  # sets read here are dropped: their time stamps, unless prepared, go too
    result = compare_prepared(*prepared, settings, progress, design, units)
    if any(named):  # as with_units
        result = dataclasses.replace(result, units=named)
    if method.relevance:
        from simcred.compare.run_level import feature_relevance

        result = feature_relevance(result, *prepared)
    return result


def with_units(result: Comparison, a: TraceSet, b: TraceSet) -> Comparison:
    """``result`` with the features' units of the two sets, where any is known."""
    units = feature_units(a, b, result.options.features)
    return dataclasses.replace(result, units=units) if any(units) else result


def feature_units(a: TraceSet, b: TraceSet, features: Sequence[str]) -> tuple[str, ...]:
    """Unit of every feature ("" if unknown); one-line error if the two sets disagree."""
    units_a, units_b = a.units, b.units
    out = []
    for name in features:
        ua, ub = units_a.get(name), units_b.get(name)
        if ua is not None and ub is not None and ua != ub:
            raise OptionError(f"unit mismatch for '{name}': {a.source} has {ua!r}, "
                              f"{b.source} has {ub!r}")
        out.append(ua or ub or "")
    return tuple(out)


def load(traces: TraceSet | str | Path) -> TraceSet:
    return traces if isinstance(traces, TraceSet) else TraceSet.read(traces)


def load_for(traces: TraceSet | str | Path, method: Method) -> TraceSet | TimelessSet:
    """:func:`load`, or a path read without its time column where ``method`` needs no time
    stamps (:mod:`simcred.compare.streamed`: Parquet files grouped by run)."""
    needs_time = method.time_bins is not None or method.resample is not None \
        or Test(method.test) is Test.RESPONSE
    if not (needs_time or isinstance(traces, TraceSet)):
        timeless = read_timeless(traces)
        if timeless is not None:
            return timeless
    return load(traces)


@dataclass(frozen=True, slots=True, eq=False)
class Prepared:
    """A trace set reduced to what a comparison needs: feature values, time, run offsets,
    identity."""

    values: np.ndarray
    time: np.ndarray
    offsets: np.ndarray
    info: InputInfo

    @classmethod
    def of(cls, traces: TraceSet, features: Sequence[str], resample: float | None = None,
           time: bool = True) -> Prepared:
        """``time=False`` keeps no time stamps (an empty array): only time windows and the
        response test read them, and a set travels to Dask workers a third lighter without."""
        info = InputInfo(traces.source, traces.digest(), traces.n_runs, traces.n_rows)
        if resample is not None:
            traces = resample_runs(traces, resample)
        values = traces.values if tuple(features) == tuple(traces.signals) \
            else traces.features(features)  # all signals in order: the set's own (read-only)
        return cls(values, traces.time if time else np.empty(0), traces.offsets, info)

    @classmethod
    def for_options(cls, traces: TraceSet | TimelessSet, options: ComparisonOptions
                    ) -> Prepared:
        """The set as a comparison with ``options`` needs it (a set read without time stamps:
        one whose options need none)."""
        if isinstance(traces, TimelessSet):
            return cls(traces.features(options.features), np.empty(0), traces.offsets,
                       traces.info)
        needs_time = options.time_bins is not None or Test(options.test) is Test.RESPONSE
        return cls.of(traces, options.features, options.resample, time=needs_time)

    def __sizeof__(self) -> int:
        """Bytes held (:meth:`TraceSet.__sizeof__` says why)."""
        return object.__sizeof__(self) + self.values.nbytes + self.time.nbytes \
            + self.offsets.nbytes

    def encoded(self, space: StateSpace, options: ComparisonOptions) -> EncodedRuns:
        return encode(space, self.values, self.time, self.offsets, options.history,
                      options.time_bins is not None, self.info.source)


def common_space(a: Prepared, b: Prepared, options: ComparisonOptions) -> StateSpace:
    """The state space of a comparison: pooled binning of both sets, history, time windows."""
    return state_space([a.values, b.values], [a.time, b.time], [a.offsets, b.offsets],
                       options.bins, options.features, options.history, options.time_bins)


def compare_prepared(
    a: Prepared, b: Prepared, options: ComparisonOptions, progress: Progress | None = None,
    design: Design | None = None, units: dict[str, str] | None = None,
) -> Comparison:
    """The process of [1] sec. V-A on validated options and prepared sets.

    ``design`` (response test): the units of the runs; default: every run its own unit.
    """
    space = common_space(a, b, options)
    runs_a, runs_b = a.encoded(space, options), b.encoded(space, options)
    if Test(options.test) is Test.RESPONSE:
        from simcred.compare.conditional import response_comparison

        design = design or runs_design(a.info.runs, b.info.runs)
        parts = [(p.values, p.time, p.offsets, r.codes) for p, r in ((a, runs_a), (b, runs_b))]
        return response_comparison(parts, design, space, options, (a.info, b.info),
                                   units or {})
    if Test(options.test) is Test.RUNS:
        from simcred.compare.run_level import counts_comparison, pooled_counts

        counts = pooled_counts(runs_a, runs_b, space)
        n_a = len(runs_a.offsets) - 1
        runs_a = runs_b = None  # the per-row codes (4 to 8 bytes a row) are not held in the test
        return counts_comparison(counts, n_a, space, options, (a.info, b.info))
    spec = options.spec
    counts_a = ChainCounts.from_codes(runs_a.codes, runs_a.offsets, space.n_states)
    counts_b = ChainCounts.from_codes(runs_b.codes, runs_b.offsets, space.n_states)

    states, x, y = aligned(counts_a.start_states, counts_a.start_counts,
                           counts_b.start_states, counts_b.start_counts)
    start = mmd_test(space.vectors(states), x, y, spec, space.shape,
                     stream(options.seed, START_KEY))
    stopped = start.rejected and not options.continue_on_start_difference
    tested: list[StateTest] = []
    untestable: list[UntestableState] = []
    if not stopped:
        groups = list(successor_counts(counts_a, counts_b))
        for g in progress(groups, len(groups)) if progress else groups:
            state = tuple(int(i) for i in space.decode([g.state])[0])
            if min(g.m, g.n) < spec.estimator.min_samples:
                untestable.append(UntestableState(state, g.m, g.n))
                continue
            result = mmd_test(space.vectors(g.successors), g.counts_a, g.counts_b, spec,
                              space.shape, stream(options.seed, 1 + g.state))
            tested.append(StateTest(state, result))
    return Comparison(options, (a.info, b.info), space, start, stopped, tuple(tested),
                      tuple(untestable))


def resolve_features(sets: Sequence[SetFacts], features: Sequence[str] | str | None
                     ) -> tuple[str, ...]:
    """Explicit features (each must exist in every set), or all signals when the sets agree."""
    if features is None:
        for other in sets[1:]:
            if set(other.signals) != set(sets[0].signals):
                raise OptionError(
                    f"trace sets have different signal names ({sets[0].source}: "
                    f"{sorted(sets[0].signals)}; {other.source}: {sorted(other.signals)}); "
                    "choose the features to compare"
                )
        return tuple(sets[0].signals)
    names = feature_names(features)
    for facts in sets:
        facts.check_signals(names)  # raises, naming the set and the unknown signal
    return names


def resolve_bins(bins: int | Sequence[int], n_features: int) -> tuple[int, ...]:
    per_feature = [bins] * n_features if isinstance(bins, numbers.Integral) else list(bins)
    if len(per_feature) != n_features:
        raise OptionError(f"bins gives {len(per_feature)} values for {n_features} features")
    for value in per_feature:
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 2:
            raise OptionError(f"bins must be integers >= 2, got {value!r}")
        check_count(int(value), "bins", "bins")  # before any data is read or simulated
    return tuple(int(v) for v in per_feature)


def comparison_options(sets: Sequence[TraceSet | SetFacts], method: Method | None = None,
                       **options: Any) -> ComparisonOptions:
    """``method`` (or :class:`Method` ``(**options)``) checked against the trace sets it will be
    used on (or their :class:`SetFacts`, all these checks need), resolved into the options a
    result records: the features, bins per feature, the seed's entropy and what the test
    uses."""
    method = Method.of(method, **options)
    sets = [s if isinstance(s, SetFacts) else SetFacts.of(s) for s in sets]
    names = resolve_features(sets, method.features)
    test, estimator = method.test, method.estimator
    runs, response = test is Test.RUNS, test is Test.RESPONSE
    if response:
        response_features(names, method.inputs)
    small = [s for s in sets if s.n_runs < estimator.min_samples]
    if small:
        raise OptionError(f"the {estimator.value} estimator needs at least "
                          f"{estimator.min_samples} runs per trace set ({small[0].source}: "
                          f"{small[0].n_runs})")
    if runs and method.baseline and sets[0].n_runs < 4:
        raise OptionError(f"a same-model baseline splits set A into halves and needs at least 4 "
                          f"runs ({sets[0].source}: {sets[0].n_runs}); use --baseline 0")
    if method.resample is None:
        check_periods([s.source for s in sets], [s.period for s in sets])
    return ComparisonOptions(
        features=names, bins=resolve_bins(method.bins, len(names)),
        kernel=method.kernel.value, estimator=estimator.value, test=test.value,
        alpha=method.alpha, permutations=method.permutations if test is not Test.BOUND else None,
        seed=resolve_seed(method.seed),
        continue_on_start_difference=method.continue_on_start_difference,
        stop_early=method.stop_early and test is Test.PERMUTATION,
        multiplicity=method.multiplicity_used.value, chain=method.chain.value,
        one_sided=method.one_sided.value, history=method.history, time_bins=method.time_bins,
        resample=method.resample, baseline=method.baseline if runs else 0,
        bootstrap=(method.bootstrap or DEFAULT_REPLICATES) if response
        else method.bootstrap if runs else 0,
        inputs=method.inputs, pair_by=method.pair_by, group_by=method.group_by,
        margin=check_margins(method.margins, response_features(names, method.inputs))
        if response else (),
    )
