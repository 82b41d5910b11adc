"""Options and results of the variation: :class:`VariationOptions`, one record per variation
(kept or rejected), the kept descriptions, and the JSON file of a whole set
(``variation_set.json``).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. V.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np

from simcred._json import JsonResult, envelope, read_json
from simcred.errors import OptionError, SimcredError
from simcred.kinematics import LANE_WIDTH
from simcred.scenario.bezier import BezierPath
from simcred.scenario.description import (
    ScenarioDescription,
)
from simcred.scenario.plausibility import PlausibilityLimits, Reason

KIND = "variation_set"
CROSSING_SIDES = (None, "left", "right")
METHOD = ("clamped C2 cubic Bezier path through equitemporal fix points, displaced around the "
          "lane crossing and refitted by fit_track; [1] sec. V")


class VariationStatus(StrEnum):
    KEPT = "kept"
    REJECTED = "rejected"


@dataclass(frozen=True, slots=True, eq=False)
class VariationRecord(JsonResult):
    """What happened to variation ``index``.

    Attributes
    ----------
    index : int
        The variation's index: its random stream is ``stream(seed, index)``.
    displacements : numpy.ndarray, shape (k, 2)
        Longitudinal and lateral offset (m) of each varied fix point, in the order of
        :attr:`VariationSet.varied`.
    rmse : float
        Position RMSE (m) of the refit against the sampled varied path (nan if it failed).
    sections : int
        Sections of the refitted TO track (0 if the refit failed).
    status : VariationStatus
        ``kept`` or ``rejected``.
    reasons : tuple of Reason
        Violated limits; empty for a kept variation.
    """

    index: int
    displacements: np.ndarray
    rmse: float
    sections: int
    status: VariationStatus
    reasons: tuple[Reason, ...]

    def __repr__(self) -> str:
        return f"VariationRecord({self.index}, {self.status.value}, rmse {self.rmse:.3g})"


    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "status": self.status.value,
                "reasons": [r.value for r in self.reasons],
                "displacements": self.displacements.tolist(),
                "rmse": self.rmse if math.isfinite(self.rmse) else None,
                "sections": self.sections}


@dataclass(frozen=True, slots=True, eq=False)
class Variation:
    """One variation: its record, the varied description and the varied Bézier path.

    ``description`` is the original with the TO's track replaced by the refit (EGO and every
    other object unchanged); it is there for rejected variations too, to inspect them (the
    original itself if the refit failed). ``path`` is the varied Bézier path B(P + D).
    """

    record: VariationRecord
    description: ScenarioDescription
    path: BezierPath

    def __repr__(self) -> str:
        return f"Variation({self.record!r})"


    @property
    def index(self) -> int:
        return self.record.index

    @property
    def displacements(self) -> np.ndarray:
        return self.record.displacements

    @property
    def kept(self) -> bool:
        return self.record.status is VariationStatus.KEPT


@dataclass(frozen=True, slots=True, eq=False)
class VariationSet(JsonResult):
    """The variations of one description, [1] sec. V (Fig. 8: 300 variations).

    Attributes
    ----------
    variations : tuple of Variation
        The kept variations, by index.
    records : tuple of VariationRecord
        Every generated variation, kept or rejected, by index.
    seed : int
        The seed (the drawn entropy if none was given): variation i uses ``stream(seed, i)``.
    to, ego : str
        The varied object and the EGO (unchanged).
    fix_times : numpy.ndarray
        τ_0 … τ_n (s).
    varied : tuple of int
        Indices of the displaced fix points.
    crossing_time : float
        The lane crossing (s) the window is centred on.
    boundary_y : float or None
        The lane boundary (m) used to find it (None if ``crossing_time`` was given).
    threshold : float
        The refit threshold (m).
    original_reasons : tuple of Reason
        Limits the original TO track itself violates: if it is not empty, most variations will
        be rejected for the same reasons.
    options, limits
        The settings used.
    base : ScenarioDescription
        The original description.
    """

    variations: tuple[Variation, ...]
    records: tuple[VariationRecord, ...]
    seed: int
    to: str
    ego: str
    fix_times: np.ndarray
    varied: tuple[int, ...]
    crossing_time: float
    boundary_y: float | None
    threshold: float
    original_reasons: tuple[Reason, ...]
    options: VariationOptions
    limits: PlausibilityLimits
    base: ScenarioDescription
    method: str = METHOD

    def __repr__(self) -> str:
        return (f"VariationSet({self.generated} generated, {self.kept} kept, "
                f"{self.rejected} rejected, seed {self.seed})")


    @property
    def generated(self) -> int:
        return len(self.records)

    @property
    def kept(self) -> int:
        return sum(r.status is VariationStatus.KEPT for r in self.records)

    @property
    def rejected(self) -> int:
        return self.generated - self.kept

    @property
    def rejections(self) -> dict[str, int]:
        """Rejected variations per violated limit (a variation counts once for each of its
        reasons, so the counts may sum to more than :attr:`rejected`); only reasons that
        occurred, in the order of :class:`Reason`."""
        counts = {reason.value: sum(reason in r.reasons for r in self.records) for reason in Reason}
        return {reason: count for reason, count in counts.items() if count}

    def to_dict(self) -> dict[str, Any]:
        """The JSON document: settings, counts, every record, and each kept variation's TO track.

        Deterministic (same set, same text) and float-exact; read the descriptions back with
        :func:`load_variations`.
        """
        tracks = {v.index: v.description.to_dict()["objects"][self.to] for v in self.variations}
        records = []
        for record in self.records:
            entry = record.to_dict()
            if record.index in tracks:
                entry["track"] = tracks[record.index]
            records.append(entry)
        return envelope(KIND, {
            "method": self.method, "seed": self.seed, "to": self.to, "ego": self.ego,
            "options": asdict(self.options), "limits": asdict(self.limits),
            "fix_times": self.fix_times.tolist(), "varied": list(self.varied),
            "crossing_time": self.crossing_time, "boundary_y": self.boundary_y,
            "threshold": self.threshold,
            "original_reasons": [r.value for r in self.original_reasons],
            "generated": self.generated, "kept": self.kept, "rejected": self.rejected,
            "rejections": self.rejections, "records": records,
            "description": self.base.to_dict(),
        })

    def write(self, path: str | Path) -> Path:
        """Write :meth:`to_json` to ``path`` (deterministic, indented JSON)."""
        path = Path(path)
        path.write_text(self.to_json(), encoding="utf-8")
        return path


def load_variations(source: Mapping[str, Any] | str | Path) -> dict[int, ScenarioDescription]:
    """The kept varied descriptions of a variations document or file, by index.

    Parameters
    ----------
    source : mapping or path
        A document from :meth:`VariationSet.to_json` or a file written by
        :meth:`VariationSet.write`.

    Returns
    -------
    dict of int to ScenarioDescription
        Equal (:meth:`ScenarioDescription.equals`) to the variations that were written.
    """
    where = "<memory>"
    if isinstance(source, str | Path):
        where = str(source)
        source = read_json(Path(source))
    if not isinstance(source, Mapping) or source.get("kind") != KIND:
        raise SimcredError(f"{where}: not a variations document (kind must be {KIND!r})")
    for key, kind in (("description", Mapping), ("records", list), ("to", str), ("seed", int)):
        if not isinstance(source.get(key), kind):
            raise SimcredError(f"{where}: missing or malformed key '{key}'")
    base, to = source["description"], source["to"]
    out = {}
    for i, record in enumerate(source["records"]):
        if not isinstance(record, Mapping):
            raise SimcredError(f"{where}: records[{i}] must be an object")
        if record.get("status") != VariationStatus.KEPT.value:
            continue
        if "track" not in record or not isinstance(record.get("index"), int):
            raise SimcredError(f"{where}: records[{i}]: a kept record needs 'index' and 'track'")
        try:
            provenance = variation_provenance(VariationRecord(
                record["index"], np.array(record["displacements"], dtype=np.float64),
                float(record["rmse"]), int(record["sections"]), VariationStatus.KEPT, ()),
                source["seed"], to)
        except (KeyError, TypeError, ValueError):
            raise SimcredError(f"{where}: records[{i}]: malformed displacements, rmse or "
                               "sections") from None
        document = {**base, "objects": {**base.get("objects", {}), to: record["track"]},
                    "metadata": {**base.get("metadata", {}), "variation": provenance}}
        out[record["index"]] = ScenarioDescription.from_json(
            document, source=f"{where}: records[{i}]")
    return out


@dataclass(frozen=True, slots=True)
class VariationOptions:
    """How the TO's path is varied, [1] sec. V.

    Parameters
    ----------
    section : float, default: 1.0
        Target section length (s). The TO's span T gets n = max(1, round(T / section)) equal
        sections. 1 s puts 3–4 fix points into a 3 s lane change, fine enough to reshape it. An
        offset δ of one fix point changes the acceleration there by about 4.4 δ / section²
        (1.3 m/s² for 0.3 m), so halving the section quadruples it.
    window : int, default: 2
        Fix points varied on each side of the lane crossing: the ``window`` last fix points at or
        before it and the ``window`` first after it; never the first or last fix point, which
        carry the end conditions.
    sigma_lon, sigma_lat : float, default: 0.3, 0.3
        Standard deviations (m) of the longitudinal (x) and lateral (y) offsets of a fix point,
        in the road frame (the road runs along +x, as in simcred's scenarios). On the reference
        cut-in (braking at −6.6 m/s²) these keep 95 % of the variations; σ_lon = 1 m keeps a
        third (docs/variation.md).
    truncation : float or None, default: 2.0
        Offsets are normal, truncated at ± truncation · σ (None: not truncated). Truncation keeps
        single draws from dominating the rejections.
    boundary_y : float, optional
        Lateral position (m) of the lane boundary the TO crosses; default
        ``metadata["road"]["boundary_y"]`` of the description, else detected: the boundaries of
        the EGO's lane (the EGO's y at the TO's start ± ``lane_width`` / 2), the one the TO
        crosses first (restricted to ``crossing_side`` if given).
    crossing_side : {"left", "right"}, optional
        Which boundary of the EGO's lane to look for when ``boundary_y`` is detected: "left"
        (y above the EGO's, a cut-in from the left or a cut-out to the left) or "right".
    lane_width : float, default: 3.5
        Width (m) of the EGO's lane for the detection.
    crossing_time : float, optional
        Time (s) of the lane crossing; default the first time the TO's y crosses the boundary
        (sampled every 0.01 s, interpolated linearly).
    sample_dt : float, optional
        Step (s) at which the varied path is sampled and refitted; default the description's
        ``dt``.
    threshold : float, optional
        Refit threshold (m); default ``metadata["fit"]["threshold"]`` of the description (the one
        it was fitted with), else :data:`~simcred.scenario.fit.THRESHOLD`.
    keep_residual : bool, default: True
        Sample the description plus the displacement of the Bézier path (True), or the Bézier path
        itself (False, literally [1]); see Notes of :func:`vary_one`.
    warm_sections : bool, default: True
        Start the refit's section search at the original TO track's sections instead of one per
        4 s (faster; the refit never has fewer sections than the original).
    """

    section: float = 1.0
    window: int = 2
    sigma_lon: float = 0.3
    sigma_lat: float = 0.3
    truncation: float | None = 2.0
    boundary_y: float | None = None
    crossing_side: str | None = None
    lane_width: float = LANE_WIDTH
    crossing_time: float | None = None
    sample_dt: float | None = None
    threshold: float | None = None
    keep_residual: bool = True
    warm_sections: bool = True

    def __post_init__(self) -> None:
        check_positive("section", self.section)
        if isinstance(self.window, bool) or not isinstance(self.window, int | np.integer) \
                or self.window < 1:
            raise OptionError(f"window must be an integer >= 1, got {self.window!r}")
        for name in ("sigma_lon", "sigma_lat"):
            value = getattr(self, name)
            if not (is_real(value) and math.isfinite(value) and value >= 0):
                raise OptionError(f"{name} must be a finite number >= 0, got {value!r}")
        if self.crossing_side not in CROSSING_SIDES:
            raise OptionError(f"crossing_side must be one of left, right (or None), got "
                              f"{self.crossing_side!r}")
        check_positive("lane_width", self.lane_width)
        for name in ("truncation", "sample_dt", "threshold"):
            if getattr(self, name) is not None:
                check_positive(name, getattr(self, name))
        for name in ("boundary_y", "crossing_time"):
            value = getattr(self, name)
            if value is not None and not (is_real(value) and math.isfinite(value)):
                raise OptionError(f"{name} must be a finite number, got {value!r}")
        for name in ("keep_residual", "warm_sections"):
            if not isinstance(getattr(self, name), bool):
                raise OptionError(f"{name} must be True or False, got {getattr(self, name)!r}")


def is_real(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def check_positive(name: str, value: Any) -> None:
    if not (is_real(value) and math.isfinite(value) and value > 0):
        raise OptionError(f"{name} must be a finite number > 0, got {value!r}")


def variation_provenance(record: VariationRecord, seed: int, to: str) -> dict[str, Any]:
    """The ``"variation"`` metadata entry of a varied description."""
    return {"index": record.index, "seed": seed, "object": to,
            "displacements": record.displacements.tolist(), "rmse": record.rmse,
            "sections": record.sections}
