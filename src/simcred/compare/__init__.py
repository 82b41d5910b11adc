"""Comparison of two sets of runs (Neurohr et al. 2023): Markov chains + MMD tests.

The default test is run-level (whole runs permuted between the sets, a chain-level verdict and
multiplicity-controlled per-state verdicts); the paper's bound and per-transition permutation
tests remain available (``test="bound"`` / ``"permutation"``).
"""

from simcred.compare.hidden import HiddenComparison, compare_hidden
from simcred.compare.method import Method
from simcred.compare.observed import (
    ObservedComparison,
    SensorModel,
    SignalSensor,
    compare_observed,
    estimate_sensor,
    observe,
)
from simcred.compare.pairwise import DistanceMatrix, matrix
from simcred.compare.process import compare
from simcred.compare.result import (
    Baseline,
    ChainVerdict,
    Comparison,
    DistanceInterval,
    FeatureRelevance,
)

__all__ = ["compare", "matrix", "Method", "Comparison", "DistanceMatrix", "ChainVerdict",
           "Baseline", "DistanceInterval", "FeatureRelevance", "compare_observed",
           "estimate_sensor", "observe", "ObservedComparison", "SensorModel", "SignalSensor",
           "compare_hidden", "HiddenComparison"]
