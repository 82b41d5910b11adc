"""The EGO's reaction: when it reacts and how ([1] §IV, eqs. (4)-(7)).

Computed on the physically consistent scenario description of each trace (as [1] does for the
risk), so measurement noise does not trigger it. The EGO **reacts** at the first time its
acceleration falls below ``-decel`` or its lateral speed (v sin θ) exceeds ``lateral_speed``
(an emergency manoeuvre: beyond the AD function's comfort braking). Its **manoeuvre** is
``evade`` when it gets more than half a lane away from its start lateral position, ``brake``
when it reacted otherwise, ``none`` when it never reacted. The **onset** is the first time its
speed is ``onset_drop`` below the highest speed it had so far: where its speed profile starts
to drop ([1] Fig. 7 reads the reaction off the speed profiles), comfort braking of the ACC
included. (A speed drop, not an acceleration threshold: a fitted description's acceleration
swings by ±1-2 m/s² at its ends, its speed by centimetres per second.)

A reaction or onset within ``start_margin`` of the trace's first sample is **not measurable**
(``measurable`` / ``onset_measurable`` False): a description's ends are boundary artefacts, and
an EGO already reacting when the recording starts has no measurable reaction time. It is still
reported, but eqs. (4)-(7) leave out every difference that involves it (None).

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from simcred._json import JsonResult, fields_dict, json_key
from simcred.kinematics import LANE_WIDTH
from simcred.reprocess.representation import SB


@dataclass(frozen=True, slots=True)
class ReactionCriteria:
    """Thresholds of a reaction (defaults sit above the AD function's comfort braking, 2 m/s²)."""

    decel: float = 2.5  # m/s²
    lateral_speed: float = 0.3  # m/s
    lane_width: float = LANE_WIDTH  # m
    onset_drop: float = 0.3  # m/s, several times a description's speed error (≈ 0.05 m/s)
    start_margin: float = 0.5  # s: a reaction this close to the first sample is not measurable


@dataclass(frozen=True, slots=True)
class Reaction(JsonResult):
    """When and how the EGO reacted in one trace (``time`` NaN: never)."""

    time: float
    manoeuvre: str
    speed_at_reaction: float
    min_acceleration: float
    max_lateral: float
    onset: float = math.nan
    measurable: bool = True  # False: ``time`` lies within ``start_margin`` of the first sample
    onset_measurable: bool = True  # the same for ``onset``

    def to_dict(self) -> dict[str, float | str | None]:
        return {k: (None if isinstance(v, float) and math.isnan(v) else v)
                for k, v in asdict(self).items()}


def reaction(t: np.ndarray, y: np.ndarray, v: np.ndarray, heading: np.ndarray,
             acceleration: np.ndarray, criteria: ReactionCriteria | None = None) -> Reaction:
    """The EGO's reaction in one trace given its lateral position, speed, heading (road along
    +x) and acceleration."""
    c = ReactionCriteria() if criteria is None else criteria
    lateral = np.abs(y - y[0])
    slowing = v < np.maximum.accumulate(v) - c.onset_drop
    onset = float(t[int(np.argmax(slowing))]) if slowing.any() else math.nan
    onset_ok = not onset - t[0] < c.start_margin  # NaN (no onset) counts as measurable
    reacting = (acceleration < -c.decel) | (np.abs(v * np.sin(heading)) > c.lateral_speed)
    if not reacting.any():
        return Reaction(math.nan, "none", math.nan, float(acceleration.min()),
                        float(lateral.max()), onset, True, onset_ok)
    k = int(np.argmax(reacting))
    manoeuvre = "evade" if lateral.max() > c.lane_width / 2 else "brake"
    return Reaction(float(t[k]), manoeuvre, float(v[k]), float(acceleration.min()),
                    float(lateral.max()), onset, bool(t[k] - t[0] >= c.start_margin), onset_ok)


@dataclass(frozen=True, slots=True)
class ReactionTiming(JsonResult):
    """Eqs. (4)-(7) of [1] for one sensor model (s; None: a difference that involves a reaction
    that is absent or not measurable): Δt_react(GT, rGT) (eq. 4, positive: the resimulation
    reacts earlier), t_ΔS,d = ΔS,d / v_EGO (eq. 5), their ratio (eq. 6), Δt_react(rGT, rSD)
    = t_rSD − t_rGT (eq. 7), and the same for the onset of the speed drop (``dt_onset_*``, eq. 6's
    ratio ``ratio_onset_eq6``: [1] reads the reaction as the drop of the speed profile). Its
    document is its fields, under [1]'s names (``dt_react_GT_rGT``, ...)."""

    dt_react_gt_rgt: float | None = field(metadata=json_key("dt_react_GT_rGT"))
    t_offset: float | None
    ratio_eq6: float | None
    dt_react_rgt_rsd: float | None = field(metadata=json_key("dt_react_rGT_rSD"))
    dt_onset_gt_rgt: float | None = field(metadata=json_key("dt_onset_GT_rGT"))
    dt_onset_rgt_rsd: float | None = field(metadata=json_key("dt_onset_rGT_rSD"))
    ratio_onset_eq6: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return fields_dict(self)


@dataclass(frozen=True, slots=True)
class ReactionAnalysis(JsonResult):
    """[1] §IV's analysis of a drive with GT: ΔS,d (``sensor_offset_d``, m: the mean TO position
    error of SD against GT), the EGO's speed before the reaction (m/s), eqs. (4)-(7) with the
    ideal sensor (``ideal``) and with the scenario-based sensor model (``scenario_based``: its
    resimulations rGT[sb], rSD[sb] in place of rGT, rSD; None without the model)."""

    sensor_offset_d: float
    ego_speed: float
    ideal: ReactionTiming
    scenario_based: ReactionTiming | None = None

    def to_dict(self) -> dict[str, Any]:
        """The flat layout of ``reprocess.json``'s ``analysis`` (deliberate, [1]'s symbols as
        keys): ΔS,d, v_EGO, the ideal sensor's eqs. (4)-(7), then the scenario-based model's
        with the suffix ``[sb]`` (``dt_react_GT_rGT[sb]``, ...)."""
        out: dict[str, Any] = {"sensor_offset_d": self.sensor_offset_d,
                               "ego_speed": self.ego_speed, **self.ideal.to_dict()}
        if self.scenario_based is not None:
            out.update({f"{k}{SB}": v for k, v in self.scenario_based.to_dict().items()})
        return out


def reaction_analysis(reactions: dict[str, Reaction], sensor_offset: float, ego_speed: float
                      ) -> ReactionTiming:
    """Eqs. (4)-(7) of [1] (:class:`ReactionTiming`) from the reactions in ``GT``, ``rGT`` and
    ``rSD``.

    ``sensor_offset`` is ΔS,d (mean TO position error of SD against GT), ``ego_speed`` the EGO's
    speed before the reaction. A difference involving a reaction that is not measurable (see
    the module docstring) is None.
    """
    def time(name: str, what: str = "time") -> float:
        """The time, NaN where absent or not measurable (near the trace's first sample)."""
        r = reactions.get(name)
        ok = r is not None and (r.measurable if what == "time" else r.onset_measurable)
        return getattr(r, what) if ok else math.nan

    def defined(value: float) -> float | None:
        return None if math.isnan(value) else value

    def ratio(shift: float) -> float | None:  # [1] eq. (6)
        return defined(shift / offset_time if offset_time > 0 else math.nan)

    gt_vs_rgt = time("GT") - time("rGT")
    onset_gt_vs_rgt = time("GT", "onset") - time("rGT", "onset")
    offset_time = sensor_offset / ego_speed
    return ReactionTiming(
        dt_react_gt_rgt=defined(gt_vs_rgt),
        t_offset=defined(offset_time),
        ratio_eq6=ratio(gt_vs_rgt),
        dt_react_rgt_rsd=defined(time("rSD") - time("rGT")),
        dt_onset_gt_rgt=defined(onset_gt_vs_rgt),
        dt_onset_rgt_rsd=defined(time("rSD", "onset") - time("rGT", "onset")),
        ratio_onset_eq6=ratio(onset_gt_vs_rgt),
    )
