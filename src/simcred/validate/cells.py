"""The operating-condition grid and per-cell segments: moved to :mod:`simcred.regions.cells`
(the per-region engine that ``validate`` and ``study`` share); re-exported here."""

from simcred.regions.cells import OUTSIDE, SOURCE_RUN, Grid, Segments, grid_of, segments

__all__ = ["OUTSIDE", "SOURCE_RUN", "Grid", "Segments", "grid_of", "segments"]
