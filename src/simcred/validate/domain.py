"""Validity domains learned from measurements: one response comparison per cell, decided on the
size of the deviation, not on whether a difference was found.

The per-cell engine — cells, segments, the design, the status, seeds, the too-little-data rule —
is :mod:`simcred.regions` (shared with ``simcred study``); this module states the validation
file's part: the test case's tolerance, ``pairs`` / ``groups``, ``min_data``, ``segments`` and
``comparison``. With ``K`` the number of cells of the test case and ``α`` the comparison's level,
a cell is

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

from simcred.compare import Comparison, compare
from simcred.regions import engine
from simcred.regions.cells import Grid, Segments
from simcred.regions.engine import (
    CellComparison,
    CellResult,
    CellRule,
    CellStatus,
    Domain,
    FeatureBounds,
    MinData,
    cell_seed,
)
from simcred.traces import TraceSet
from simcred.validate.spec import ValidationSpec

__all__ = ["CellResult", "CellRule", "CellStatus", "Domain", "FeatureBounds", "cell_rule",
           "cell_seed", "cell_settings", "learn_domain", "unpaired_comparison"]


def unpaired_comparison(spec: ValidationSpec, a: TraceSet, b: TraceSet, group_by: str,
                        seed: int, bootstrap: int) -> Comparison:
    """Two sets of the reference's units (halves, or draws from them) compared with the file's
    comparison options, grouped by ``group_by``: the pilot of the plan and the spread of a
    relative tolerance. Only the deviation is used, so the difference test is cut to 19
    permutations and no margin is given."""
    return compare(a, b, spec.method, permutations=19, bootstrap=bootstrap, seed=seed,
                   group_by=group_by)


def cell_settings(spec: ValidationSpec) -> CellComparison:
    """The engine's per-cell settings of a validation file: the comparison's options, the
    test case's tolerance (its features are the ones reported), ``min_data`` and ``segments``."""
    return CellComparison(spec.method, dict(spec.test_case.tolerance),
                          tuple(spec.test_case.tolerance),
                          MinData(spec.min_data.runs, spec.min_data.samples),
                          spec.segments.min_length)


def cell_rule(spec: ValidationSpec, family: int, replay: bool) -> CellRule:
    """The design of one candidate's cells (module docs): declared pairs or groups, pairs by
    run for a replay, else the runs the segments were cut from as groups."""
    return engine.cell_rule(spec.comparison.alpha, family,
                            pairs=None if spec.pairs is None else spec.pairs.by,
                            groups=None if spec.groups is None else spec.groups.by,
                            replay=replay)


def learn_domain(spec: ValidationSpec, grid: Grid, reference: Segments, candidate: TraceSet,
                 name: str, rule: CellRule) -> Domain:
    """Compare ``candidate`` with the reference in every cell of ``grid`` (module docs)."""
    return engine.learn_domain(cell_settings(spec), grid, reference, candidate, name, rule)
