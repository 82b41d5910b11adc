"""The comparison process of Neurohr et al. 2023 [1], sec. V-A (Fig. 2, path a).

Select features → equal-frequency binning on the pooled values → Markov-chain counts → MMD test
of the start distributions (R1; stop if rejected, unless told to continue) → MMD test of the
successor distribution of every start state seen in both sets (R2) → distance = fraction of
rejected states over the whole state space ([1] eq. (6)).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simcred.compare.chains import ChainCounts, aligned, successor_counts
from simcred.compare.design import Design, build_design, runs_design
from simcred.compare.discretize import StateSpace
from simcred.compare.effect import check_margins
from simcred.compare.encoding import (
    EncodedRuns,
    check_history,
    check_time_bins,
    encode,
    state_space,
)
from simcred.compare.facts import SetFacts
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, Test, mmd_test
from simcred.compare.resample import check_periods, check_resample
from simcred.compare.resample import resample as resample_runs
from simcred.compare.result import (
    Comparison,
    ComparisonOptions,
    InputInfo,
    StateTest,
    UntestableState,
)
from simcred.compare.runs import ChainStatistic, Multiplicity, OneSided
from simcred.compare.transitions import response_features
from simcred.engine import Progress
from simcred.errors import OptionError
from simcred.seeds import resolve_seed, stream
from simcred.traces import TraceSet

START_KEY = 0  # seed stream of the start test; state s uses 1 + s
DEFAULT_REPLICATES = 500  # response test: cluster-bootstrap replicates of the effect intervals


# compare() is long only in its signature and docstring (21 documented options, the public face
# of the package); its body is four steps, each a function below.
def compare(
    a: TraceSet | str | Path,
    b: TraceSet | str | Path,
    *,
    features: Sequence[str] | str | None = None,
    bins: int | Sequence[int] = 10,
    kernel: str = "gaussian",
    estimator: str = "biased",
    test: str = "runs",
    alpha: float = 0.01,
    permutations: int = 999,
    seed: int | np.random.Generator | None = None,
    multiplicity: str | None = None,
    chain: str = "sum",
    one_sided: str = "evidence",
    history: int = 1,
    time_bins: int | None = None,
    resample: float | None = None,
    baseline: int = 0,
    bootstrap: int = 0,
    relevance: bool = False,
    continue_on_start_difference: bool = False,
    stop_early: bool = True,
    inputs: Sequence[str] | str = (),
    pair_by: str | None = None,
    group_by: str | None = None,
    margin: float | Mapping[str, float] | None = None,
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
    test : {"runs", "response", "bound", "permutation"}, default: "runs"
        ``runs``: run-level permutation test (whole runs reassigned; valid under any dependence
        within runs) with a chain-level verdict; ``response``: the conditional test of the
        response law given the state (docs/comparison.md: run lengths, visit frequencies,
        start states and declared inputs are not part of its H0; paired and grouped designs;
        effect sizes with intervals; equivalence); ``bound``: the paper's Gretton-type bound;
        ``permutation``: the paper's per-transition permutation test. The last two treat
        transitions as independent samples.
    alpha : float, default: 0.01
        Level of every single test (and of the chain verdict), in (0, 1).
    permutations : int, default: 999
        Resamples of the permutation tests.
    seed : int, Generator or None
        Seed of the permutation tests. None draws fresh entropy, which is stored in the result.
    multiplicity : {"fwer", "fdr", "none"}, default: "fwer" for ``runs``, else "none"
        Control of the per-state verdicts: max-T family-wise, Benjamini–Hochberg, or none (the
        paper's). Only ``runs`` supports "fwer" and "fdr".
    chain : {"sum", "max"}, default: "sum"
        Chain statistic of the run-level test: sum or maximum of standardised state statistics.
    one_sided : {"evidence", "neutral"}, default: "evidence"
        Run-level test: a state without transitions on one side counts as the largest possible
        difference, or as no evidence.
    history : int, default: 1
        States are the last ``history`` binned feature vectors (1 = the paper's chain).
    time_bins : int or None
        Time since run start, binned into ``time_bins`` equal-frequency windows, becomes part
        of the state (time-inhomogeneous chain). At least 2; None = time-homogeneous.
    resample : float or None
        Resample every run to this period (s) by linear interpolation. Without it, sets with
        different sample periods are refused.
    baseline : int, default: 0
        Run-level test: number of random half-splits of set A compared against each other, the
        distance's same-model baseline.
    bootstrap : int, default: 0 (``response``: 500)
        Run-level test: bootstrap replicates (runs resampled within each set) for a re-test
        spread of the distance. Response test: cluster-bootstrap replicates of the effect
        intervals (units resampled within each set, or whole pairs).
    relevance : bool, default: False
        Run-level test: chain statistics on each feature alone and with each feature left out.
    continue_on_start_difference : bool, default: False
        Bound/permutation tests: test the transitions even when the start distributions differ.
    stop_early : bool, default: True
        Permutation test: stop drawing once rejection is impossible (Besag & Clifford 1991).
        Verdicts are those of the full test; p-values above ``alpha`` become sequential
        estimates. False always draws all ``permutations``.
    inputs : sequence of str or comma-separated str
        Response test: features the model does not control (a recorded leader's speed):
        they condition the state but their own evolution is not compared.
    pair_by : str, optional
        Response test: ``"run_id"`` or a per-run fact (``metadata["run_info"]``) that pairs run
        *i* of B with the run of A whose scenario it replays; the null swaps within pairs.
    group_by : str, optional
        Response test: a per-run fact (driver, recording, parent run of a segment) whose runs
        form one exchangeable unit; whole groups are permuted and resampled.
    margin : float or mapping, optional
        Response test: equivalence margin per response feature (its unit per second), or one
        for all; the result says whether equivalence within the margin is shown.
    progress : callable, optional
        Wraps the sequence of start states (e.g. a progress bar).

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
    >>> result = compare(a, b, features=["y"], bins=5, permutations=199, seed=3)
    >>> result.chain.pvalue <= 0.01, result.distance > 0
    (True, True)
    """
    from simcred.io.dataset import is_dataset

    if is_dataset(a) or is_dataset(b):  # Parquet data sets: read out of core
        from simcred.compare.outofcore import compare_datasets

        return compare_datasets(
            a, b, progress=progress, relevance=relevance, features=features, bins=bins,
            kernel=kernel, estimator=estimator, test=test, alpha=alpha, permutations=permutations,
            seed=seed, multiplicity=multiplicity, chain=chain, one_sided=one_sided,
            history=history, time_bins=time_bins, resample=resample, baseline=baseline,
            bootstrap=bootstrap, continue_on_start_difference=continue_on_start_difference,
            stop_early=stop_early, inputs=inputs, pair_by=pair_by, group_by=group_by,
            margin=margin)
    a, b = load(a), load(b)
    options = comparison_options(
        [a, b], features=features, bins=bins, kernel=kernel, estimator=estimator, test=test,
        alpha=alpha, permutations=permutations, seed=seed, multiplicity=multiplicity,
        chain=chain, one_sided=one_sided, history=history, time_bins=time_bins,
        resample=resample, baseline=baseline, bootstrap=bootstrap,
        continue_on_start_difference=continue_on_start_difference, stop_early=stop_early,
        inputs=inputs, pair_by=pair_by, group_by=group_by, margin=margin)
    prepared = [Prepared.for_options(traces, options) for traces in (a, b)]
    design = build_design(a, b, pair_by=options.pair_by, group_by=options.group_by) \
        if Test(options.test) is Test.RESPONSE else None
    units = dict(zip(options.features, feature_units(a, b, options.features), strict=True))
    result = with_units(compare_prepared(*prepared, options, progress, design, units), a, b)
    if relevance:
        from simcred.compare.calibrate import feature_relevance

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
    def for_options(cls, traces: TraceSet, options: ComparisonOptions) -> Prepared:
        """The set as a comparison with ``options`` needs it."""
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
        from simcred.compare.calibrate import run_level_comparison

        return run_level_comparison(runs_a, runs_b, space, options, (a.info, b.info))
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
    names = tuple(f.strip() for f in features.split(",")) if isinstance(features, str) \
        else tuple(features)
    if not names or any(not n for n in names):
        raise OptionError(f"features must be non-empty signal names, got {features!r}")
    if len(set(names)) != len(names):
        raise OptionError(f"features repeat a name: {list(names)}")
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
    return tuple(int(v) for v in per_feature)


