"""Validity domains learned from measurements: one calibrated comparison per cell.

For every candidate and every cell of the operating-condition grid, the candidate's segments in
the cell are compared with the reference's segments in the cell by the run-level comparison
(:func:`simcred.compare.compare` with ``test="runs"``: whole segments are permuted, so the
dependence of samples within a segment does not inflate the level). A cell is

* ``unknown`` when either side has fewer segments or samples than ``min_data`` — never valid;
* ``not valid`` when the chain test rejects at alpha (under every acceptance rule: a cell whose
  test rejects is never accepted), or, under ``rule: distance``, when the distance is above
  ``d_max``;
* ``valid`` otherwise.

"Valid" means *no difference detected with at least min_data on each side*; it is not an
equivalence test. The power that min_data buys is measured in docs/validate.md.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from simcred.compare import Comparison, compare
from simcred.traces import TraceSet
from simcred.validate.cells import Grid, Segments, segments
from simcred.validate.spec import ValidationSpec


class CellStatus(StrEnum):
    VALID = "valid"
    NOT_VALID = "not valid"
    UNKNOWN = "unknown"


@dataclass(frozen=True, slots=True, eq=False)
class CellResult:
    """One candidate in one cell: data counts, the chain test, the distance, the status."""

    cell: int
    index: tuple[int, ...]
    label: str
    status: CellStatus
    reason: str
    reference_segments: int
    reference_samples: int
    candidate_segments: int
    candidate_samples: int
    pvalue: float | None = None
    statistic: float | None = None
    distance: float | None = None
    seed: int | None = None
    baseline: tuple[float, float] | None = None
    comparison: Comparison | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"cell": self.cell, "index": list(self.index), "label": self.label,
                "status": self.status.value, "reason": self.reason,
                "reference": {"segments": self.reference_segments,
                              "samples": self.reference_samples},
                "candidate": {"segments": self.candidate_segments,
                              "samples": self.candidate_samples},
                "chain_pvalue": self.pvalue, "chain_statistic": self.statistic,
                "distance": self.distance,
                "baseline": None if self.baseline is None else list(self.baseline),
                "seed": self.seed}


@dataclass(frozen=True, slots=True, eq=False)
class Domain:
    """The learned validity domain of one candidate: a result per cell of the grid."""

    candidate: str
    grid: Grid
    cells: tuple[CellResult, ...]

    def with_status(self, status: CellStatus) -> tuple[CellResult, ...]:
        return tuple(c for c in self.cells if c.status is status)

    @property
    def bound(self) -> float | None:
        """The largest distance measured in a valid cell (the learned guarantee), None if no
        cell is valid."""
        valid = [c.distance for c in self.with_status(CellStatus.VALID)]
        return max(valid) if valid else None

    def to_dict(self) -> dict[str, Any]:
        return {"candidate": self.candidate,
                "counts": {s.value: len(self.with_status(s)) for s in CellStatus},
                "distance_bound": self.bound, "cells": [c.to_dict() for c in self.cells]}


def cell_seed(seed: int, candidate: str, cell: int) -> int:
    """The seed of one comparison: independent of the order of candidates and cells."""
    sequence = np.random.SeedSequence(seed, spawn_key=(zlib.crc32(candidate.encode()), cell))
    return int(sequence.generate_state(1, np.uint64)[0] >> np.uint64(1))


def learn_domain(spec: ValidationSpec, grid: Grid, reference: Segments, candidate: TraceSet,
                 name: str) -> Domain:
    """Compare ``candidate`` with the reference in every cell of ``grid`` (module docs)."""
    mine = segments(candidate, grid, spec.segments.min_length)
    return Domain(name, grid, tuple(_cell(spec, grid, reference, mine, name, c)
                                    for c in range(grid.n_cells)))


def _cell(spec: ValidationSpec, grid: Grid, reference: Segments, candidate: Segments,
          name: str, cell: int) -> CellResult:
    counts = (reference.runs(cell), reference.samples(cell), candidate.runs(cell),
              candidate.samples(cell))
    head = (cell, grid.index(cell), grid.label(cell))
    short = _too_little(spec, counts)
    if short:
        return CellResult(*head, CellStatus.UNKNOWN, short, *counts)
    options = spec.comparison
    seed = cell_seed(options.seed, name, cell)
    result = compare(reference.by_cell[cell], candidate.by_cell[cell], features=spec.features,
                     bins=options.bins, kernel=options.kernel, test="runs", alpha=options.alpha,
                     permutations=options.permutations, seed=seed,
                     multiplicity=options.multiplicity, chain=options.chain,
                     resample=options.resample, baseline=options.baseline)
    chain = result.chain
    distance = result.distance
    if spec.acceptance.rule == "chain":
        ok = not chain.rejected
        reason = (f"chain test p = {chain.pvalue:.3g} {'>' if ok else '≤'} alpha = "
                  f"{options.alpha:g}")
    elif chain.rejected:  # a cell whose test rejects is never accepted, whatever the rule
        ok = False
        reason = (f"chain test p = {chain.pvalue:.3g} ≤ alpha = {options.alpha:g} (a cell "
                  "whose test rejects is never valid, whatever d_max)")
    else:
        ok = distance is not None and distance <= spec.acceptance.d_max
        reason = f"distance {distance:.3g} {'≤' if ok else '>'} d_max = {spec.acceptance.d_max:g}"
    status = CellStatus.VALID if ok else CellStatus.NOT_VALID
    baseline = None if result.baseline is None else (result.baseline.low, result.baseline.high)
    return CellResult(*head, status, reason, *counts, float(chain.pvalue),
                      float(chain.statistic), distance, seed, baseline, result)


def _too_little(spec: ValidationSpec, counts: tuple[int, int, int, int]) -> str:
    need = spec.min_data
    ref_runs, ref_samples, cand_runs, cand_samples = counts
    for side, runs, samples in (("reference", ref_runs, ref_samples),
                                ("candidate", cand_runs, cand_samples)):
        if runs < need.runs or samples < need.samples:
            return (f"too little data: {side} has {runs} segments / {samples} samples "
                    f"(needs {need.runs} / {need.samples})")
    return ""
