"""A validity domain as a DataFrame: one row per cell, the numbers of its JSON (no rounding).

Columns: ``candidate``, ``cell``, ``label`` (``10 ≤ v < 15``), per condition variable
``<var>.low`` / ``<var>.high``, ``status``, ``reason``, the units and samples on each side,
``pvalue`` (the difference test), and per judged feature ``<feature>.estimate``, ``.lower``,
``.upper``, ``.floor``, ``.tolerance`` (the deviation, its one-sided bounds, the upper bound's
power floor and the tolerance).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from simcred.regions.engine import Domain


def domains_frame(domains: Iterable[Domain]) -> pd.DataFrame:
    """The cells of ``domains`` (one per candidate), candidate after candidate."""
    import pandas as pd

    rows: list[dict[str, Any]] = []
    for domain in domains:
        grid = domain.grid
        for cell in domain.cells:
            row: dict[str, Any] = {"candidate": domain.candidate, "cell": cell.cell,
                                   "label": cell.label}
            for variable, (low, high) in zip(grid.variables, grid.bounds(cell.cell),
                                             strict=True):
                row[f"{variable}.low"], row[f"{variable}.high"] = float(low), float(high)
            row.update(status=cell.status.value, reason=cell.reason,
                       reference_units=cell.reference_units,
                       reference_samples=cell.reference_samples,
                       candidate_units=cell.candidate_units,
                       candidate_samples=cell.candidate_samples,
                       pvalue=math.nan if cell.pvalue is None else cell.pvalue)
            for b in cell.bounds:
                row[f"{b.feature}.estimate"], row[f"{b.feature}.lower"] = b.estimate, b.lower
                row[f"{b.feature}.upper"], row[f"{b.feature}.floor"] = b.upper, b.floor
                row[f"{b.feature}.tolerance"] = math.nan if b.tolerance is None else b.tolerance
            rows.append(row)
    return pd.DataFrame(rows)
