"""Validity domains learned from measurements: one response comparison per cell, decided on the
size of the deviation, not on whether a difference was found.

For every candidate and every cell of the operating-condition grid, the candidate's segments in
the cell are compared with the reference's by the response comparison
(:func:`simcred.compare.compare` with ``test="response"``): the response law given the state,
with the declared inputs conditioned on, on the design's units (pairs of replays, groups, or the
runs the segments were cut from). For each feature with a tolerance ``δ`` it gives the response
deviation ``E`` with bootstrap bounds. With ``K`` the number of cells of the test case and ``α``
the comparison's level, a cell is

* ``valid`` when every ``E`` is shown below its ``δ``: the one-sided upper ``1 − α`` bound is
  below ``δ``. VALID for the test case needs every one of its cells valid (an
  intersection–union test: the probability of declaring valid a candidate that deviates by
  ``δ`` or more in some cell is at most ``α``, without adjustment);
* ``not valid`` when some ``E`` is shown above its ``δ``: the one-sided lower ``1 − α/K`` bound
  is above ``δ`` (Bonferroni over the test case's cells: a candidate within tolerance in every
  cell comes out not valid in at most ``α`` of cases, whatever the number of cells), and the
  permutation test of ``E`` itself rejects the same law at ``α/K``. The bootstrap bound is
  approximate and fails with few units; the permutation test is exact for a candidate with the
  reference's own law, so that candidate is never declared not valid at more than ``α`` over
  the test case, however little data there is;
* ``inconclusive`` otherwise: the data cannot place the deviation on either side of ``δ``;
* ``unknown`` when either side has fewer design units or samples than ``min_data``.

Design: ``pairs`` (or, for a candidate made by a simulator command that replays the reference,
its own run ids) pairs each reference run with its replay; ``groups`` makes drivers, recordings
or vehicles the units; by default the units are the runs the segments were cut from. In a paired
cell, runs whose partner has no segment in the cell are left out (counted in the reason).
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from simcred.compare import Comparison, compare
from simcred.compare.design import RUN_ID, unit_keys
from simcred.compare.effect import FeatureEffect
from simcred.traces import TraceSet, take
from simcred.validate.cells import SOURCE_RUN, Grid, Segments, segments
from simcred.validate.spec import ValidationSpec


class CellStatus(StrEnum):
    VALID = "valid"
    NOT_VALID = "not valid"
    INCONCLUSIVE = "inconclusive"
    UNKNOWN = "unknown"


@dataclass(frozen=True, slots=True)
class FeatureBounds:
    """One feature's deviation in one cell against its tolerance: the estimate, the one-sided
    bounds the decision uses (``upper`` at ``1 − α``, ``lower`` at ``1 − α/K``), the two-sided
    95 % interval and the smallest uniform shift the data could detect (80 % power)."""

    feature: str
    unit: str
    tolerance: float
    estimate: float
    lower: float
    upper: float
    low: float
    high: float
    detectable: float
    pvalue: float


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
        """The largest estimate relative to its tolerance (NaN when not compared)."""
        ratios = [b.estimate / b.tolerance for b in self.bounds]
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
            "deviation_pvalue": b.pvalue}


@dataclass(frozen=True, slots=True, eq=False)
class Domain:
    """The learned validity domain of one candidate: a result per cell of the grid."""

    candidate: str
    grid: Grid
    cells: tuple[CellResult, ...]

    def with_status(self, status: CellStatus) -> tuple[CellResult, ...]:
        return tuple(c for c in self.cells if c.status is status)

    def to_dict(self) -> dict[str, Any]:
        return {"candidate": self.candidate,
                "counts": {s.value: len(self.with_status(s)) for s in CellStatus},
                "cells": [c.to_dict() for c in self.cells]}


@dataclass(frozen=True, slots=True)
class CellRule:
    """What every cell's decision shares: the level, the Bonferroni family (the test case's
    cells) and how the candidate's runs are paired or grouped."""

    alpha: float
    family: int
    pair_by: str | None
    group_by: str | None

    @property
    def design(self) -> str:
        if self.pair_by is not None:
            return f"pairs by {_user_key(self.pair_by)}"
        return f"groups by {_user_key(self.group_by)}"


def cell_seed(seed: int, candidate: str, cell: int) -> int:
    """The seed of one comparison: independent of the order of candidates and cells."""
    sequence = np.random.SeedSequence(seed, spawn_key=(zlib.crc32(candidate.encode()), cell))
    return int(sequence.generate_state(1, np.uint64)[0] >> np.uint64(1))


def cell_rule(spec: ValidationSpec, family: int, replay: bool) -> CellRule:
    """The design of one candidate's cells (module docs): declared pairs or groups, pairs by
    run for a replay, else the runs the segments were cut from as groups."""
    alpha = spec.comparison.alpha
    family = max(family, 1)
    if spec.pairs is not None:
        return CellRule(alpha, family, _segment_key(spec.pairs.by), None)
    if spec.groups is not None:
        return CellRule(alpha, family, None, _segment_key(spec.groups.by))
    if replay:
        return CellRule(alpha, family, SOURCE_RUN, None)
    return CellRule(alpha, family, None, SOURCE_RUN)


def _segment_key(key: str) -> str:
    """A user's per-run key as a key of the segments' facts (``run_id`` is the source run)."""
    return SOURCE_RUN if key == RUN_ID else key


def _user_key(key: str | None) -> str:
    return "run" if key == SOURCE_RUN else str(key)