def _choice(enum: type, value: str, name: str):
    try:
        return enum(value)
    except ValueError:
        choices = ", ".join(e.value for e in enum)
        raise OptionError(f"{name} must be one of {choices}; got {value!r}") from None


def comparison_options(
    sets: Sequence[TraceSet | SetFacts], *, features=None, bins=10, kernel="gaussian",
    estimator="biased", test="runs", alpha=0.01, permutations=999, seed=None, multiplicity=None,
    chain="sum", one_sided="evidence", history=1, time_bins=None, resample=None, baseline=0,
    bootstrap=0, continue_on_start_difference=False, stop_early=True, inputs=(), pair_by=None,
    group_by=None, margin=None,
) -> ComparisonOptions:
    """Validate every option of :func:`compare` against the trace sets they will be used on
    (or against their :class:`SetFacts`, all these checks need)."""
    sets = [s if isinstance(s, SetFacts) else SetFacts.of(s) for s in sets]
    names = resolve_features(sets, features)
    estimator = _choice(Estimator, estimator, "estimator")
    test = _choice(Test, test, "test")
    runs = test is Test.RUNS
    response = test is Test.RESPONSE
    inputs = _names(inputs, "inputs")
    if not response and (inputs or pair_by or group_by or margin is not None):
        raise OptionError("inputs, pair-by, group-by and margin belong to the response test "
                          "(--test response)")
    if response:
        response_features(names, inputs)
        if baseline:
            raise OptionError("the response test has no random-halves baseline (it cannot see "
                              "heterogeneity of the reference); use --baseline 0")
    multiplicity = _choice(Multiplicity, multiplicity or ("fwer" if runs or response else "none"),
                           "multiplicity")
    if response and multiplicity is not Multiplicity.FWER:
        raise OptionError("the response test's per-state verdicts are family-wise (max-T, "
                          "after the chain verdict); multiplicity must be fwer")
    if not runs and not response and multiplicity is not Multiplicity.NONE:
        raise OptionError(f"multiplicity {multiplicity.value} needs the run-level test "
                          "(--test runs); the paper's tests are per state only")
    small = [s for s in sets if s.n_runs < estimator.min_samples]
    if small:
        raise OptionError(f"the {estimator.value} estimator needs at least "
                          f"{estimator.min_samples} runs per trace set ({small[0].source}: "
                          f"{small[0].n_runs})")
    if runs and baseline and sets[0].n_runs < 4:
        raise OptionError(f"a same-model baseline splits set A into halves and needs at least 4 "
                          f"runs ({sets[0].source}: {sets[0].n_runs}); use --baseline 0")
    resample = check_resample(resample)
    if resample is None:
        check_periods([s.source for s in sets], [s.period for s in sets])
    return ComparisonOptions(
        features=names,
        bins=resolve_bins(bins, len(names)),
        kernel=_choice(Kernel, kernel, "kernel").value,
        estimator=estimator.value,
        test=test.value,
        alpha=_check_alpha(alpha),
        permutations=_check_permutations(permutations) if test is not Test.BOUND else None,
        seed=resolve_seed(seed),
        continue_on_start_difference=bool(continue_on_start_difference),
        stop_early=bool(stop_early) and test is Test.PERMUTATION,
        multiplicity=multiplicity.value,
        chain=_choice(ChainStatistic, chain, "chain").value,
        one_sided=_choice(OneSided, one_sided, "one-sided").value,
        history=check_history(history),
        time_bins=check_time_bins(time_bins),
        resample=resample,
        baseline=_check_count(baseline, "baseline") if runs else 0,
        bootstrap=(_check_count(bootstrap, "bootstrap") or DEFAULT_REPLICATES) if response
        else _check_count(bootstrap, "bootstrap") if runs else 0,
        inputs=inputs,
        pair_by=_key(pair_by, "pair-by"),
        group_by=_key(group_by, "group-by"),
        margin=check_margins(margin, response_features(names, inputs)) if response else (),
    )


def _names(value: Sequence[str] | str, option: str) -> tuple[str, ...]:
    names = tuple(v.strip() for v in value.split(",")) if isinstance(value, str) \
        else tuple(value)
    if any(not isinstance(n, str) or not n for n in names) or len(set(names)) != len(names):
        raise OptionError(f"{option} must be distinct signal names, got {value!r}")
    return names


def _key(value: str | None, option: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise OptionError(f"{option} must be 'run_id' or a per-run fact's name, got {value!r}")
    return value.strip()


def _check_count(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise OptionError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


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
