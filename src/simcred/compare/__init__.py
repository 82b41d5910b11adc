"""Comparison of two sets of runs (Neurohr et al. 2023): Markov chains + MMD tests."""

from simcred.compare.pairwise import DistanceMatrix, matrix
from simcred.compare.process import compare
from simcred.compare.result import Comparison

__all__ = ["compare", "matrix", "Comparison", "DistanceMatrix"]
