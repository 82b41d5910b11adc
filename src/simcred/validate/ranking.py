"""Candidates ordered by how far they deviate, with intervals.

A candidate's *score* is its largest response deviation relative to the tolerance over the test
case's compared cells and the features with a tolerance: ``max_(c, f) E_cf / δ_f`` (1 = at the
tolerance). Its interval is simultaneous: each of the ``M`` ratios gets a two-sided
``1 − α/M`` bootstrap interval (Bonferroni), so with probability at least ``1 − α`` all ``M``
hold at once, and then the maximum lies between the largest lower and the largest upper end.
Candidates are ordered by score (ties by name); a candidate compared in no cell of the test case
has no score and comes last. Beside them, :data:`REFERENCE`: two random halves of the reference
compared with each other in the same cells — the score a candidate as good as the reference
itself would show with half the data (the floor the others are read against).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from simcred.compare import Comparison
from simcred.validate.domain import Domain
from simcred.validate.spec import ValidationSpec

REFERENCE = "reference halves"


@dataclass(frozen=True, slots=True)
class Ranked:
    """One candidate's place: score, simultaneous interval, over how many cells."""

    candidate: str
    score: float | None
    low: float | None
    high: float | None
    cells: int
    of: int

    def to_dict(self) -> dict[str, Any]:
        return {"candidate": self.candidate, "score": self.score,
                "interval": None if self.low is None else [self.low, self.high],
                "cells_compared": self.cells, "test_case_cells": self.of}


def rank(domains: dict[str, Domain], relevant: tuple[int, ...], spec: ValidationSpec,
         pilot: Sequence[Comparison] = ()) -> tuple[Ranked, ...]:
    """The candidates in order of their score (module docs); ``pilot``: the comparisons of two
    halves of the reference in the test case's cells, ranked as :data:`REFERENCE` (what a
    candidate as good as the reference shows with half its data)."""
    compared = {name: [domain.cells[c].comparison for c in relevant
                       if domain.cells[c].comparison is not None]
                for name, domain in domains.items()}
    if pilot:
        compared[REFERENCE] = list(pilot)
    out = [_ranked(name, comparisons, len(relevant), spec)
           for name, comparisons in compared.items()]
    return tuple(sorted(out, key=lambda r: (r.score is None, r.score or 0.0, r.candidate)))


def _ranked(name: str, comparisons: Sequence[Comparison], of: int, spec: ValidationSpec
            ) -> Ranked:
    tolerance = spec.test_case.tolerance
    effects = [(f, tolerance[f.feature]) for c in comparisons
               for f in c.response.effect.features if f.feature in tolerance]
    if not effects:
        return Ranked(name, None, None, None, 0, of)
    share = spec.comparison.alpha / (2 * len(effects))
    ends = [f.bounds(share) for f, _ in effects]
    return Ranked(name, max(f.estimate / d for f, d in effects),
                  max(lo / d for (lo, _), (_, d) in zip(ends, effects, strict=True)),
                  max(hi / d for (_, hi), (_, d) in zip(ends, effects, strict=True)),
                  len(comparisons), of)
