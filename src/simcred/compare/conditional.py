"""The conditional comparison (``test="response"``): one answer to "does the candidate respond to
the situation as the reference does?", and, by name, what is *not* part of that question.

* **response** — :mod:`simcred.compare.response` on the adjusted responses of
  :mod:`simcred.compare.transitions`: the chain verdict and the gatekept per-state verdicts;
* **start** — where runs start (the start-state law; a scenario property in a replay design);
* **occupancy** — how often each state is visited (the transition-weighted state law);
* **lengths** — the run-length law (mean log length per unit);
* **effect** — :mod:`simcred.compare.effect`: the response deviation per feature in its unit,
  with a cluster-bootstrap interval, equivalence against declared margins, detectable effect.

All tests share the design's assignments (the same units, permuted the same way), so the start,
occupancy and lengths p-values are exact under the same exchangeability as the response test.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.design import Design, DesignKind
from simcred.compare.discretize import StateSpace
from simcred.compare.effect import (
    ENTRY,
    FEW_UNITS,
    EffectSummary,
    effect_null,
    rate_unit,
    response_effects,
)
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestResult
from simcred.compare.paired_runs import paired_statistics, run_summaries, tippett
from simcred.compare.response import ResponseOutcome, response_test
from simcred.compare.result import (
    ChainVerdict,
    Comparison,
    ComparisonOptions,
    InputInfo,
    StateTest,
    UntestableState,
)
from simcred.compare.run_counts import START, RunCounts
from simcred.compare.runs import (
    ChainStatistic,
    Multiplicity,
    OneSided,
    RunTestSpec,
    exceedance_pvalues,
    run_level_test,
)
from simcred.compare.threads import beside
from simcred.compare.transitions import transitions
from simcred.compare.unit_sums import unique_inverse
from simcred.seeds import stream

#: Seed-stream keys (spawn keys of the comparison seed).
ASSIGN_KEY, RESPONSE_KEY, EFFECT_KEY = 2**41, 2**41 + 1, 2**41 + 2
OCCUPANCY = -2  # block code of the occupancy law
INTERVAL_LEVEL = 0.95
#: Assignments per batch of the lengths test's side means (two float64 buffers of this many rows).
GAP_ROWS = 64


@dataclass(frozen=True, slots=True)
class NamedTest:
    """A test of one named property that is not the response law."""

    name: str
    statistic: float
    pvalue: float
    rejected: bool


@dataclass(frozen=True, slots=True)
class DesignInfo:
    """The design that was tested: kind, key, units per side, smallest attainable p-value."""

    kind: str
    key: str | None
    units_a: int
    units_b: int
    smallest_pvalue: float


@dataclass(frozen=True, slots=True)
class ResponseAnalysis:
    """What the conditional comparison adds to a :class:`Comparison`."""

    design: DesignInfo
    inputs: tuple[str, ...]
    response: tuple[str, ...]
    bandwidth: tuple[float, ...]
    scenario: tuple[NamedTest, ...]
    effect: EffectSummary
    warnings: tuple[str, ...]


def response_comparison(parts, design: Design, space: StateSpace, options: ComparisonOptions,
                        inputs: tuple[InputInfo, InputInfo], units: dict[str, str]
                        ) -> Comparison:
    """The conditional comparison of two prepared and encoded sets.

    ``parts``: per set ``(values, time, offsets, codes)`` as :func:`transitions` takes them.
    """
    assignments = design.assignments(options.permutations, stream(options.seed, ASSIGN_KEY))
    with beside(_scenario_and_runs, parts, design, space, options, assignments) as side:
        data = transitions(parts, design.unit_of_run, options.features, options.inputs,
                           options.history)
        with beside(effect_null, data, design, assignments) as null:
            outcome = response_test(data, design.n_units, assignments,
                                    stream(options.seed, RESPONSE_KEY))
            prepared = null.result()
        (start, scenario), runs = side.result()
    if runs is not None:
        outcome = with_paired_runs(outcome, runs)
    rate_units = {name: rate_unit(units.get(name)) for name in data.response}
    effect = response_effects(data, design, options.bootstrap, options.alpha, INTERVAL_LEVEL,
                              options.margin, rate_units, stream(options.seed, EFFECT_KEY),
                              assignments, prepared=prepared)
    analysis = ResponseAnalysis(
        DesignInfo(design.kind.value, design.key, design.units_a,
                   design.n_units - design.units_a, design.smallest_pvalue),
        options.inputs, data.response, outcome.bandwidth, scenario, effect,
        _warnings(design, options, outcome, effect))
    return _comparison(outcome, start, space, options, inputs, analysis)


def _scenario_and_runs(parts, design: Design, space: StateSpace, options: ComparisonOptions,
                       assignments: np.ndarray):
    """What does not depend on the transitions: the scenario tests and, for pairs, the pairs'
    run-summary statistic of every assignment (None otherwise)."""
    runs = paired_run_statistics(parts, design, options, assignments) \
        if design.kind is DesignKind.PAIRS else None
    return scenario_tests(parts, design, space, options, assignments), runs


def paired_run_statistics(parts, design: Design, options: ComparisonOptions,
                          assignments: np.ndarray) -> np.ndarray:
    """The pairs' run-summary statistic (:mod:`simcred.compare.paired_runs`) of every
    assignment (row 0 observed)."""
    response = [options.features.index(n) for n in options.features if n not in options.inputs]
    per_run = np.vstack([run_summaries(p[0][:, response], p[2]) for p in parts])
    return paired_statistics(unit_means(per_run, parts, design), design.units_a, assignments)


def with_paired_runs(outcome: ResponseOutcome, runs: np.ndarray) -> ResponseOutcome:
    """The chain verdict of a paired design: the state-conditional statistic and the pairs'
    run summaries ``runs`` (:func:`paired_run_statistics`), combined by Tippett's rule over the
    same assignments (exact under the pair flips)."""
    chain = tippett(outcome.chain_null, runs)
    pvalue = float(exceedance_pvalues(chain[:, None], chain[:1])[0])
    return dataclasses.replace(outcome, chain_statistic=float(chain[0]), chain_pvalue=pvalue,
                               chain_null=chain)


def unit_means(per_run: np.ndarray, parts, design: Design) -> np.ndarray:
    """(units, columns) length-weighted means of the runs' rows of ``per_run`` over each unit
    (a member of a pair may hold several runs: the segments of one replayed run)."""
    if np.bincount(design.unit_of_run, minlength=design.n_units).max() == 1:
        out = np.empty_like(per_run)
        out[design.unit_of_run] = per_run
        return out
    lengths = np.concatenate([np.diff(p[2]) for p in parts]).astype(np.float64)
    weight = sp.csr_matrix((lengths, (design.unit_of_run, np.arange(len(lengths)))),
                           shape=(design.n_units, len(lengths)))
    return np.asarray(weight @ per_run) / np.asarray(weight.sum(axis=1))


def scenario_tests(parts, design: Design, space: StateSpace, options: ComparisonOptions,
                   assignments: np.ndarray) -> tuple[MMDTestResult, tuple[NamedTest, ...]]:
    """Start law, occupancy law and run-length law under the design's assignments."""
    counts = _scenario_counts(parts, design, options.history)
    spec = RunTestSpec(Kernel.GAUSSIAN, Estimator.BIASED, options.permutations, options.alpha,
                       Multiplicity.NONE, ChainStatistic.SUM, OneSided.EVIDENCE)
    outcome = run_level_test(counts, assignments[0], space.decode, spec, space.shape, None,
                             null=assignments[1:])
    start_i = int(np.flatnonzero(outcome.blocks == START)[0])
    occupancy_i = int(np.flatnonzero(outcome.blocks == OCCUPANCY)[0])
    start = MMDTestResult(int(outcome.m[start_i]), int(outcome.n[start_i]),
                          float(outcome.statistic[start_i]),
                          bool(outcome.pvalue[start_i] <= options.alpha),
                          pvalue=float(outcome.pvalue[start_i]),
                          bandwidth=float(outcome.bandwidth[start_i]),
                          n_resamples=outcome.permutations)
    named = [NamedTest(name, float(outcome.statistic[i]), float(outcome.pvalue[i]),
                       bool(outcome.pvalue[i] <= options.alpha))
             for name, i in (("start", start_i), ("occupancy", occupancy_i))]
    named.append(_lengths_test(parts, design, assignments, options.alpha))
    return start, tuple(named)


