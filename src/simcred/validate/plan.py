"""How much data would show equivalence: units per side and cell for 80 % power, from a pilot,
checked by simulation.

**Pilot.** In each cell of the test case the reference's units (the runs the segments were cut
from, or the declared groups) are split at random into two halves that play a perfect candidate
and the reference: the response comparison of the halves gives, per feature with a tolerance
``δ``, the bootstrap standard error ``se_m`` of the deviation at ``m`` units per side. The pilot
is unpaired: for candidates that replay the reference run by run (pairs), their own rows, in
their own design, start the plan (pairing removes the scenarios' spread; the pilot cannot) and
their own pairs are resampled for the check (below).

**Size.** VALID for the test case needs every one of its ``K`` cells shown within tolerance, so
each cell needs power ``p = 0.8^(1/K)`` for the test case to have 80 %. Two sizes per row, with
``z = z_(1−α) + z_p``:

* **if as good as the reference** (true deviation 0): the bias-corrected estimate is near 0
  (0.002 / 0 m/s² on replayed car following at 300 pairs) and estimate and standard error both
  shrink like ``1/√n``, so the upper bound does: ``n = m ((Ê_m + z se_m) / δ)²``, with this
  source's ``Ê_m`` and ``se_m`` at ``m`` units as the pilot of the design's noise (for a
  candidate whose true deviation is not 0, its ``Ê_m`` holds that too, and the number is
  pessimistic). Measured optimistic: at the size it planned from 300 pairs (1,262 episodes) the
  same model was VALID in 27 of 40 draws, not 80 % — near 0 the upper bound's law is skewed,
  which a normal rule with the bootstrap standard error does not see (docs/validate.md);
* **at its estimate** (a true deviation ``E = Ê < δ`` that stays): ``n = m (z se_m /
  (δ − E))²``; at or above the tolerance "not reachable".
**Check.** The normal approximation fails where it matters most: at ``E = 0`` the deviation sits
on the boundary of its range, and its estimate keeps a bias at small sizes. So the pilot's size
is simulated: ``reps`` data sets whose two sides are each ``n`` units drawn with replacement
from the cell's reference units (one law on both sides: a candidate exactly as good as the
reference; drawing each side from its own half would build the halves' sampling difference into
the truth), each compared as ``validate`` would; the share in which every cell of the test case
comes out valid is the simulated power. Each cell has its own size, starting from the pilot's
"as good as the reference" size;
while the test case is below 80 %, every cell below its share ``p`` grows by half, up to
``MAX_GROWTH`` times the cell's reference units (beyond, resampling a small reference says
little); the plan is the first simulated sizes that reach 80 %, or none. Cells of the test case
without a pilot (fewer than 4 reference units) are named: they need reference data before any
plan, and the simulated power covers the other cells.

**Paired candidates** are checked the same way from their own pairs: ``n`` pairs per cell drawn
with replacement from the cell's matched pairs, the two members of each drawn pair swapped with
probability 1/2 (:func:`~simcred.validate.draws.draw_pairs`): both sides then follow one law — a
candidate exactly as good as the reference — while every pair keeps its scenario and the
dependence of its two members, which is what pairing buys. Each data set is compared and decided
as ``validate`` decides the cell (:func:`~simcred.regions.engine.compare_cell`: same design,
permutations, bootstrap and tolerance); the search starts from the candidate's rows' "as good as
the reference" sizes and grows as above, up to ``MAX_GROWTH_PAIRS`` (10) times the cell's
pairs. Why further than the pilot's 4: the simulated world is the same law on both sides by
construction (no halves' difference to inherit) and the deviation is a smooth function of sums
over pairs, whose spread at ``n`` pairs the ``m`` observed pairs estimate as the normal rule
does; on replayed car following the normal rule itself asked for 4.2 times the pairs of a
300-episode pilot, so a limit of 4 would refuse every plan there. The normal rule alone was
measured optimistic there (VALID in 27 of 40 draws at the size it planned, docs/validate.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import norm

from simcred._json import fields_dict, json_key
from simcred.compare import Comparison
from simcred.regions.cells import Grid, Segments
from simcred.regions.engine import (
    CellResult,
    CellRule,
    CellStatus,
    Domain,
    cell_rule,
    cell_seed,
    compare_cell,
    count_units,
    matched,
)
from simcred.regions.engine import halves as split_halves
from simcred.traces import TraceSet
from simcred.validate.domain import cell_settings, unpaired_comparison
from simcred.validate.draws import draw_pairs, draw_units
from simcred.validate.ranking import REFERENCE as PILOT
from simcred.validate.spec import ValidationSpec

POWER = 0.8
MAX_GROWTH = 4
#: A paired candidate's limit, in times its pairs in the cell (module docs).
MAX_GROWTH_PAIRS = 10


@dataclass(frozen=True, slots=True)
class PlanRow:
    """Units per side one source needs in one cell, with the inputs of that number."""

    source: str
    cell: int
    label: str
    units: int = field(metadata=json_key("units_per_side"))
    feature: str
    tolerance: float
    estimate: float
    se: float
    if_perfect: int | None = field(metadata=json_key("needed_if_as_good_as_reference"))
    needed: int | None = field(metadata=json_key("needed_at_estimate"))

    def to_dict(self) -> dict[str, Any]:
        return fields_dict(self)


@dataclass(frozen=True, slots=True)
class Searched:
    """Sizes searched by simulation: units per side (pairs for a paired candidate) per cell of
    the test case, empty when none was reached (``note`` says why), and the simulated power of
    the test case at the last sizes tried."""

    sizes: dict[int, int]
    simulated_power: float | None
    simulations: int
    note: str

    def to_dict(self) -> dict[str, Any]:
        return {"planned_units_per_side": {str(c): n for c, n in self.sizes.items()},
                "simulated_power": self.simulated_power, "simulations": self.simulations,
                "note": self.note}


@dataclass(frozen=True, slots=True)
class Plan:
    """The plan: rows per source, cell and feature; per cell of the test case the simulated
    size for a candidate as good as the reference (``sizes``: units per side; empty when no
    size was reached) and the simulated power of the test case at those sizes; per paired
    candidate its own simulated sizes (``candidates``)."""

    power: float
    cell_power: float
    rows: tuple[PlanRow, ...]
    sizes: dict[int, int]
    simulated_power: float | None
    simulations: int
    note: str
    candidates: dict[str, Searched] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"power": self.power, "power_per_cell": self.cell_power,
                "rows": [r.to_dict() for r in self.rows],
                "planned_units_per_side": {str(c): n for c, n in self.sizes.items()},
                "simulated_power": self.simulated_power, "simulations": self.simulations,
                "note": self.note,
                "candidates": {n: c.to_dict() for n, c in self.candidates.items()}}


def power_per_cell(cells: int) -> float:
    """Each of ``cells`` cells' share of :data:`POWER`: VALID needs every cell."""
    return POWER ** (1 / max(cells, 1))


