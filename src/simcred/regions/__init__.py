"""Compare per region: the operating-condition grid, runs cut into per-cell segments, and one
response comparison per cell with one status, one seed scheme and one too-little-data rule.

The one per-region engine of ``simcred validate`` (a test case, a tolerance: valid / not valid /
inconclusive / unknown) and ``simcred study`` (validate without a test case: deviations with
intervals, judged only when a tolerance is given). Above compare and contracts, below sim, study
and validate. See docs/validate.md ("The cells", "Cell verdicts").
"""

from simcred.regions.cells import OUTSIDE, SOURCE_RUN, Grid, Segments, grid_of, segments
from simcred.regions.engine import (
    DECIDED,
    CellComparison,
    CellResult,
    CellRule,
    CellStatus,
    Domain,
    FeatureBounds,
    MinData,
    cell_rule,
    cell_seed,
    compare_cell,
    halves,
    learn_domain,
    segment_key,
)

__all__ = ["DECIDED", "OUTSIDE", "SOURCE_RUN", "CellComparison", "CellResult", "CellRule",
           "CellStatus", "Domain", "FeatureBounds", "Grid", "MinData", "Segments", "cell_rule",
           "cell_seed", "compare_cell", "grid_of", "halves", "learn_domain", "segment_key",
           "segments"]
