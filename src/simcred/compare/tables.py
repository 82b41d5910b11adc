"""Result tables as DataFrames: a comparison's start states, a distance matrix's pairs.

One row per thing the JSON lists, with the same numbers (no rounding), for notebooks and
``DataFrame`` pipelines; :meth:`Comparison.to_pandas` and :meth:`DistanceMatrix.to_pandas` are
the entry points.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from simcred.compare.pairwise import DistanceMatrix
    from simcred.compare.result import Comparison

#: status of a start state in :func:`states_frame` (as in :meth:`Comparison.state_grid`)
STATUS = {1: "kept", 2: "rejected", 3: "untestable"}


def _interval(edges: np.ndarray, index: int) -> tuple[float, float]:
    """The value range of bin ``index`` (outer bins are open: -inf / inf)."""
    low = -math.inf if index == 0 else float(edges[index - 1])
    high = math.inf if index == len(edges) else float(edges[index])
    return low, high


def states_frame(result: Comparison) -> pd.DataFrame:
    """One row per start state seen in A or B: its bins and their value ranges ``[low, high)``
    per feature, ``status`` (kept, rejected, untestable), ``m``, ``n`` successor samples and,
    for tested states, ``statistic``, ``pvalue``, ``adjusted_pvalue``, ``threshold``."""
    import pandas as pd

    rows: list[dict[str, Any]] = []
    features, edges = result.space.features, result.space.edges
    for state, status, m, n, test in (
            [(s.state, 2 if s.result.rejected else 1, s.result.m, s.result.n, s.result)
             for s in result.states]
            + [(u.state, 3, u.m, u.n, None) for u in result.untestable]):
        row: dict[str, Any] = {}
        for name, e, index in zip(features, edges, state, strict=True):
            row[f"{name}.bin"] = int(index)
            row[f"{name}.low"], row[f"{name}.high"] = _interval(e, int(index))
        row.update(status=STATUS[status], m=int(m), n=int(n))
        for key in ("statistic", "pvalue", "adjusted_pvalue", "threshold"):
            value = None if test is None else getattr(test, key)
            row[key] = math.nan if value is None else float(value)
        rows.append(row)
    columns = [f"{f}.{k}" for f in features for k in ("bin", "low", "high")] + [
        "status", "m", "n", "statistic", "pvalue", "adjusted_pvalue", "threshold"]
    frame = pd.DataFrame(rows, columns=columns)
    return frame.sort_values([f"{f}.bin" for f in features], kind="stable", ignore_index=True)


def matrix_frame(result: DistanceMatrix) -> pd.DataFrame:
    """The distance matrix as a square DataFrame indexed by the set names (NaN: stopped)."""
    import pandas as pd

    return pd.DataFrame(np.array(result.distances, dtype=float), index=list(result.names),
                        columns=list(result.names))