def needed_units(units: int, se: float, tolerance: float, estimate: float, alpha: float,
                 power: float) -> int | None:
    """At its estimate: ``m (z se / (δ − E))²`` rounded up (module docs); None if ``E ≥ δ`` or
    nothing is estimable."""
    if not (np.isfinite(se) and np.isfinite(estimate)) or estimate >= tolerance:
        return None
    z = norm.ppf(1 - alpha) + norm.ppf(power)
    return max(2, math.ceil(units * (z * se / (tolerance - estimate)) ** 2))


def needed_if_perfect(units: int, se: float, tolerance: float, estimate: float, alpha: float,
                      power: float) -> int | None:
    """As good as the reference: ``m ((Ê + z se) / δ)²`` rounded up (module docs); None if
    nothing is estimable."""
    if not (np.isfinite(se) and np.isfinite(estimate)):
        return None
    z = norm.ppf(1 - alpha) + norm.ppf(power)
    return max(2, math.ceil(units * ((max(estimate, 0.0) + z * se) / tolerance) ** 2))


@dataclass(frozen=True, slots=True, eq=False)
class Pilot:
    """Two random halves of the reference's units per cell of the test case, and their
    comparison (a candidate as good as the reference, with half its data)."""

    rule: CellRule
    pools: dict[int, TraceSet]
    halves: dict[int, tuple[TraceSet, TraceSet]]
    comparisons: dict[int, Comparison]


def pilot(spec: ValidationSpec, reference: Segments, relevant: tuple[int, ...]) -> Pilot:
    """The pilot in every cell of the test case with at least 4 reference units."""
    rule = cell_rule(spec.comparison.alpha, len(relevant),
                     groups=spec.groups.by if spec.groups is not None else None)
    halves = {}
    for cell in relevant:
        split = None if cell not in reference.by_cell else split_halves(
            reference.by_cell[cell], rule.group_by,
            cell_seed(spec.comparison.seed, "plan:halves", cell))
        if split is not None:
            halves[cell] = split
    comparisons = {cell: unpaired_comparison(spec, *split, rule.group_by,
                                             cell_seed(spec.comparison.seed, "plan:pilot", cell),
                                             spec.comparison.bootstrap)
                   for cell, split in halves.items()}
    pools = {cell: reference.by_cell[cell] for cell in halves}
    return Pilot(rule, pools, halves, comparisons)


