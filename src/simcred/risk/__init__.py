"""Risk measures of highway scenes: Time-To-React risk after Wagner et al. 2018, TTC and THW."""

from simcred.risk.measures import time_headway, time_to_collision
from simcred.risk.ttr import (
    DEFAULT_PREDICTIONS,
    MANEUVERS,
    EvasionSet,
    Lanes,
    Prediction,
    PredictionSet,
    ReactionTime,
    RiskResult,
    VehicleStates,
    risk,
    risk_series,
)

__all__ = [
    "DEFAULT_PREDICTIONS",
    "MANEUVERS",
    "EvasionSet",
    "Lanes",
    "Prediction",
    "PredictionSet",
    "ReactionTime",
    "RiskResult",
    "VehicleStates",
    "risk",
    "risk_series",
    "time_headway",
    "time_to_collision",
]