def _scenario_counts(parts, design: Design, history: int) -> RunCounts:
    """Per unit: counts of start states (block START) and of all visited states (OCCUPANCY)."""
    codes = np.concatenate([p[3] for p in parts])
    coded = np.concatenate([np.diff(p[2]) - (history - 1) for p in parts])
    run = np.repeat(np.arange(len(coded)), coded)
    unit = design.unit_of_run[run]
    first = np.r_[0, np.cumsum(coded)[:-1]]
    blocks = [_count_block(codes[first], design.unit_of_run, design.n_units),
              _count_block(codes, unit, design.n_units)]
    states = [b[1] for b in blocks]
    matrix = sp.vstack([b[0] for b in blocks]).tocsr()
    bounds = np.r_[0, np.cumsum([len(s) for s in states])]
    return RunCounts(matrix, np.array([START, OCCUPANCY]), bounds, np.concatenate(states))


def _count_block(codes: np.ndarray, unit: np.ndarray, n_units: int):
    states, index = unique_inverse(codes)
    matrix = sp.csr_matrix((np.ones(len(codes)), (index, unit)), shape=(len(states), n_units))
    matrix.sum_duplicates()
    return matrix, states


def _lengths_test(parts, design: Design, assignments: np.ndarray, alpha: float) -> NamedTest:
    """|difference of the mean log length per unit| between the sides, permuted like the rest."""
    lengths = np.concatenate([np.diff(p[2]) for p in parts]).astype(np.float64)
    per_unit = np.bincount(design.unit_of_run, weights=lengths, minlength=design.n_units)
    stat = side_mean_gap(assignments, np.log(per_unit))
    pvalue = float(exceedance_pvalues(stat[:, None], stat[:1])[0])
    return NamedTest("lengths", float(stat[0]), pvalue, pvalue <= alpha)