def plan(spec: ValidationSpec, grid: Grid, found: Pilot, relevant: tuple[int, ...],
         domains: dict[str, Domain], paired: Mapping[str, PairedInput] | None = None, *,
         reps: int = 20) -> Plan:
    """The plan for the test case's cells (module docs); ``paired``: the candidates whose runs
    pair with the reference's, searched by simulation from their own pairs."""
    alpha = spec.comparison.alpha
    cell_power = power_per_cell(len(relevant))
    rule, halves = found.rule, found.halves
    rows: list[PlanRow] = []
    for cell, result in found.comparisons.items():
        units = min(count_units(h, rule) for h in halves[cell])
        rows += _pilot_rows(spec, grid, cell, result, units, alpha, cell_power)
    for name, domain in domains.items():
        rows += _candidate_rows(name, domain, relevant, spec, cell_power)
    candidates = {name: _paired_search(spec, grid, name, given, relevant, rows, cell_power,
                                       reps) for name, given in (paired or {}).items()}
    missing = [grid.label(c) for c in relevant if c not in halves]
    lacking = (f" No pilot in {'; '.join(missing)} (fewer than 4 reference units): those cells "
               "need reference data before any plan.") if missing else ""
    sizes = _start_sizes(rows, PILOT)
    if not sizes:
        return Plan(POWER, cell_power, tuple(rows), {}, None, 0,
                    ("No cell of the test case has a usable pilot." + lacking).strip(),
                    candidates)
    limits = {c: MAX_GROWTH * count_units(found.pools[c], rule) for c in sizes}
    found_sizes, share, note = _search(
        lambda at: _simulate(spec, found.pools, rule, at, reps), sizes, limits, cell_power,
        grid, "reference units", "more reference data is needed", MAX_GROWTH)
    return Plan(POWER, cell_power, tuple(rows), found_sizes, share, reps,
                (note + lacking).strip(), candidates)


@dataclass(frozen=True, slots=True, eq=False)
class PairedInput:
    """A candidate whose runs pair with the reference's: its design and its segments."""

    rule: CellRule
    reference: Segments
    candidate: Segments


def _paired_search(spec, grid, name: str, given: PairedInput, relevant, rows, cell_power,
                   reps) -> Searched:
    """The candidate's own pairs, resampled with their members swapped at random (one law on
    both sides: as good as the reference, with this candidate's pairing), searched from its
    rows' "as good as the reference" sizes (module docs)."""
    pools = {}
    for cell in relevant:
        ref, cand = (s.by_cell.get(cell) for s in (given.reference, given.candidate))
        if ref is not None and cand is not None:
            ref, cand, _ = matched(ref, cand, given.rule)
            if ref is not None and count_units(ref, given.rule) >= 4:
                pools[cell] = (ref, cand)
    sizes = {c: n for c, n in _start_sizes(rows, name).items() if c in pools}
    lacking = [grid.label(c) for c in relevant if c not in sizes]
    if lacking:
        return Searched({}, None, 0, f"No plan: fewer than 4 pairs or nothing estimable in "
                                     f"{'; '.join(lacking)}.")
    limits = {c: MAX_GROWTH_PAIRS * count_units(pools[c][0], given.rule) for c in sizes}
    settings = cell_settings(spec)

    def shown(cell: int, n: int, rep: int) -> bool:
        rng = np.random.default_rng(cell_seed(spec.comparison.seed, f"plan:{name}:{rep}", cell))
        a, b = draw_pairs(*pools[cell], given.rule.pair_by, n, rng)
        return compare_cell(settings, grid, cell, f"plan:{name}:cmp{rep}", given.rule, a,
                            b).status is CellStatus.VALID

    found, share, note = _search(lambda at: _power(at, reps, shown), sizes, limits, cell_power,
                                 grid, "pairs", "more pairs are needed", MAX_GROWTH_PAIRS)
    return Searched(found, share, reps, note)


def _start_sizes(rows: list[PlanRow], source: str) -> dict[int, int]:
    """Per cell with a row of ``source``, its "as good as the reference" size (the largest over
    features)."""
    sizes: dict[int, int] = {}
    for row in rows:
        if row.source == source and row.if_perfect is not None:
            sizes[row.cell] = max(sizes.get(row.cell, 2), row.if_perfect)
    return sizes


