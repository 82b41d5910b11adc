"""Results of the scenario fit, [1] sec. II-B: one object's :class:`TrackFit`, a recording's
:class:`ScenarioFit`, and why the section search stopped (:class:`StopReason`).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from simcred._json import JsonResult
from simcred.scenario.description import ObjectTrack, ScenarioDescription
from simcred.scenario.fit_support import PHANTOM_MARGIN
from simcred.scenario.plausibility import Reason


class StopReason(StrEnum):
    """Why the section search stopped: the threshold was reached, or why not."""

    THRESHOLD = "threshold"
    """The position RMSE reached the threshold."""
    NOISE_FLOOR = "noise_floor"
    """The RMSE is within 1.2 × the estimated position noise: the threshold lies below the
    noise of the data, and more sections would only fit noise."""
    STALLED = "stalled"
    """``patience`` consecutive steps each reduced the RMSE by less than ``min_gain``."""
    MAX_SECTIONS = "max_sections"
    """``max_sections`` was reached without meeting the threshold."""
    REVERSING = "reversing"
    """Not reached, and the object reverses (see ``reversals``): the description drives forward
    (v ≥ 0) and cannot follow the reversed part."""


@dataclass(frozen=True, slots=True, eq=False)
class TrackFit(JsonResult):
    """The fit of one object.

    Attributes
    ----------
    track : ObjectTrack
        The fitted description of the object.
    rmse : float
        √(mean((x̂ − x)² + (ŷ − y)²)) over the samples that are not glitches (m).
    max_error : float
        Largest Euclidean position error over those samples (m).
    sections : int
        Sections of the returned track.
    history : tuple of (int, float)
        (sections, rmse) of every step of the section search, in order.
    iterations : int
        Jacobian evaluations (solver iterations) summed over the search.
    stop_reason : StopReason
        Why the search stopped; :attr:`reached` says whether the threshold was met.
    threshold, min_gain : float
        The settings used.
    noise : float
        Estimated RMS position noise of the data (m).
    glitches : tuple of int
        Indices of samples set aside as glitches (outliers); not in ``rmse``.
    reversals : tuple of float
        Times (s) where the object reverses its direction of travel at a stop.
    violations : tuple of Reason
        Plausibility limits the track violates (checked every 0.01 s); empty unless the fit ran
        without limits.
    unsupported_acceleration : float
        By how much (m/s²) the track's v̇ leaves what the positions support
        (:mod:`~simcred.scenario.fit_support`); :attr:`phantom_acceleration` flags it.
    """

    track: ObjectTrack
    rmse: float
    max_error: float
    sections: int
    history: tuple[tuple[int, float], ...]
    iterations: int
    stop_reason: StopReason
    threshold: float
    min_gain: float
    noise: float = 0.0
    glitches: tuple[int, ...] = ()
    reversals: tuple[float, ...] = ()
    violations: tuple[Reason, ...] = ()
    unsupported_acceleration: float = 0.0

    def __repr__(self) -> str:
        return (f"TrackFit({self.sections} sections, rmse {self.rmse:.4g} m, "
                f"{self.stop_reason})")

    @property
    def phantom_acceleration(self) -> bool:
        """Whether the fit's acceleration exceeds what the positions support by more than
        :data:`~simcred.scenario.fit_support.PHANTOM_MARGIN` (a "reached" fit included)."""
        return self.unsupported_acceleration > PHANTOM_MARGIN

    @property
    def reached(self) -> bool:
        """Whether the position RMSE reached the threshold."""
        return self.stop_reason is StopReason.THRESHOLD

    def to_dict(self) -> dict[str, Any]:
        """The fit's numbers (the track itself: ``track``'s JSON in a description)."""
        return {"sections": self.sections, "rmse": self.rmse, "max_error": self.max_error,
                "reached": self.reached, "stop_reason": str(self.stop_reason),
                "iterations": self.iterations, "history": [list(step) for step in self.history],
                "threshold": self.threshold, "min_gain": self.min_gain, "noise": self.noise,
                "glitches": list(self.glitches), "reversals": list(self.reversals),
                "violations": [str(r) for r in self.violations],
                "unsupported_acceleration": self.unsupported_acceleration,
                "phantom_acceleration": self.phantom_acceleration}


@dataclass(frozen=True, slots=True, eq=False)
class ScenarioFit(JsonResult):
    """The fitted description and the fit of every object."""

    description: ScenarioDescription
    fits: Mapping[str, TrackFit]

    def __repr__(self) -> str:
        return f"ScenarioFit({', '.join(f'{k}: {v!r}' for k, v in self.fits.items())})"

    def to_dict(self) -> dict[str, Any]:
        """Per object, :meth:`TrackFit.to_dict`."""
        return {name: fit.to_dict() for name, fit in self.fits.items()}

    @property
    def rmse(self) -> float:
        """The worst object's position RMSE (m)."""
        return max(fit.rmse for fit in self.fits.values())
