"""Scenario description of Wagner, Groh et al. (paper 002) sec. II-B and its local variation (V).

An object is a start position and two cubic splines of time, speed v(t) and heading θ(t); its
positions follow from eq. (1) by one fixed quadrature, so that the description is unambiguous.
:func:`fit_track` / :func:`fit_scenario` obtain the splines from measured positions;
:func:`to_openscenario` exports to OpenSCENARIO 1.x and :func:`validate_openscenario` checks a file
against the schema. :func:`generate_variations` varies a traffic object's cut-in along a C²
Bézier path (:class:`BezierPath`) and rejects implausible variations
(:class:`PlausibilityLimits`).

Modules: ``spline`` (time curves, the quadrature of eq. (1)), ``description`` (objects,
JSON), ``fit`` (the fit's face: one track, a recording), ``fit_search`` (sections, stop rules),
``fit_problem`` (one step's least squares), ``fit_result`` (results), ``fit_constraints``
(plausibility rows of the fit), ``fit_robust`` (noise, glitches, reversals), ``openscenario``
(export), ``frenet`` (path frame), ``bezier`` (the path), ``plausibility`` (limits),
``variation`` (drawing and refitting variations), ``variation_set`` (options and results).
"""

from simcred.scenario.bezier import BezierPath, influence
from simcred.scenario.description import ObjectTrack, ScenarioDescription
from simcred.scenario.fit import ScenarioFit, StopReason, TrackFit, fit_scenario, fit_track
from simcred.scenario.openscenario import (
    build_openscenario,
    to_openscenario,
    validate_openscenario,
)
from simcred.scenario.plausibility import (
    VEHICLE_LIMITS,
    PlausibilityLimits,
    Reason,
    check_plausibility,
)
from simcred.scenario.spline import Spline
from simcred.scenario.variation import draw_displacements, generate_variations, vary_one
from simcred.scenario.variation_set import (
    Variation,
    VariationOptions,
    VariationRecord,
    VariationSet,
    VariationStatus,
    load_variations,
)

__all__ = [
    "VEHICLE_LIMITS",
    "BezierPath",
    "ObjectTrack",
    "PlausibilityLimits",
    "Reason",
    "ScenarioDescription",
    "ScenarioFit",
    "Spline",
    "VariationStatus",
    "StopReason",
    "TrackFit",
    "Variation",
    "VariationOptions",
    "VariationRecord",
    "VariationSet",
    "build_openscenario",
    "check_plausibility",
    "draw_displacements",
    "fit_scenario",
    "fit_track",
    "generate_variations",
    "influence",
    "load_variations",
    "to_openscenario",
    "validate_openscenario",
    "vary_one",
]
