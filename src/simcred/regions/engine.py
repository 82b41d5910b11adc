"""Compare per region: one response comparison per cell, a status decided on the size of the
deviation, one seed scheme and one too-little-data rule. ``validate`` and ``study`` both use it.

For every candidate and every cell of the operating-condition grid (:mod:`simcred.regions.cells`),
the candidate's segments in the cell are compared with the reference's by the response
comparison (:func:`simcred.compare.compare` with ``test="response"``): the response law given the
state, with the declared inputs conditioned on, on the design's units (pairs of replays, groups,
or the runs the segments were cut from). For each reported feature it gives the response
deviation ``E`` with bootstrap bounds. With ``K`` the Bonferroni family (the cells of the test
case; all cells of a study) and ``α`` the comparison's level, a cell is

* ``valid`` when every ``E`` with a tolerance ``δ`` is shown below it: the one-sided upper
  ``1 − α`` bound is below ``δ`` (an intersection–union test over features and cells: no
  adjustment needed);
* ``not valid`` when some ``E`` is shown above its ``δ``: the one-sided lower ``1 − α/K`` bound
  is above ``δ`` and the permutation test of ``E`` rejects the same law at ``α/K`` (a candidate
  within tolerance everywhere comes out not valid in at most ``α`` of cases over the ``K`` cells);
* ``inconclusive`` otherwise: the data cannot place the deviation on either side of ``δ``;
* ``unknown`` when either side has fewer design units or samples than the :class:`MinData` rule;
* ``compared`` when no reported feature has a tolerance: the deviations, their bounds and the
  difference test are reported, nothing is judged (a study without a requirement).

Seeds: every comparison is seeded by :func:`cell_seed` from the user's seed, the candidate's name
and the cell, so results do not depend on the order of candidates or cells.

Design (:class:`CellRule`): pairs (a replay with the run it replays, or a declared key) or groups
(a declared key, by default the runs the segments were cut from). In a paired cell, runs whose
partner has no segment in the cell are left out (counted in the reason).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from simcred.compare import Comparison, Method, compare
from simcred.compare.design import RUN_ID, unit_keys
from simcred.compare.effect import FeatureEffect
from simcred.compare.mmd import Test
from simcred.errors import OptionError
from simcred.regions.cells import SOURCE_RUN, Grid, Segments, segments
from simcred.seeds import named_seed
from simcred.traces import TraceSet, take


class CellStatus(StrEnum):
    VALID = "valid"
    NOT_VALID = "not valid"
    INCONCLUSIVE = "inconclusive"
    UNKNOWN = "unknown"
    COMPARED = "compared"


#: The statuses a tolerance decides (``compared`` only where there is no tolerance).
DECIDED = (CellStatus.VALID, CellStatus.NOT_VALID, CellStatus.INCONCLUSIVE, CellStatus.UNKNOWN)


@dataclass(frozen=True, slots=True)
class FeatureBounds:
    """One feature's deviation in one cell: the estimate, the one-sided bounds a decision uses
    (``upper`` at ``1 − α``, ``lower`` at ``1 − α/K``), the two-sided 95 % interval, the smallest
    uniform shift the data could detect (80 % power), the deviation's permutation p-value and
    ``floor``, the power floor of the upper bound at ``α`` (``upper`` is never below it; a cell
    whose floor reaches its tolerance cannot be shown valid with these data);
    ``tolerance`` None: reported, not judged."""

    feature: str
    unit: str
    tolerance: float | None
    estimate: float
    lower: float
    upper: float
    low: float
    high: float
    detectable: float
    pvalue: float
    floor: float = float("nan")


@dataclass(frozen=True, slots=True, eq=False)
class CellResult:
    """One candidate in one cell: data counts, the design, the deviations, the status."""

    cell: int
    index: tuple[int, ...]
    label: str
    status: CellStatus
    reason: str
    reference_units: int
    reference_samples: int
    candidate_units: int
    candidate_samples: int
    design: str = ""
    pvalue: float | None = None
    bounds: tuple[FeatureBounds, ...] = ()
    seed: int | None = None
    comparison: Comparison | None = None

    def worst(self) -> float:
        """The largest estimate relative to its tolerance (NaN when none is judged)."""
        ratios = [b.estimate / b.tolerance for b in self.bounds if b.tolerance is not None]
        return max(ratios) if ratios else float("nan")

    def to_dict(self) -> dict[str, Any]:
        return {"cell": self.cell, "index": list(self.index), "label": self.label,
                "status": self.status.value, "reason": self.reason,
                "reference": {"units": self.reference_units, "samples": self.reference_samples},
                "candidate": {"units": self.candidate_units, "samples": self.candidate_samples},
                "design": self.design, "difference_pvalue": self.pvalue,
                "deviation": [_bounds_dict(b) for b in self.bounds], "seed": self.seed}


def _bounds_dict(b: FeatureBounds) -> dict[str, Any]:
    return {"feature": b.feature, "unit": b.unit, "tolerance": b.tolerance,
            "estimate": b.estimate, "lower": b.lower, "upper": b.upper,
            "interval_95": [b.low, b.high], "detectable_shift": b.detectable,
            "deviation_pvalue": b.pvalue, "upper_floor": b.floor}


@dataclass(frozen=True, slots=True, eq=False)
class Domain:
    """One candidate over the grid: a result per cell (its learned validity domain when the
    cells are judged)."""

    candidate: str
    grid: Grid
    cells: tuple[CellResult, ...]

    def with_status(self, status: CellStatus) -> tuple[CellResult, ...]:
        return tuple(c for c in self.cells if c.status is status)

    def to_dict(self) -> dict[str, Any]:
        counts = {s.value: len(self.with_status(s)) for s in CellStatus
                  if s in DECIDED or self.with_status(s)}
        return {"candidate": self.candidate, "counts": counts,
                "cells": [c.to_dict() for c in self.cells]}


@dataclass(frozen=True, slots=True)
class CellRule:
    """What every cell's decision shares: the level, the Bonferroni family (the test case's
    cells) and how the candidate's runs are paired or grouped (keys of the segments' facts)."""

    alpha: float
    family: int
    pair_by: str | None
    group_by: str | None

    @property
    def design(self) -> str:
        if self.pair_by is not None:
            return f"pairs by {_user_key(self.pair_by)}"
        return f"groups by {_user_key(self.group_by)}"


def cell_rule(alpha: float, family: int, *, pairs: str | None = None, groups: str | None = None,
              replay: bool = False) -> CellRule:
    """The design of one candidate's cells: declared ``pairs`` or ``groups`` (a per-run key or
    ``run_id``), pairs by run for a ``replay`` (a candidate that replays the reference run by
    run), else the runs the segments were cut from as groups."""
    family = max(family, 1)
    if pairs is not None:
        return CellRule(alpha, family, segment_key(pairs), None)
    if groups is not None:
        return CellRule(alpha, family, None, segment_key(groups))
    if replay:
        return CellRule(alpha, family, SOURCE_RUN, None)
    return CellRule(alpha, family, None, SOURCE_RUN)


def cell_seed(seed: int, candidate: str, cell: int) -> int:
    """The seed of one comparison: independent of the order of candidates and cells
    (:func:`simcred.seeds.named_seed` of the candidate and the cell)."""
    return named_seed(seed, candidate, cell)


def segment_key(key: str) -> str:
    """A user's per-run key as a key of the segments' facts (``run_id`` is the source run)."""
    return SOURCE_RUN if key == RUN_ID else key


def _user_key(key: str | None) -> str:
    return "run" if key == SOURCE_RUN else str(key)


@dataclass(frozen=True, slots=True)
class MinData:
    """The too-little-data rule: least design units (pairs, groups or source runs) and samples
    per side and cell; below, the cell is unknown."""

    units: int = 8
    samples: int = 100

    def short(self, counts: tuple[int, int, int, int]) -> str:
        """Why ``(reference units, samples, candidate units, samples)`` are too little, or ''."""
        ref_units, ref_samples, cand_units, cand_samples = counts
        for side, units, samples in (("reference", ref_units, ref_samples),
                                     ("candidate", cand_units, cand_samples)):
            if units < self.units or samples < self.samples:
                return (f"too little data: {side} has {units} units / {samples} samples "
                        f"(needs {self.units} / {self.samples})")
        return ""


@dataclass(frozen=True, slots=True, eq=False)
class CellComparison:
    """What every cell's comparison shares: the response comparison's ``method``
    (:class:`~simcred.compare.Method` with ``test="response"``; its seed is the user's, each
    cell's is derived from it by :func:`cell_seed`, and the cell's design and the tolerance as
    margin are added per cell), the tolerance per response feature (empty: nothing judged), the
    features whose deviations are reported (default: those with a tolerance, else every
    response feature), the too-little-data rule and the shortest segment kept."""

    method: Method
    tolerance: Mapping[str, float] = field(default_factory=dict)
    reported: tuple[str, ...] = ()
    min_data: MinData = field(default_factory=MinData)
    min_length: int = 10

    def __post_init__(self) -> None:
        if self.method.test is not Test.RESPONSE or self.method.features is None \
                or not isinstance(self.method.seed, int):
            raise OptionError("the per-cell comparison is the response test on named features "
                              f"with an integer seed, got {self.method!r}")

    @property
    def features(self) -> tuple[str, ...]:
        return self.method.features

    @property
    def inputs(self) -> tuple[str, ...]:
        return self.method.inputs

    @property
    def response(self) -> tuple[str, ...]:
        return tuple(f for f in self.features if f not in self.inputs)

    @property
    def shown(self) -> tuple[str, ...]:
        """The features whose deviations a cell reports, in order."""
        return self.reported or tuple(self.tolerance) or self.response

    def segments(self, traces: TraceSet, grid: Grid) -> Segments:
        return segments(traces, grid, self.min_length)


def learn_domain(settings: CellComparison, grid: Grid, reference: Segments, candidate: TraceSet,
                 name: str, rule: CellRule) -> Domain:
    """Compare ``candidate`` with the reference in every cell of ``grid`` (module docs)."""
    mine = settings.segments(candidate, grid)
    return Domain(name, grid, tuple(
        compare_cell(settings, grid, cell, name, rule, reference.by_cell.get(cell),
                     mine.by_cell.get(cell)) for cell in range(grid.n_cells)))


def compare_cell(settings: CellComparison, grid: Grid, cell: int, name: str, rule: CellRule,
                 reference: TraceSet | None, candidate: TraceSet | None) -> CellResult:
    """One cell: the reference's and the candidate's segments there (None: none), compared and
    decided (module docs); seeded by :func:`cell_seed` (``name``, ``cell``)."""
    head = (cell, grid.index(cell), grid.label(cell))
    if reference is None or candidate is None:
        counts = (count_units(reference, rule), _samples(reference),
                  count_units(candidate, rule), _samples(candidate))
        return CellResult(*head, CellStatus.UNKNOWN, settings.min_data.short(counts), *counts,
                          rule.design)
    ref, cand, dropped = matched(reference, candidate, rule)
    counts = (count_units(ref, rule), _samples(ref), count_units(cand, rule), _samples(cand))
    short = settings.min_data.short(counts)
    if short:
        return CellResult(*head, CellStatus.UNKNOWN, short + dropped, *counts, rule.design)
    seed = cell_seed(settings.method.seed, name, cell)
    result = compare(ref, cand, settings.method, seed=seed, pair_by=rule.pair_by,
                     group_by=rule.group_by, margin=dict(settings.tolerance) or None)
    effects = {f.feature: f for f in result.response.effect.features}
    bounds = tuple(_feature_bounds(effects[n], settings.tolerance.get(n), rule)
                   for n in settings.shown)
    status, reason = _decide(bounds, rule)
    return CellResult(*head, status, reason + dropped, *counts, rule.design,
                      float(result.chain.pvalue), bounds, seed, result)


def halves(traces: TraceSet, key: str, seed: int) -> tuple[TraceSet, TraceSet] | None:
    """``traces`` split at random into two halves of whole units of ``key`` (a per-run key of the
    segments, e.g. the source run or a driver); None with fewer than 4 units."""
    keys = unit_keys(traces, key, "groups")
    names = sorted(set(keys))
    if len(names) < 4:
        return None
    rng = np.random.default_rng(seed)
    first = set(rng.permutation(names)[: len(names) // 2].tolist())
    return (take(traces, [i for i, k in enumerate(keys) if k in first]),
            take(traces, [i for i, k in enumerate(keys) if k not in first]))


def _feature_bounds(effect: FeatureEffect, tolerance: float | None, rule: CellRule
                    ) -> FeatureBounds:
    lower = effect.bounds(rule.alpha / rule.family)[0]
    upper = effect.bounds(rule.alpha)[1]
    floor = float(np.sqrt(effect.power_floor(rule.alpha))) if np.isfinite(upper) else float("nan")
    return FeatureBounds(effect.feature, effect.unit, tolerance, effect.estimate, lower, upper,
                         effect.low, effect.high, effect.mde, effect.pvalue, floor)


def _decide(bounds: Sequence[FeatureBounds], rule: CellRule) -> tuple[CellStatus, str]:
    """Valid when every judged upper bound is below its tolerance, not valid when some judged
    lower bound is above it, inconclusive otherwise (not estimable counts as not shown);
    compared when nothing is judged."""
    judged = [b for b in bounds if b.tolerance is not None]
    if not judged:
        return CellStatus.COMPARED, "; ".join(_reported(b) for b in bounds)
    confidence = f"{100 * (1 - rule.alpha):g} %"
    level = rule.alpha / rule.family
    family = f"{100 * (1 - level):.4g} %"
    above = [b for b in judged if b.lower > b.tolerance and b.pvalue <= level]
    if above:
        return CellStatus.NOT_VALID, "; ".join(
            f"{b.feature} deviates by more than {b.tolerance:g} {b.unit}: {b.estimate:.3g}, "
            f"lower {family} bound {b.lower:.3g}, deviation p = {b.pvalue:.3g}" for b in above)
    if all(b.upper < b.tolerance for b in judged):
        return CellStatus.VALID, "; ".join(
            f"{b.feature} within {b.tolerance:g} {b.unit}: {b.estimate:.3g}, upper "
            f"{confidence} bound {b.upper:.3g}" for b in judged)
    open_ = [b for b in judged if not b.upper < b.tolerance]
    return CellStatus.INCONCLUSIVE, "; ".join(_undecided(b, level) for b in open_)


def _reported(b: FeatureBounds) -> str:
    if not np.isfinite(b.estimate):
        return f"{b.feature}: not estimable (no state visited enough by both sides)"
    return (f"{b.feature}: {b.estimate:.3g} {b.unit} (95 % interval {b.low:.3g}–{b.high:.3g}; "
            "no tolerance given, not judged)")


def _undecided(b: FeatureBounds, level: float) -> str:
    if not np.isfinite(b.estimate):
        return f"{b.feature}: not estimable (no state visited enough by both sides)"
    if b.lower > b.tolerance:
        return (f"{b.feature}: {b.estimate:.3g} {b.unit}, bounds {b.lower:.3g}–{b.upper:.3g} "
                f"above the tolerance {b.tolerance:g}, but the deviation's permutation test "
                f"does not reject the same law at {level:.3g} (p = {b.pvalue:.3g})")
    straddle = (f"{b.feature}: {b.estimate:.3g} {b.unit}, bounds {b.lower:.3g}–{b.upper:.3g} "
                f"straddle the tolerance {b.tolerance:g}")
    if b.tolerance is not None and b.floor >= b.tolerance:
        return (f"{straddle}; these data cannot show it within the tolerance: the upper bound "
                f"is never below the deviation test's power floor {b.floor:.3g} (more units "
                "needed)")
    return straddle


def matched(reference: TraceSet, candidate: TraceSet, rule: CellRule
             ) -> tuple[TraceSet | None, TraceSet | None, str]:
    """A paired cell keeps the runs whose key has segments on both sides (None: no pair)."""
    if rule.pair_by is None:
        return reference, candidate, ""
    keys_r = unit_keys(reference, rule.pair_by, "pairs")
    keys_c = unit_keys(candidate, rule.pair_by, "pairs")
    common = set(keys_r) & set(keys_c)
    keep_r = [i for i, k in enumerate(keys_r) if k in common]
    keep_c = [i for i, k in enumerate(keys_c) if k in common]
    left = (len(keys_r) - len(keep_r), len(keys_c) - len(keep_c))
    if left == (0, 0):
        return reference, candidate, ""
    note = (f" ({left[0]} reference and {left[1]} candidate segments without a partner in the "
            "cell left out)")
    if not common:
        return None, None, note
    return take(reference, keep_r), take(candidate, keep_c), note


def _samples(traces: TraceSet | None) -> int:
    return 0 if traces is None else traces.n_rows


def count_units(traces: TraceSet | None, rule: CellRule) -> int:
    """Distinct design units (pair members or groups) among ``traces``' runs; 0 for none."""
    if traces is None:
        return 0
    key = rule.pair_by or rule.group_by
    return len(set(unit_keys(traces, key, "pairs" if rule.pair_by else "groups")))
