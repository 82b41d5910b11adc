"""Risk measures of highway scenes: Time-To-React risk after Wagner et al. 2018, TTC and THW.

Modules: ``scene`` (the inputs: vehicle states, lanes), ``prediction`` (the TOs' predictions, the
EGO's evasions, the reaction-time law, predicted paths), ``ttr`` (plans, collisions and the
risk), ``ttr_search`` (evasive maneuvers, the TTR search), ``measures`` (TTC, THW).
"""

from simcred.risk.measures import time_headway, time_to_collision
from simcred.risk.prediction import (
    DEFAULT_PREDICTIONS,
    MANEUVERS,
    EvasionSet,
    Prediction,
    PredictionSet,
    ReactionTime,
)
from simcred.risk.scene import Lanes, VehicleStates
from simcred.risk.series import risk_series
from simcred.risk.ttr import RiskResult, max_risk, risk

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
    "max_risk",
    "risk",
    "risk_series",
    "time_headway",
    "time_to_collision",
]