def _search(simulate, sizes: dict[int, int], limits: dict[int, int], cell_power: float,
            grid: Grid, what: str, more: str, growth: int
            ) -> tuple[dict[int, int], float | None, str]:
    """Simulate at ``sizes``; grow (by half) every cell below its share of the power until the
    test case reaches it (those sizes, the simulated power, no note) or a cell would need more
    than its limit (no sizes, the last power, a note)."""
    share = 0.0
    while True:
        too_big = [c for c, n in sizes.items() if n > limits[c]]
        if too_big:
            return {}, share if share else None, (
                f"Not reached by simulation: {'; '.join(grid.label(c) for c in too_big)} would "
                f"need more than {growth} times its {what}; {more} to plan.")
        per_cell, share = simulate(sizes)
        if share >= POWER:
            return dict(sizes), share, ""
        sizes = {c: math.ceil(1.5 * n) if per_cell[c] < cell_power else n
                 for c, n in sizes.items()}


def _power(sizes: dict[int, int], reps: int, shown) -> tuple[dict[int, float], float]:
    """Per cell and for the whole test case, the share of ``reps`` simulated data sets in which
    ``shown(cell, n, rep)``."""
    count = {cell: 0 for cell in sizes}
    every = 0
    for rep in range(reps):
        passed = True
        for cell, n in sizes.items():
            valid = shown(cell, n, rep)
            count[cell] += valid
            passed &= valid
        every += passed
    return {cell: k / reps for cell, k in count.items()}, every / reps


def _pilot_rows(spec, grid, cell, result, m, alpha, cell_power) -> list[PlanRow]:
    return [_row(PILOT, cell, grid.label(cell), m, effect, spec, alpha, cell_power)
            for effect in result.response.effect.features
            if effect.feature in spec.test_case.tolerance]


def _row(source, cell, label, m, effect, spec, alpha, cell_power) -> PlanRow:
    delta = spec.test_case.tolerance[effect.feature]
    se = float(np.std(effect.replicates, ddof=1)) if len(effect.replicates) > 1 else np.nan
    return PlanRow(source, cell, label, m, effect.feature, delta, effect.estimate, se,
                   needed_if_perfect(m, se, delta, effect.estimate, alpha, cell_power),
                   needed_units(m, se, delta, effect.estimate, alpha, cell_power))


def _candidate_rows(name, domain, relevant, spec, cell_power) -> list[PlanRow]:
    out = []
    for cell in relevant:
        out += cell_rows(name, domain.cells[cell], spec, cell_power)
    return out


def cell_rows(name: str, result: CellResult, spec: ValidationSpec, cell_power: float
              ) -> list[PlanRow]:
    """One candidate's plan rows in one compared cell (none without a comparison)."""
    if result.comparison is None:
        return []
    m = min(result.reference_units, result.candidate_units)
    return [_row(name, result.cell, result.label, m, effect, spec, spec.comparison.alpha,
                 cell_power)
            for effect in result.comparison.response.effect.features
            if effect.feature in spec.test_case.tolerance]


def needed_text(rows: list[PlanRow]) -> str:
    """What an undecided cell would need, by the normal rule at the candidate's estimate."""
    if not rows:
        return ""
    if any(r.needed is None for r in rows):
        return ("at its estimate no amount of data would show it within tolerance (normal "
                "rule; `--plan` simulates)")
    return (f"about {max(r.needed for r in rows)} units per side would show it within "
            f"tolerance at its estimate (now {rows[0].units}; normal rule, `--plan` simulates)")


def _simulate(spec: ValidationSpec, pools: dict[int, TraceSet], rule: CellRule,
              sizes: dict[int, int], reps: int) -> tuple[dict[int, float], float]:
    """The pilot's simulated power: ``n`` units per side in each cell, both sides drawn with
    replacement from the cell's reference units (the same law)."""
    tolerance = spec.test_case.tolerance
    alpha = spec.comparison.alpha

    def shown(cell: int, n: int, rep: int) -> bool:
        pool = pools[cell]
        rng = np.random.default_rng(cell_seed(spec.comparison.seed, f"plan:sim{rep}", cell))
        result = unpaired_comparison(spec, draw_units(pool, rule.group_by, n, rng, "a"),
                                     draw_units(pool, rule.group_by, n, rng, "b"),
                                     rule.group_by,
                                     cell_seed(spec.comparison.seed, f"plan:cmp{rep}", cell),
                                     spec.comparison.bootstrap)
        return all(f.bounds(alpha)[1] < tolerance[f.feature]
                   for f in result.response.effect.features if f.feature in tolerance)

    return _power(sizes, reps, shown)
