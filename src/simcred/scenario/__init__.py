"""Scenario description of Wagner, Groh et al. (seed 002) sec. II-B: fit, JSON and OpenSCENARIO.

An object is a start position and two cubic splines of time, speed v(t) and heading θ(t); its
positions follow from eq. (1) by one fixed quadrature, so that the description is unambiguous.
:func:`fit_track` / :func:`fit_scenario` obtain the splines from measured positions;
:func:`to_openscenario` exports to OpenSCENARIO 1.x and :func:`validate_openscenario` checks a file
against the schema.
"""

from simcred.scenario.description import (
    ObjectTrack,
    ScenarioDescription,
    Spline,
)
from simcred.scenario.fit import ScenarioFit, StopReason, TrackFit, fit_scenario, fit_track
from simcred.scenario.openscenario import (
    build_openscenario,
    to_openscenario,
    validate_openscenario,
)

__all__ = [
    "ObjectTrack",
    "ScenarioDescription",
    "ScenarioFit",
    "Spline",
    "StopReason",
    "TrackFit",
    "build_openscenario",
    "fit_scenario",
    "fit_track",
    "to_openscenario",
    "validate_openscenario",
]
