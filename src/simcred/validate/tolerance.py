"""A tolerance relative to the reference's own spread, resolved to a number before deciding.

``tolerance: {v: {relative: f}}`` asks "is the candidate as close to the reference as the
reference's own units are to each other, times ``f``?". The spread is measured on the reference
alone: its segments in the test case's cells are pooled, split ``SPLITS`` times at random into two
halves of whole units (the declared ``groups`` — drivers, recordings, vehicles — else the runs
the segments were cut from), the halves compared by the response comparison (grouped by that
unit), and the median of the ``SPLITS`` observed (plug-in) deviations is the spread. The plug-in,
not the bias-corrected estimate: the two halves follow one law, so the estimate removes exactly
the between-unit variation this spread is meant to measure. The tolerance is
``f`` times it: one number per feature for the whole test case, written in verdict.json with the
splits it came from, then used exactly like an absolute tolerance.

Read it for what it is: the deviation between two halves of a finite set of units. With few
drivers it is the spread *between drivers* (it does not shrink as each drives longer); with many
units it shrinks towards 0 — then a relative tolerance becomes strict. Which
to choose is the test case's call (docs/validate.md, "Which tolerance?").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from simcred.regions.cells import SOURCE_RUN, Segments
from simcred.regions.engine import cell_seed, halves, segment_key
from simcred.traces import RUN_INFO, concat
from simcred.validate.domain import unpaired_comparison
from simcred.validate.spec import ValidationFileError, ValidationSpec

SPLITS = 5
BOOTSTRAP = 100  # the halves' comparisons need the observed deviation, not its interval


@dataclass(frozen=True, slots=True)
class Resolution:
    """How one relative tolerance became a number."""

    feature: str
    relative: float
    unit_key: str
    estimates: tuple[float, ...]
    spread: float
    tolerance: float

    def to_dict(self) -> dict[str, Any]:
        return {"feature": self.feature, "relative": self.relative,
                "units": "run" if self.unit_key == SOURCE_RUN else self.unit_key,
                "split_estimates": list(self.estimates), "spread": self.spread,
                "tolerance": self.tolerance}


def resolve(spec: ValidationSpec, reference: Segments, relevant: tuple[int, ...]
            ) -> tuple[ValidationSpec, tuple[Resolution, ...]]:
    """``spec`` with every relative tolerance replaced by its number, and how each was found."""
    relative = spec.relative
    if not relative:
        return spec, ()
    key = segment_key(spec.groups.by) if spec.groups is not None else SOURCE_RUN
    pool = _pool(reference, relevant)
    estimates = {name: [] for name in relative}
    for split in range(SPLITS):
        found = None if pool is None else halves(pool, key, cell_seed(spec.comparison.seed,
                                                                       "tolerance", split))
        if found is None:
            raise ValidationFileError("test_case.tolerance: a relative tolerance needs at least 4 "
                                      "reference units in the test case's cells to measure the "
                                      "reference's own spread")
        result = unpaired_comparison(spec, *found, key,
                                     cell_seed(spec.comparison.seed, "tolerance:cmp", split),
                                     BOOTSTRAP)
        for effect in result.response.effect.features:
            if effect.feature in relative:
                estimates[effect.feature].append(effect.plugin)
    out, numbers = [], dict(spec.test_case.tolerance)
    for name, factor in relative.items():
        spread = float(np.median(estimates[name]))
        if not np.isfinite(spread) or spread <= 0:
            raise ValidationFileError(f"test_case.tolerance.{name}: the reference's own spread "
                                      f"is {spread:g}: a relative tolerance cannot be set from "
                                      "it; give an absolute one")
        numbers[name] = factor * spread
        out.append(Resolution(name, factor, key, tuple(estimates[name]), spread, numbers[name]))
    return spec.with_tolerance(numbers), tuple(out)


def placeholder(spec: ValidationSpec) -> ValidationSpec:
    """``spec`` with 1 for every relative tolerance: for what needs only the test case's
    conditions (its cells) before the tolerance is known."""
    return spec.with_tolerance({name: value if isinstance(value, float | int) else 1.0
                                for name, value in spec.test_case.tolerance.items()})


def _pool(reference: Segments, relevant: tuple[int, ...]):
    """The reference's segments in the test case's cells as one set (their facts kept)."""
    parts = [reference.by_cell[c] for c in relevant if c in reference.by_cell]
    if not parts:
        return None
    facts = {}
    for part in parts:
        facts.update(part.metadata.get(RUN_INFO, {}))
    return concat(parts, metadata={**parts[0].metadata, RUN_INFO: facts})