def learn_domain(spec: ValidationSpec, grid: Grid, reference: Segments, candidate: TraceSet,
                 name: str, rule: CellRule) -> Domain:
    """Compare ``candidate`` with the reference in every cell of ``grid`` (module docs)."""
    mine = segments(candidate, grid, spec.segments.min_length)
    return Domain(name, grid, tuple(_cell(spec, grid, reference, mine, name, c, rule)
                                    for c in range(grid.n_cells)))


def _cell(spec: ValidationSpec, grid: Grid, reference: Segments, candidate: Segments,
          name: str, cell: int, rule: CellRule) -> CellResult:
    head = (cell, grid.index(cell), grid.label(cell))
    if cell not in reference.by_cell or cell not in candidate.by_cell:
        counts = (_units(reference, cell, rule), reference.samples(cell),
                  _units(candidate, cell, rule), candidate.samples(cell))
        return CellResult(*head, CellStatus.UNKNOWN, _too_little(spec, counts), *counts,
                          rule.design)
    ref, cand, dropped = _matched(reference.by_cell[cell], candidate.by_cell[cell], rule)
    counts = (0, 0, 0, 0) if ref is None else (_count_units(ref, rule), ref.n_rows,
                                                _count_units(cand, rule), cand.n_rows)
    short = _too_little(spec, counts)
    if short:
        return CellResult(*head, CellStatus.UNKNOWN, short + dropped, *counts, rule.design)
    options = spec.comparison
    seed = cell_seed(options.seed, name, cell)
    result = compare(ref, cand, features=spec.features, inputs=spec.inputs, test="response",
                     bins=options.bins, alpha=options.alpha, permutations=options.permutations,
                     bootstrap=options.bootstrap, seed=seed, resample=options.resample,
                     pair_by=rule.pair_by, group_by=rule.group_by,
                     margin=dict(spec.test_case.tolerance))
    effects = {f.feature: f for f in result.response.effect.features}
    bounds = tuple(_feature_bounds(effects[n], delta, rule)
                   for n, delta in spec.test_case.tolerance.items())
    status, reason = _decide(bounds, rule)
    return CellResult(*head, status, reason + dropped, *counts, rule.design,
                      float(result.chain.pvalue), bounds, seed, result)


def _feature_bounds(effect: FeatureEffect, tolerance: float, rule: CellRule) -> FeatureBounds:
    lower = effect.bounds(rule.alpha / rule.family)[0]
    upper = effect.bounds(rule.alpha)[1]
    return FeatureBounds(effect.feature, effect.unit, tolerance, effect.estimate, lower, upper,
                         effect.low, effect.high, effect.mde, effect.pvalue)


def _decide(bounds: Sequence[FeatureBounds], rule: CellRule) -> tuple[CellStatus, str]:
    """Valid when every upper bound is below its tolerance, not valid when some lower bound is
    above it, inconclusive otherwise; not estimable counts as not shown."""
    confidence = f"{100 * (1 - rule.alpha):g} %"
    level = rule.alpha / rule.family
    family = f"{100 * (1 - level):.4g} %"
    above = [b for b in bounds if b.lower > b.tolerance and b.pvalue <= level]
    if above:
        return CellStatus.NOT_VALID, "; ".join(
            f"{b.feature} deviates by more than {b.tolerance:g} {b.unit}: {b.estimate:.3g}, "
            f"lower {family} bound {b.lower:.3g}, deviation p = {b.pvalue:.3g}" for b in above)
    if all(b.upper < b.tolerance for b in bounds):
        return CellStatus.VALID, "; ".join(
            f"{b.feature} within {b.tolerance:g} {b.unit}: {b.estimate:.3g}, upper "
            f"{confidence} bound {b.upper:.3g}" for b in bounds)
    open_ = [b for b in bounds if not b.upper < b.tolerance]
    return CellStatus.INCONCLUSIVE, "; ".join(_undecided(b, level) for b in open_)


def _undecided(b: FeatureBounds, level: float) -> str:
    if not np.isfinite(b.estimate):
        return f"{b.feature}: not estimable (no state visited enough by both sides)"
    if b.lower > b.tolerance:
        return (f"{b.feature}: {b.estimate:.3g} {b.unit}, bounds {b.lower:.3g}–{b.upper:.3g} "
                f"above the tolerance {b.tolerance:g}, but the deviation's permutation test "
                f"does not reject the same law at {level:.3g} (p = {b.pvalue:.3g})")
    return (f"{b.feature}: {b.estimate:.3g} {b.unit}, bounds {b.lower:.3g}–{b.upper:.3g} "
            f"straddle the tolerance {b.tolerance:g}")


def _matched(reference: TraceSet, candidate: TraceSet, rule: CellRule
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


def _units(segs: Segments, cell: int, rule: CellRule) -> int:
    return _count_units(segs.by_cell[cell], rule) if cell in segs.by_cell else 0


def _count_units(traces: TraceSet, rule: CellRule) -> int:
    key = rule.pair_by or rule.group_by
    return len(set(unit_keys(traces, key, "pairs" if rule.pair_by else "groups")))


def _too_little(spec: ValidationSpec, counts: tuple[int, int, int, int]) -> str:
    need = spec.min_data
    ref_units, ref_samples, cand_units, cand_samples = counts
    for side, units, samples in (("reference", ref_units, ref_samples),
                                 ("candidate", cand_units, cand_samples)):
        if units < need.runs or samples < need.samples:
            return (f"too little data: {side} has {units} units / {samples} samples "
                    f"(needs {need.runs} / {need.samples})")
    return ""
