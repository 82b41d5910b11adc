"""Candidates ordered by how far they deviate, with intervals.

A candidate's *score* is its largest response deviation relative to the tolerance over the test
case's compared cells and the features with a tolerance: ``max_(c, f) E_cf / δ_f`` (1 = at the
tolerance). Its interval is simultaneous: each of the ``M`` ratios gets a two-sided
``1 − α/M`` bootstrap interval (Bonferroni), so with probability at least ``1 − α`` all ``M``
hold at once, and then the maximum lies between the largest lower and the largest upper end.
Candidates are ordered by score (ties by name); a candidate compared in no cell of the test case
has no score and comes last.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from simcred.validate.domain import Domain
from simcred.validate.spec import ValidationSpec


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


def rank(domains: dict[str, Domain], relevant: tuple[int, ...], spec: ValidationSpec
         ) -> tuple[Ranked, ...]:
    """The candidates in order of their score (module docs)."""
    alpha = spec.comparison.alpha
    tolerance = spec.test_case.tolerance
    out = []
    for name, domain in domains.items():
        compared = [domain.cells[c] for c in relevant if domain.cells[c].comparison is not None]
        effects = [(f, tolerance[f.feature]) for c in compared
                   for f in c.comparison.response.effect.features if f.feature in tolerance]
        if not effects:
            out.append(Ranked(name, None, None, None, 0, len(relevant)))
            continue
        share = alpha / (2 * len(effects))
        ends = [f.bounds(share) for f, _ in effects]
        out.append(Ranked(name, max(f.estimate / d for f, d in effects),
                          max(lo / d for (lo, _), (_, d) in zip(ends, effects, strict=True)),
                          max(hi / d for (_, hi), (_, d) in zip(ends, effects, strict=True)),
                          len(compared), len(relevant)))
    return tuple(sorted(out, key=lambda r: (r.score is None, r.score or 0.0, r.candidate)))