def side_mean_gap(assignments: np.ndarray, value: np.ndarray) -> np.ndarray:
    """Per assignment ``|mean of value over A − mean over B|``, as float64 row products
    ``Z v / Z 1`` and ``(1 − Z) v / (1 − Z) 1``, :data:`GAP_ROWS` assignments at a time in two
    reused buffers (the whole float64 ``Z`` and ``1 − Z`` were 0.6 GB of fresh memory at 1,000
    assignments of 40,000 units)."""
    side_a = np.empty((min(GAP_ROWS, len(assignments)), assignments.shape[1]))
    side_b = np.empty_like(side_a)
    stat = np.empty(len(assignments))
    for lo in range(0, len(assignments), GAP_ROWS):
        rows = assignments[lo:lo + GAP_ROWS]
        a, b = side_a[:len(rows)], side_b[:len(rows)]
        np.copyto(a, rows)
        np.subtract(1, a, out=b)
        stat[lo:lo + len(rows)] = np.abs(a @ value / a.sum(axis=1) - b @ value / b.sum(axis=1))
    return stat


def _warnings(design: Design, options: ComparisonOptions, outcome: ResponseOutcome,
              effect: EffectSummary) -> tuple[str, ...]:
    out = []
    floor = max(design.smallest_pvalue, 1.0 / (options.permutations + 1))
    if floor > options.alpha:
        what = f"{design.units_a} pairs" if design.kind is DesignKind.PAIRS else \
            f"{design.units_a} vs {design.n_units - design.units_a} units"
        out.append(f"this design cannot reject at alpha = {options.alpha:g}: its smallest "
                   f"p-value is {floor:.3g} ({what}, {options.permutations} permutations); "
                   "'no difference shown' means nothing here")
    if not outcome.in_family.any():
        out.append("no state is visited by both sets with a response that varies: the response "
                   "law could not be compared")
    if effect.states == 0:
        out.append(f"no state {ENTRY}: the deviation "
                   "cannot be estimated (this is not 'no deviation'); use fewer bins or more runs")
    elif effect.units_per_state < FEW_UNITS:
        out.append(f"the deviation rests on {effect.units_per_state:.1f} units per state (the "
                   f"side with fewer, weighted): below {FEW_UNITS} its interval is not calibrated "
                   "and the estimate of a heavy-tailed response leans high (docs/calibration.md, "
                   "'Session 30'); decide on its bounds and p-value, or use fewer bins or more "
                   "runs")
    return tuple(out)


def _comparison(outcome: ResponseOutcome, start: MMDTestResult, space: StateSpace,
                options: ComparisonOptions, inputs, analysis: ResponseAnalysis) -> Comparison:
    rejected = outcome.rejected(options.alpha)
    tested, untestable = [], []
    for i, code in enumerate(outcome.states):
        cell = tuple(int(v) for v in space.decode([code])[0])
        if min(outcome.m[i], outcome.n[i]) < 1:
            untestable.append(UntestableState(cell, int(outcome.m[i]), int(outcome.n[i])))
            continue
        tested.append(StateTest(cell, MMDTestResult(
            int(outcome.m[i]), int(outcome.n[i]), float(outcome.statistic[i]),
            bool(rejected[i]), pvalue=float(outcome.pvalue[i]),
            n_resamples=outcome.permutations, adjusted_pvalue=float(outcome.adjusted[i]))))
    combine = "pooled states per feature + response profile" + (
        " + paired runs" if analysis.design.kind == DesignKind.PAIRS.value else "") + " (Tippett)"
    chain = ChainVerdict("response", combine, outcome.chain_statistic, outcome.chain_pvalue,
                         outcome.chain_pvalue <= options.alpha, outcome.permutations,
                         int(outcome.in_family.sum()))
    return Comparison(options, inputs, space, start, False, tuple(tested), tuple(untestable),
                      chain=chain, response=analysis)
